"""Gymnasium conventions users will test on the agvsim environments."""
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import envs
from envs.agv_env import COVARIANCE_FLAT_INDEX

FAST = {"localization": "odometry"}


@pytest.mark.parametrize("env_id", sorted(envs.ENV_SPECS))
def test_check_env_passes_without_warnings(env_id):
    """With the defaults: EKF localization on rendered camera frames."""
    if env_id.endswith("-v2"):
        env = gym.make(env_id, render_mode="rgb_array")
    else:  # (kept for old code: gymnasium says the version is out of date)
        with pytest.warns(DeprecationWarning, match="out of date"):
            env = gym.make(env_id, render_mode="rgb_array")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


def test_ekf_keeps_the_estimate_where_odometry_drifts():
    """Replay the same actions (a route follower's, recorded on the true pose)
    with worn odometry: the camera-corrected estimate stays within centimetres
    while dead reckoning drifts by decimetres."""
    from agvsim.loop.pure_pursuit import FollowerParams, PurePursuit, RoutePath

    env = gym.make("agvsim/PlantFloor-v2", localization="truth", odometry="worn", task="localize")
    obs, _ = env.reset(seed=4)
    base = env.unwrapped
    start = base.loop.true_pose
    route = RoutePath.from_route(base.map, "default")
    pursuit = PurePursuit(route, FollowerParams(), laps=10)
    pursuit.progress = route.project(start[:2], 0.0, window=1e9)
    actions = []
    for _ in range(500):
        v, w = pursuit.command(tuple(obs["pose"].astype(float)))
        a = np.array([v / 1.5, w / 1.5], np.float32)
        actions.append(a)
        obs, *_ = env.step(a)
    errors = {}
    for mode in ("ekf", "odometry"):
        env = gym.make("agvsim/PlantFloor-v2", localization=mode, odometry="worn",
                       observations="geometric", task="localize")
        env.reset(seed=4)
        accepted = 0
        for a in actions:
            _, _, _, _, info = env.step(a)
            accepted += info["observations"]["accepted"]
        errors[mode] = (info["position_error"], accepted)
    assert errors["ekf"][1] > 10  # it did see targets
    assert errors["ekf"][0] < 0.05
    assert errors["odometry"][0] > 4 * errors["ekf"][0]
    assert errors["odometry"][0] > 0.1


@pytest.mark.render
def test_observe_image_returns_the_rendered_frame():
    env = gym.make("agvsim/Corridor-v2", observe_image=True, render_mode="rgb_array")
    obs, _ = env.reset(seed=1)
    assert obs["image"].shape == (480, 512, 1) and obs["image"].dtype == np.uint8
    for _ in range(5):  # the first frame is captured after 1 / camera_rate = 0.25 s
        obs, *_ = env.step(np.array([0.3, 0.0], np.float32))
    frame = env.unwrapped.loop.last_frame
    assert frame is not None and frame.mean() > 20  # a rendered picture, not the blank placeholder
    np.testing.assert_array_equal(obs["image"][..., 0], frame)
    img = env.render()
    assert img.shape[2] == 3
    env.close()


def test_observe_image_needs_rendered_frames():
    with pytest.raises(ValueError, match="observe_image"):
        gym.make("agvsim/PlantFloor-v2", observe_image=True, observations="geometric")


def test_string_entry_point_without_prior_import():
    env = gym.make("envs:agvsim/Corridor-v2", **FAST)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert set(info) >= {"true_pose", "estimated_pose", "odometry_pose", "position_error",
                         "observations", "collision"}


def test_unknown_option_is_an_error_with_a_suggestion():
    with pytest.raises(ValueError, match="localisation.*did you mean 'localization'"):
        gym.make("agvsim/PlantFloor-v2", localisation="ekf")


@pytest.mark.parametrize("bad", [{"localization": "gps"}, {"camera_rate": 0.0}, {"lens": 35},
                                 {"odometry": "new"}])
def test_bad_option_values_are_errors(bad):
    with pytest.raises(ValueError):
        gym.make("agvsim/PlantFloor-v2", **bad)


def rollout(env, seed, n=60):
    obs, _ = env.reset(seed=seed)
    actions = np.random.default_rng(seed).uniform(-1, 1, (n, 2)).astype(np.float32)
    trace = [obs["pose"].copy()]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        trace.append(np.concatenate([obs["pose"], [r], info["true_pose"]]))
        if term or trunc:
            break
    return trace


def test_same_seed_steps_identically():
    a = gym.make("agvsim/PlantFloor-v2", **FAST)
    b = gym.make("agvsim/PlantFloor-v2", **FAST)
    ta, tb = rollout(a, 5), rollout(b, 5)
    assert len(ta) == len(tb)
    assert all(np.array_equal(x, y) for x, y in zip(ta, tb))
    tc = rollout(a, 6)
    assert not all(np.array_equal(x, y) for x, y in zip(ta, tc))


