"""Drive a route and log what happened (no camera, no filter yet).

:func:`drive_route` runs the pure-pursuit follower on a pose source — the
true pose for the world-only demo — and logs true and dead-reckoned poses
each control step. Later stages (camera, EKF) add their own logs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from agvsim.control.pure_pursuit import FollowerParams, PurePursuit, RoutePath
from agvsim.simulation import SimConfig, Simulation


@dataclass(frozen=True)
class RunLog:
    """Per-control-step log of one run (N steps).

    Attributes:
        time: (N,) s.
        distance: (N,) true path length travelled so far (m).
        true_pose: (N, 3) ground-truth (x m, y m, θ rad).
        odometry_pose: (N, 3) dead-reckoned pose.
        command: (N, 2) commanded (v m/s, ω rad/s).
        collisions: number of contact begins during the run.
        arrivals: (station id, distance to it when passed in m) in order.
        completed: whether the route was finished before the step limit.
    """

    time: np.ndarray
    distance: np.ndarray
    true_pose: np.ndarray
    odometry_pose: np.ndarray
    command: np.ndarray
    collisions: int
    arrivals: tuple[tuple[str, float], ...]
    completed: bool

    def odometry_error(self) -> np.ndarray:
        """(N,) dead-reckoning position error (m)."""
        return np.linalg.norm(self.odometry_pose[:, :2] - self.true_pose[:, :2], axis=1)

    def odometry_heading_error(self) -> np.ndarray:
        """(N,) dead-reckoning heading error wrapped to (-π, π] (rad)."""
        d = self.odometry_pose[:, 2] - self.true_pose[:, 2]
        return np.arctan2(np.sin(d), np.cos(d))


def drive_route(world_map, rng: np.random.Generator, route: str = "default",
                config: SimConfig = SimConfig(), laps: float = 1.0,
                distance: float | None = None, follower: FollowerParams = FollowerParams(),
                max_time: float | None = None,
                progress: Callable[[float], None] | None = None) -> RunLog:
    """Drive ``route`` on ``world_map`` steering on the *true* pose.

    Args:
        world_map: the map.
        rng: the run's generator (odometry noise).
        route: route name.
        config: rates, vehicle, odometry.
        laps: passes of a loop route (ignored when ``distance`` is set).
        distance: drive this many metres of route instead (m).
        follower: path-follower tuning.
        max_time: step limit in simulated seconds (default: generous).
        progress: called with the route progress (m) each control step.

    Returns:
        the run's :class:`RunLog`.
    """
    path = RoutePath.from_route(world_map, route)
    if distance is not None:
        if not path.loop and distance > path.length:
            raise ValueError(f"route {route!r} is open and {path.length:.1f} m long; "
                             f"cannot drive {distance} m")
        laps = distance / path.length
    start = world_map.route(route)[0].pose
    pursuit = PurePursuit(path, follower, laps=laps, max_speed=config.vehicle.max_speed,
                          max_yaw_rate=config.vehicle.max_yaw_rate)
    sim = Simulation(world_map, start, config, rng)
    if max_time is None:
        max_time = 3.0 * pursuit.end_s / max(follower.cruise_speed, 0.1) + 60.0
    n_max = int(math.ceil(max_time * config.control_rate))
    times, dists, truth, odo, cmds = [], [], [], [], []
    collisions = 0
    for _ in range(n_max):
        v, w = pursuit.command(sim.true_pose)
        if pursuit.finished:
            break
        result = sim.step(v, w)
        collisions += int(result.collided)
        times.append(sim.time)
        dists.append(sim.distance)
        truth.append(sim.true_pose)
        odo.append(sim.odometry_pose)
        cmds.append((v, w))
        if progress is not None:
            progress(pursuit.progress)
    return RunLog(
        time=np.asarray(times), distance=np.asarray(dists),
        true_pose=np.asarray(truth).reshape(-1, 3), odometry_pose=np.asarray(odo).reshape(-1, 3),
        command=np.asarray(cmds).reshape(-1, 2), collisions=collisions,
        arrivals=tuple(pursuit.arrivals), completed=pursuit.finished)
