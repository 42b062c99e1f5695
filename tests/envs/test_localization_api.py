"""The localization where users look: ``-v1``'s ``status``, ``info["localization"]``,
``reset(options=...)`` (start pose, believed pose) and ``kidnap``."""
from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

import envs
from envs.config import EnvConfig
from localizer.filter import LOST, STATUSES, TRACKING

FAST = {"observations": "geometric"}
OLD_KEYS = {"pose", "covariance", "goal", "wheel_speeds"}
INFO_KEYS = {"status": str, "position_sigma": float, "since_fix": float, "lost_events": int, "relocalizations": int}
FREE = (20.0, 20.0, 0.3)  # plant_floor: 4 m from the nearest wall or obstacle


def make(env_id="agvsim/PlantFloor-v1", **kw):
    if env_id.endswith("-v2"):
        return gym.make(env_id, **{**FAST, **kw})
    with pytest.warns(DeprecationWarning, match="out of date"):  # gymnasium: an older version than -v2
        return gym.make(env_id, **{**FAST, **kw})


def test_every_env_has_a_v0_a_v1_and_a_v2():
    names = {i.rsplit("-", 1)[0] for i in envs.ENV_SPECS}
    assert {f"{n}-{v}" for n in names for v in ("v0", "v1", "v2")} == set(envs.ENV_SPECS)
    assert all(envs.ENV_SPECS[f"{n}-{v}"][0].get("observe_status") is True for n in names for v in ("v1", "v2"))
    assert all(envs.ENV_SPECS[f"{n}-v2"][0].get("covariance") == "flat" for n in names)
    assert all("observe_status" not in envs.ENV_SPECS[f"{n}-v0"][0] for n in names)


@pytest.mark.parametrize("env_id", sorted(envs.ENV_SPECS))
def test_check_env_passes_for_every_version(env_id):
    env = make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


def test_v1_observes_the_status_and_v0_keeps_its_space():
    v0, v1 = make("agvsim/PlantFloor-v0"), make("agvsim/PlantFloor-v1")
    assert set(v0.observation_space.spaces) == OLD_KEYS
    assert set(v1.observation_space.spaces) == OLD_KEYS | {"status"}
    assert v1.observation_space["status"] == spaces.Discrete(len(STATUSES))
    obs0, _ = v0.reset(seed=3)
    obs1, _ = v1.reset(seed=3)
    assert set(obs0) == OLD_KEYS and v0.observation_space.contains(obs0)
    assert v1.observation_space.contains(obs1) and obs1["status"] == STATUSES.index(TRACKING)
    for key in OLD_KEYS:  # the same episode: only the status is new
        np.testing.assert_array_equal(obs0[key], obs1[key])


def test_observe_status_is_validated():
    with pytest.raises(ValueError, match="observe_status must be True or False"):
        EnvConfig(observe_status="yes")


@pytest.mark.parametrize("localization", ["ekf", "odometry", "truth"])
def test_info_localization_at_reset_and_every_step(localization):
    env = make(localization=localization)
    _, info = env.reset(seed=1)
    steps = [info]
    for _ in range(5):
        steps.append(env.step(np.array([0.5, 0.1], np.float32))[4])
    for info in steps:
        loc = info["localization"]
        assert set(loc) >= set(INFO_KEYS) | {"reason"}
        for key, kind in INFO_KEYS.items():
            assert isinstance(loc[key], kind), (key, loc[key])
        assert loc["status"] in STATUSES and loc["position_sigma"] >= 0 and loc["since_fix"] >= 0
    assert steps[-1]["localization"] is not steps[-2]["localization"]  # a fresh dict
    if localization == "truth":
        assert steps[-1]["localization"]["position_sigma"] == 0.0
    else:
        assert steps[-1]["localization"]["since_fix"] > 0  # no target seen in half a second here


def test_unknown_believed_pose_starts_lost():
    env = make()
    obs, info = env.reset(seed=2, options={"believed_pose": "unknown"})
    assert info["localization"]["status"] == LOST
    assert info["localization"]["reason"]
    assert obs["status"] == STATUSES.index(LOST)
    obs, info = env.reset(seed=2)  # and the next episode without options is back to tracking
    assert info["localization"]["status"] == TRACKING and obs["status"] == STATUSES.index(TRACKING)


def test_start_pose_puts_the_true_pose_there_and_the_filter_believes_it():
    env = make()
    obs, info = env.reset(seed=4, options={"start_pose": FREE})
    np.testing.assert_allclose(info["true_pose"], FREE, atol=1e-9)
    np.testing.assert_allclose(info["estimated_pose"], FREE, atol=1e-9)
    assert info["start_station"] is None and info["goal_station"] is not None
    info = env.step(np.zeros(2, np.float32))[4]
    np.testing.assert_allclose(info["true_pose"][:2], FREE[:2], atol=1e-3)


def test_believed_pose_is_what_the_filter_is_told():
    env = make()
    told = (FREE[0] + 1.0, FREE[1] - 0.5, 0.0)
    _, info = env.reset(seed=4, options={"start_pose": FREE, "believed_pose": told})
    np.testing.assert_allclose(info["true_pose"], FREE, atol=1e-9)
    np.testing.assert_allclose(info["estimated_pose"], told, atol=1e-9)
    assert info["position_error"] == pytest.approx(np.hypot(1.0, 0.5))


def rollout(env, options, n=40):
    obs, info = env.reset(seed=7, options=options)
    out = [obs["pose"].copy(), info["true_pose"]]
    rng = np.random.default_rng(7)
    for _ in range(n):
        obs, r, *_, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        out += [obs["pose"].copy(), np.array([r]), info["true_pose"]]
    return out


