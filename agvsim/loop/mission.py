r"""The one route driver: drive a route with a pure-pursuit follower and log everything.

Each control step (default 10 Hz) the follower is given the pose it steers on —
the filter's estimate (``steer_on="estimate"``, a real AGV) or the true pose
(``steer_on="truth"``, the world-only demo) — and the closed loop
(:class:`~agvsim.loop.closed_loop.ClosedLoop`) advances: simulation, odometry
into the filter, camera frames at their own rate (default 4 Hz, the thesis's
quarter second) at the vehicle's *true* pose, fused ``latency`` seconds later
at their capture time. With vision off, the filter is still predicted at the
frame times, so the log always carries an estimate and its covariance.

Logged per control step (:class:`~agvsim.loop.log.MissionLog`): true,
dead-reckoned and estimated pose, the estimate's covariance, the command,
whether the filter was lost; per frame: the observations with their
association, NIS and timings. A long run's record is thinned to
``MissionConfig.record`` (:mod:`agvsim.loop.record`: its memory is bounded
whatever the distance), with exact totals over every step and frame.

Seeding: the run's generator is split once, ``rng.spawn(2)`` (odometry,
camera), inside the closed loop; the same seed gives the same run, bit for bit.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from agvsim.loop.closed_loop import ClosedLoop, LoopConfig, LoopStep
from agvsim.loop.log import Arrival, MissionLog, frame_record
from agvsim.loop.record import MissionRecorder, RecordLimits
from agvsim.loop.modes import STEER_ON
from agvsim.loop.pure_pursuit import FollowerParams, PurePursuit, RoutePath
from localizer.numeric import check_choice, check_number

__all__ = ["MissionConfig", "run_mission"]


@dataclass(frozen=True)
class MissionConfig(LoopConfig):
    """A driven run: the loop (:class:`~agvsim.loop.closed_loop.LoopConfig` fields) plus the route.

    Attributes:
        route: route name.
        distance: drive this many metres of route (m); None: ``laps`` passes.
        laps: passes of a loop route when ``distance`` is None.
        steer_on: the pose the follower steers on, one of :data:`~agvsim.loop.modes.STEER_ON`.
        vision: False: no camera; dead reckoning through the filter only (the contrast run).
        follower: path follower tuning.
        max_time: step limit (s); None: generous (three times the route at cruise speed + 60 s).
        record: how much of the run the log keeps in full (beyond it, a thinned record and
            totals over every step: :mod:`agvsim.loop.record`).
    """

    route: str = "default"
    distance: float | None = None  # m
    laps: float = 1.0
    steer_on: str = "estimate"
    vision: bool = True
    follower: FollowerParams = field(default_factory=FollowerParams)
    max_time: float | None = None  # s
    record: RecordLimits = field(default_factory=RecordLimits)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.distance is not None:
            check_number("MissionConfig.distance", self.distance, low=0.0, low_open=True, unit="m")
        check_number("MissionConfig.laps", self.laps, low=0.0, low_open=True)
        check_choice("MissionConfig.steer_on", self.steer_on, STEER_ON)
        if self.max_time is not None:
            check_number("MissionConfig.max_time", self.max_time, low=0.0, low_open=True, unit="s")


def _follower(world_map, config: MissionConfig) -> PurePursuit:
    """The pure-pursuit follower over ``config.route`` for ``config.distance`` or ``config.laps``."""
    path = RoutePath.from_route(world_map, config.route)
    laps = config.laps
    if config.distance is not None:
        if not path.loop and config.distance > path.length:
            raise ValueError(f"route {config.route!r} is open and {path.length:.1f} m long; "
                             f"cannot drive {config.distance} m")
        laps = config.distance / path.length
    vp = config.sim.vehicle
    return PurePursuit(path, config.follower, laps=laps, max_speed=vp.max_speed, max_yaw_rate=vp.max_yaw_rate)


def run_mission(world_map, source, rng: np.random.Generator, config: MissionConfig = MissionConfig(),
                progress: Callable[[float], None] | None = None,
                observer: Callable[[ClosedLoop, LoopStep], None] | None = None) -> MissionLog:
    """Drive ``config.route`` on ``world_map`` from its first station.

    Args:
        world_map: the map (the world, and the filter's target list).
        source: an observation source (:mod:`agvsim.sensors`), or None with ``vision=False``.
        rng: the run's generator (split into odometry and camera streams).
        config: the run's settings.
        progress: called with the route progress (m) each control step.
        observer: called with the loop and its :class:`~agvsim.loop.closed_loop.LoopStep` after
            each control step (a recording, an exported log: it reads, it does not steer).

    Returns:
        the run's :class:`~agvsim.loop.log.MissionLog`.
    """
    if config.vision and source is None:
        raise ValueError("run_mission: vision is on but no observation source was given "
                         "(pass a source from agvsim.sensors.make_source, or MissionConfig(vision=False))")
    pursuit = _follower(world_map, config)
    start = tuple(float(v) for v in world_map.route(config.route)[0].pose)
    loop = ClosedLoop(world_map, start, rng, config, source if config.vision else None)
    sim, ekf = loop.sim, loop.ekf
    max_time = config.max_time
    if max_time is None:
        max_time = 3.0 * pursuit.end_s / max(config.follower.cruise_speed, 0.1) + 60.0
    n_max = int(math.ceil(max_time * config.sim.control_rate))
    on_truth = config.steer_on == "truth"
    record = MissionRecorder(config.record)
    station_xy = {s.id: s.position for s in world_map.stations}
    collisions = 0
    started = time.perf_counter()

    for _ in range(n_max):
        t_step = time.perf_counter()
        pose_est = ekf.pose()
        v, w = pursuit.command(sim.true_pose if on_truth else tuple(pose_est))
        for sid, d_steer in pursuit.arrivals:
            true_xy = np.asarray(sim.true_pose[:2], dtype=float)
            record.arrival(Arrival(sid, d_steer, float(np.linalg.norm(true_xy - station_xy[sid])),
                                   float(np.linalg.norm(true_xy - pose_est[:2]))))
        pursuit.arrivals.clear()  # (recorded: the follower's list stays short whatever the distance)
        if pursuit.finished:
            break
        step = loop.step(v, w)
        collisions += int(step.sim.collided)
        for f in step.fused:
            record.frame(frame_record(f))
        record.step(sim.time, sim.distance, sim.true_pose, sim.odometry_pose, ekf.pose(), ekf.covariance(),
                    (v, w), ekf.lost, (time.perf_counter() - t_step) * 1e3)
        if observer is not None:
            observer(loop, step)
        if progress is not None:
            progress(pursuit.progress)
    t_sim, t_obs, t_filter = (loop.timings[k] for k in ("sim", "observe", "filter"))
    total = time.perf_counter() - started
    return record.finish(
        completed=pursuit.finished, collisions=collisions, rejections=ekf.rejections,
        relocalizations=ekf.relocalizations, lost_events=ekf.lost_events,
        timings={"sim": t_sim, "observe": t_obs, "filter": t_filter, "total": total},
        steer_on=config.steer_on)
