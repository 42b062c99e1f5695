"""Tasks as classes, the camera mount as an env parameter, and the choice lists behind validation."""
from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from agvsim.world import load_map
from envs.config import EnvConfig
from envs.tasks import TASK_NAMES, TASKS, GotoTask, LocalizeTask, Task
from localizer.model.mount import CameraMount

FAST = {"observations": "geometric"}


def test_corridor_env_uses_the_corridors_mount_and_takes_another():
    env = gym.make("agvsim/Corridor-v2", **FAST).unwrapped
    assert env.vision.mount == load_map("corridor").camera_mount
    assert env.vision.mount != load_map("plant_floor").camera_mount
    env = gym.make("agvsim/Corridor-v2", **FAST, camera_mount={"forward": 0.2, "lateral": 0.0, "height": 1.0,
                                                               "yaw": -math.pi / 2}).unwrapped
    assert env.vision.mount == CameraMount(forward=0.2, lateral=0.0, height=1.0, yaw=-math.pi / 2)
    env.reset(seed=0)
    assert env.loop.ekf is not None and env.loop.vision.mount == env.vision.mount


def test_bad_mount_and_choices_are_one_line_errors():
    with pytest.raises(ValueError, match="camera_mount: unknown field.*heigth"):
        EnvConfig(camera_mount={"heigth": 1.0})
    with pytest.raises(ValueError, match="CameraMount.height must be a finite number > 0"):
        EnvConfig(camera_mount={"height": -1.0})
    with pytest.raises(ValueError, match=r"EnvConfig.task must be one of goto, localize; got 'gotoo'"):
        EnvConfig(task="gotoo")
    with pytest.raises(ValueError, match=r"EnvConfig.odometry must be one of ideal, typical, worn"):
        EnvConfig(odometry="new")
    with pytest.raises(ValueError, match=r"observations='geometric' draws none"):
        EnvConfig(observations="geometric", observe_image=True)
    with pytest.raises(ValueError, match=r"lighting_randomization=0.3 needs a source with an exposure"):
        EnvConfig(observations="geometric", lighting_randomization=0.3)


def test_tasks_registry_and_docstring_read_one_list():
    assert TASK_NAMES == tuple(TASKS) == ("goto", "localize")
    assert TASKS["goto"] is GotoTask and TASKS["localize"] is LocalizeTask
    doc = envs.AGVEnv.__doc__
    for name, cls in TASKS.items():
        assert f"``{name}``: {cls.summary}" in doc
    assert "{tasks}" not in doc and "'ideal' | 'typical' | 'worn'" in doc


def test_localize_task_rewards_a_small_error_and_goto_progress():
    env = gym.make("agvsim/ActiveLocalization-v2", **FAST, time_cost=0.0, collision_penalty=0.0).unwrapped
    env.reset(seed=0)
    _, reward, terminated, _, info = env.step(np.array([0.5, 0.0], np.float32))
    assert reward == pytest.approx(1.0 / (1.0 + (info["position_error"] / env.config.error_scale) ** 2))
    assert not terminated and isinstance(env.task, LocalizeTask) and env.task.goal is None
    base = Task(env.config)
    assert base.reward(env.loop, None) == 0.0 and base.is_terminal(env.loop) is False


def test_goto_terminates_at_the_goal():
    env = gym.make("agvsim/Corridor-v2", **FAST, goal_radius=100.0).unwrapped
    env.reset(seed=2)
    _, _, terminated, _, _ = env.step(np.zeros(2, np.float32))
    assert terminated  # every station is within 100 m


def test_filter_config_reaches_the_filter_over_the_envs_own():
    from agvsim.loop.closed_loop import filter_config_for
    from localizer.filter import FilterConfig
    from localizer.filter.wide import WideConfig

    plain = gym.make("agvsim/PlantFloor-v2", **FAST).unwrapped
    plain.reset(seed=0)
    assert plain.loop.ekf.config.wide is None
    env = gym.make("agvsim/PlantFloor-v2", **FAST, filter_config={"wide": WideConfig()}).unwrapped
    env.reset(seed=0)
    own = filter_config_for(env.sim_config, env.vision)
    assert env.loop.ekf.config.wide == WideConfig() and env.loop.ekf.config.noise == own.noise
    assert env.loop.ekf.config.gate == plain.loop.ekf.config.gate  # the env's camera limits kept
    whole = FilterConfig(lost_rejected_frames=5)
    env = gym.make("agvsim/Corridor-v2", **FAST, filter_config=whole).unwrapped
    env.reset(seed=0)
    assert env.loop.ekf.config is whole
    with pytest.raises(ValueError, match="filter_config: unknown field.*wid\\b"):
        EnvConfig(filter_config={"wid": WideConfig()})
    with pytest.raises(ValueError, match="FilterConfig.lost_rejected_frames must be"):
        EnvConfig(filter_config={"lost_rejected_frames": 0})
    with pytest.raises(ValueError, match="must be None, a localizer.filter.FilterConfig or a dict"):
        EnvConfig(filter_config="wide")
    with pytest.raises(ValueError, match="filter_config needs localization='ekf'"):
        EnvConfig(localization="truth", filter_config={})