def test_the_drawn_station_as_start_pose_is_the_same_episode():
    """Options do not change what is drawn: the station drawn as an explicit start pose (with
    an empty options dict, and without options) gives the same episode, bit for bit."""
    env = make()
    _, info = env.reset(seed=7)
    station = env.unwrapped.map.station(info["start_station"]).pose
    plain = rollout(env, None)
    for options in ({}, {"start_pose": station}):
        assert all(np.array_equal(a, b) for a, b in zip(plain, rollout(env, options)))


@pytest.mark.parametrize("options, match", [
    ({"start": (1, 2, 3)}, "unknown reset option 'start'.*start_pose, believed_pose"),
    ({"start_pose": (14.5, 7.0, 0.0)}, r"'start_pose'=\(14.5, 7.0, 0.0\) is 0.45 m from the nearest wall.*clearance"),
    ({"start_pose": (500.0, 5.0, 0.0)}, "'start_pose'.*outside the map"),
    ({"start_pose": (0.0, 0.0, 0.0)}, "'start_pose'.*from the nearest wall"),
    ({"start_pose": (1.0, 2.0)}, "'start_pose' must be 3 numbers"),
    ({"start_pose": (20.0, 20.0, float("nan"))}, "'start_pose'.*finite"),
    ({"believed_pose": "lost"}, "'believed_pose' must be a pose .* or 'unknown', got 'lost'"),
    ({"believed_pose": (1.0, "a", 0.0)}, "'believed_pose'"),
    ("unknown", "reset options must be a dict"),
])
def test_bad_reset_options_are_one_clear_error(options, match):
    env = make()
    with pytest.raises(ValueError, match=match) as err:
        env.reset(seed=0, options=options)
    assert "\n" not in str(err.value)


def test_believed_pose_needs_the_filter():
    env = make(localization="odometry")
    with pytest.raises(ValueError, match="'believed_pose'.*needs localization='ekf'"):
        env.reset(seed=0, options={"believed_pose": "unknown"})


def test_kidnap_moves_the_vehicle_and_leaves_the_estimate():
    env = make()
    _, info = env.reset(seed=5)
    base = env.unwrapped
    before = base.loop.estimated_pose
    base.kidnap(FREE)
    np.testing.assert_allclose(base.loop.true_pose, FREE, atol=1e-9)
    np.testing.assert_array_equal(base.loop.estimated_pose, before)
    _, _, _, _, info = env.step(np.zeros(2, np.float32))
    np.testing.assert_allclose(info["true_pose"][:2], FREE[:2], atol=1e-3)
    assert info["position_error"] > 5.0  # the filter was not told
    assert info["localization"]["status"] == TRACKING  # and does not know yet
    with pytest.raises(ValueError, match="wall or"):
        base.kidnap((14.5, 7.0, 0.0))
    with pytest.raises(ValueError):
        base.kidnap((1.0, 2.0))


def test_kidnap_before_reset_is_an_error():
    with pytest.raises(RuntimeError, match="reset"):
        make().unwrapped.kidnap(FREE)


def test_unknown_start_is_reported_lost_until_the_filter_relocalizes():
    """obs["status"] and info["localization"] follow the filter: lost, relocalizing, then tracking
    near the truth, with the recovery counted."""
    env = make(task="localize")
    obs, info = env.reset(seed=0, options={"believed_pose": "unknown"})
    codes = [int(obs["status"])]
    for _ in range(300):
        obs, _, _, _, info = env.step(np.array([0.2, 0.3], np.float32))
        assert int(obs["status"]) == STATUSES.index(info["localization"]["status"])
        if codes[-1] != int(obs["status"]):
            codes.append(int(obs["status"]))
        if info["localization"]["status"] == TRACKING:
            break
    assert [STATUSES[c] for c in codes][0] == LOST and STATUSES[codes[-1]] == TRACKING
    assert info["localization"]["relocalizations"] == 1 and info["localization"]["reason"] is None
    assert info["position_error"] < 0.5


def test_v2_observes_the_covariance_flat_as_sb3_and_rllib_expect():
    """The 6 unique entries of the symmetric matrix, upper triangle row by row; every Box of
    the observation 1-D or an image (Stable-Baselines3's checker warns on any other shape)."""
    from envs.agv_env import COVARIANCE_FLAT_INDEX

    v1, v2 = make("agvsim/PlantFloor-v1"), make("agvsim/PlantFloor-v2")
    assert v1.observation_space["covariance"].shape == (3, 3)  # -v1 keeps the documented matrix
    assert v2.observation_space["covariance"].shape == (6,)
    for key, space in gym.make("agvsim/PlantFloor-v2", observe_image=True).observation_space.spaces.items():
        if isinstance(space, spaces.Box):
            assert len(space.shape) == 1 or (len(space.shape) == 3 and space.dtype == np.uint8), key
    assert COVARIANCE_FLAT_INDEX == ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
    obs1, _ = v1.reset(seed=5)
    obs2, _ = v2.reset(seed=5)
    for _ in range(3):
        a = np.array([0.5, 0.2], np.float32)
        obs1, *_ = v1.step(a)
        obs2, *_ = v2.step(a)
    assert v2.observation_space.contains(obs2)
    expected = np.array([obs1["covariance"][i, j] for i, j in COVARIANCE_FLAT_INDEX], np.float32)
    np.testing.assert_array_equal(obs2["covariance"], expected)
    assert obs2["covariance"][1] == obs1["covariance"][1, 0]  # symmetric: nothing lost
    flat = make("agvsim/PlantFloor-v1", covariance="flat")
    assert flat.observation_space["covariance"].shape == (6,)


def test_covariance_form_is_validated():
    with pytest.raises(ValueError, match="EnvConfig.covariance must be one of matrix, flat; got .diagonal."):
        EnvConfig(covariance="diagonal")