def test_pickle_round_trip_reproduces_reset_and_step():
    env = gym.make("agvsim/Corridor-v2", **FAST).unwrapped
    clone = pickle.loads(pickle.dumps(env))
    ta, tb = rollout(env, 11), rollout(clone, 11)
    assert all(np.array_equal(x, y) for x, y in zip(ta, tb))


def test_actions_are_clipped_and_nan_is_an_error():
    env = gym.make("agvsim/PlantFloor-v2", **FAST).unwrapped
    env.reset(seed=0)
    for _ in range(40):
        _, _, _, _, info = env.step(np.array([5.0, 0.0]))
    # 5x the limit is clipped to the vehicle's top speed (1.5 m/s)
    speed = np.mean(env.loop.sim.vehicle.velocity[0])
    assert speed == pytest.approx(1.5, abs=1e-6)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan, 0.0]))


def test_goal_reward_is_progress_on_the_true_pose():
    env = gym.make("agvsim/Corridor-v2", **FAST, time_cost=0.0).unwrapped
    env.reset(seed=3)
    before = env.task.goal_distance(env.loop)
    _, reward, _, _, _ = env.step(np.array([0.5, 0.0]))
    assert reward == pytest.approx(before - env.task.goal_distance(env.loop), abs=1e-12)


def test_truth_mode_observes_the_true_pose_and_odometry_does_not():
    truth = gym.make("agvsim/PlantFloor-v2", localization="truth", odometry="worn").unwrapped
    odo = gym.make("agvsim/PlantFloor-v2", localization="odometry", odometry="worn").unwrapped
    for env in (truth, odo):
        env.reset(seed=2)
        for _ in range(150):
            obs, _, _, _, info = env.step(np.array([0.7, 0.3]))
        env._last = (obs, info)
    obs, info = truth._last
    assert np.allclose(obs["pose"], info["true_pose"], atol=1e-4)
    assert info["position_error"] == 0.0
    obs, info = odo._last
    assert info["position_error"] > 0.01
    assert np.allclose(obs["pose"], info["odometry_pose"], atol=1e-4)
    cov = np.zeros((3, 3))
    for value, (i, k) in zip(obs["covariance"].astype(float), COVARIANCE_FLAT_INDEX):  # (-v2's flat layout)
        cov[i, k] = cov[k, i] = value
    assert np.all(np.linalg.eigvalsh(cov) >= -1e-9)
    assert cov[0, 0] > 0


def test_truncated_at_the_step_limit():
    env = gym.make("agvsim/PlantFloor-v2", **FAST, max_episode_steps=5)
    env.reset(seed=0)
    flags = [env.step(np.zeros(2))[3] for _ in range(5)]
    assert flags == [False] * 4 + [True]


def test_rgb_array_render_shows_the_floor():
    env = gym.make("agvsim/PlantFloor-v2", **FAST, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.array([0.5, 0.0]))
    img = env.render()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3
    assert img.std() > 10


ASYNC_SCRIPT = """
import gymnasium as gym, numpy as np, envs
vec = gym.make_vec("agvsim/Corridor-v2", num_envs=2, vectorization_mode="async")
try:
    obs, _ = vec.reset(seed=[1, 2])
    assert obs["pose"].shape == (2, 3)
    for _ in range(4):  # past the first camera frame (rendered in the workers)
        obs, rew, term, trunc, info = vec.step(np.full((2, 2), 0.2, np.float32))
    assert rew.shape == (2,)
finally:
    vec.close()
print("ok")
"""


@pytest.mark.render
@pytest.mark.slow
def test_async_vector_env_steps():
    """Rendered EKF envs in forked workers (the default start method): the env
    the parent builds for the spaces opens no GL context, so the workers do not
    hang on their first frame. Run in a fresh interpreter: a process that has
    itself rendered (as earlier tests here have) must use
    ``vector_kwargs={"context": "spawn"}``."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", ASYNC_SCRIPT], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().endswith("ok")


def test_rgb_array_keeps_the_camera_frame_and_key_off_the_map():
    env = gym.make("agvsim/PlantFloor-v2", **FAST, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.array([0.5, 0.0]))
    img = env.render()
    view = env.unwrapped._view
    u0, v0, u1, v1 = view.map_box
    x0, y0, x1, y1 = view.inset_box
    assert x0 >= u1 and view.key_box[0] >= u1  # beside the map: no station or target under them
    assert (x1 - x0) * (y1 - y0) < img.shape[0] * img.shape[1] / 8
    assert view.inset_fraction < 1 / 8
    env.close()
