"""What the agent is asked to do: tasks as small classes (reward, termination, goal drawing).

Each task gets the episode's :class:`~agvsim.loop.closed_loop.ClosedLoop` and
adds its part of the reward; the environment adds the shared parts (time cost,
collision penalty, ``terminate_on_collision``).

Adding a task: subclass :class:`Task`, set :attr:`Task.name`, override
:meth:`Task.draw_goal`, :meth:`Task.reward` and :meth:`Task.is_terminal` as
needed, and add it to :data:`TASKS`. Its name then is a valid ``task=`` of
every environment, and the env docstring's task list reads it.
"""
from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

__all__ = ["GotoTask", "LocalizeTask", "TASKS", "TASK_NAMES", "Task"]


class Task:
    """The base task: no goal, no reward of its own, never terminal.

    Args:
        config: the environment's :class:`~envs.config.EnvConfig` (task settings are read from it).
    """

    name: ClassVar[str] = ""
    #: one line for docs and errors
    summary: ClassVar[str] = ""

    def __init__(self, config) -> None:
        self.config = config
        self.goal = None  # a map Station, or None

    def draw_goal(self, world_map, station_ids: list[str], start_id: str, rng: np.random.Generator):
        """The goal station of a new episode (drawn from ``rng``), or None."""
        self.goal = None
        return None

    def reset(self, loop) -> None:
        """Called once the episode's closed loop exists."""

    def reward(self, loop, step) -> float:
        """The task's part of the reward for one step (:class:`~agvsim.loop.closed_loop.LoopStep`)."""
        return 0.0

    def is_terminal(self, loop) -> bool:
        """Whether the task is done after this step."""
        return False

    def goal_distance(self, loop) -> float:
        """Distance (m) from the true pose to the goal; 0 without a goal."""
        if self.goal is None:
            return 0.0
        x, y, _ = loop.sim.true_pose  # the same x, y as loop.true_pose, without building an array
        return float(math.hypot(self.goal.pose[0] - x, self.goal.pose[1] - y))


class GotoTask(Task):
    """Drive from a start station to a goal station of the route.

    Reward: progress towards the goal measured on the *true* pose (m closer this
    step). Terminal: the true pose within ``goal_radius`` of the goal.
    """

    name = "goto"
    summary = "drive to a goal station (reward: metres of progress on the true pose)"

    def draw_goal(self, world_map, station_ids, start_id, rng):
        others = [i for i in station_ids if i != start_id]
        self.goal = world_map.station(others[int(rng.integers(len(others)))])
        return self.goal

    def reset(self, loop) -> None:
        self._previous = self.goal_distance(loop)

    def reward(self, loop, step) -> float:
        dist = self.goal_distance(loop)
        gain = self._previous - dist
        self._previous = dist
        return gain

    def is_terminal(self, loop) -> bool:
        return self.goal_distance(loop) <= self.config.goal_radius


class LocalizeTask(Task):
    """Active localization: stay localized.

    Reward ``1 / (1 + (e / error_scale)²)`` per step for the true position error
    e (m) of the believed pose, so planners learn to seek targets. Never terminal.
    """

    name = "localize"
    summary = "stay localized (reward: 1 / (1 + (e / error_scale)^2) for the position error e)"

    def reward(self, loop, step) -> float:
        tx, ty, _ = loop.sim.true_pose
        bx, by, _ = loop.believed_pose.tolist()
        err = float(np.hypot(tx - bx, ty - by))
        return 1.0 / (1.0 + (err / self.config.error_scale) ** 2)


#: task name -> class: the one list of tasks (env validation, docs).
TASKS: dict[str, type[Task]] = {cls.name: cls for cls in (GotoTask, LocalizeTask)}
TASK_NAMES: tuple[str, ...] = tuple(TASKS)
