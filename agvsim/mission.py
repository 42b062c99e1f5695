r"""The closed loop: drive a route steering on the *estimated* pose.

Each control step (default 10 Hz) the pure-pursuit follower is given the
filter's current pose; the simulation advances; the odometry increment is
queued in the filter. The camera captures a frame at its own rate (default
4 Hz, the thesis's quarter second) at the vehicle's *true* pose; the frame's
observations become available ``latency`` seconds later (rounded up to the
next control step) and are fused then, at their capture time
(:class:`localizer.filter.PoseEKF` lags its state and re-applies the newer
odometry). With vision off, the filter is still predicted at the frame times.

Logged per control step: true, dead-reckoned and estimated pose, the
estimate's covariance, the command, whether the filter was lost; per frame:
the observations with their association, NIS and timings.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from agvsim.closed_loop import ClosedLoop, FusedFrame
from agvsim.control.pure_pursuit import FollowerParams, PurePursuit, RoutePath
from agvsim.observe import VisionConfig, targets_from_map
from agvsim.simulation import SimConfig, Simulation
from localizer.filter import FilterConfig, OdometryNoise, PoseEKF

__all__ = ["FrameRecord", "MissionConfig", "MissionLog", "ObservationRecord", "filter_config_for",
           "odometry_noise_for", "run_mission"]


def odometry_noise_for(config: SimConfig, correlation: float = 15.0, inflation: float = 1.0) -> OdometryNoise:
    """The filter's motion-noise model matching the simulation's odometry error preset.

    Random part: the per-wheel noise as is. Systematic part (unknown to the filter):
    |E_d - 1| and |E_b - 1| folded in as noise accumulating over ``correlation`` m
    (about the distance between target sightings on the shipped maps). Quantization
    error does not accumulate (the counts are cumulative) and is left out.
    """
    e = config.odometry
    return OdometryNoise(wheel_noise=e.wheel_noise, track_width=config.vehicle.track_width,
                         diameter_bias=abs(e.ed - 1.0), wheelbase_bias=abs(e.eb - 1.0), scale_bias=0.0,
                         correlation=correlation, inflation=inflation)


def filter_config_for(config: SimConfig, vision: VisionConfig, **kw) -> FilterConfig:
    """A :class:`FilterConfig` for this odometry and camera (``kw`` overrides fields)."""
    from localizer.filter import GateConfig

    base = dict(noise=odometry_noise_for(config), gate=GateConfig(view=vision.view_limits()))
    base.update(kw)
    return FilterConfig(**base)


@dataclass(frozen=True)
class MissionConfig:
    """A closed-loop run.

    Attributes:
        route: route name.
        distance: drive this many metres of route (m); None: ``laps`` passes.
        laps: passes of a loop route when ``distance`` is None.
        camera_rate: frames per second (Hz).
        latency: capture-to-fusion delay (s).
        vision: False: dead reckoning through the filter only (the contrast run).
        sim: rates, vehicle, odometry.
        follower: path follower tuning.
        vision_config: the camera.
        filter: filter settings; None: :func:`filter_config_for`.
        initial_sigma: (σ_x m, σ_y m, σ_θ rad) of the start pose given to the filter.
        initial_error: (3,) error added to the start pose given to the filter (m, m, rad).
        max_time: step limit (s); None: generous.
        turn_blur_noise: (k_d 1/(rad/s), k_β s, k_α s): extra standard deviations
            ``σ_d = k_d |ω| d``, ``σ_β = k_β |ω|``, ``σ_α = k_α |ω|`` added in quadrature to each
            observation of a frame captured while the vehicle turns at yaw rate ω (rad/s, from
            the odometry). Motion blur while turning biases the localizer's d and α beyond its
            reported covariance: in rendered frames (10 ms exposure, 16 mm lens, d ≈ 3 m,
            ω ≈ 0.55 rad/s) α was off by 10-18 mrad (3-9 reported σ) and d by 5-20 mm, while the
            same frames without blur were within 1 σ.
    """

    route: str = "default"
    distance: float | None = None  # m
    laps: float = 1.0
    camera_rate: float = 4.0  # Hz
    latency: float = 0.25  # s
    vision: bool = True
    sim: SimConfig = field(default_factory=SimConfig)
    follower: FollowerParams = field(default_factory=FollowerParams)
    vision_config: VisionConfig = field(default_factory=VisionConfig)
    filter: FilterConfig | None = None
    initial_sigma: tuple[float, float, float] = (0.01, 0.01, 0.002)  # m, m, rad
    initial_error: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m, m, rad
    max_time: float | None = None  # s
    turn_blur_noise: tuple[float, float, float] = (0.01, 0.0, 0.03)  # 1/(rad/s), s, s

    def __post_init__(self) -> None:
        if not (math.isfinite(self.camera_rate) and self.camera_rate > 0):
            raise ValueError(f"MissionConfig.camera_rate must be > 0 Hz, got {self.camera_rate!r}")
        if not (math.isfinite(self.latency) and self.latency >= 0):
            raise ValueError(f"MissionConfig.latency must be >= 0 s, got {self.latency!r}")
        if self.distance is not None and not (math.isfinite(self.distance) and self.distance > 0):
            raise ValueError(f"MissionConfig.distance must be > 0 m, got {self.distance!r}")
        if not (math.isfinite(self.laps) and self.laps > 0):
            raise ValueError(f"MissionConfig.laps must be > 0, got {self.laps!r}")
        if len(self.turn_blur_noise) != 3 or not all(math.isfinite(k) and k >= 0 for k in self.turn_blur_noise):
            raise ValueError(f"MissionConfig.turn_blur_noise must be 3 values >= 0, got {self.turn_blur_noise!r}")
        if len(self.initial_sigma) != 3 or not all(math.isfinite(s) and s > 0 for s in self.initial_sigma):
            raise ValueError(f"MissionConfig.initial_sigma must be 3 positive values, got {self.initial_sigma!r}")


@dataclass(frozen=True)
class ObservationRecord:
    """One observation of a frame and what the filter made of it."""

    distance: float  # m
    beta: float  # rad
    alpha: float  # rad
    polarity: str
    truth_id: str | None  # target really seen (None: false detection / unknown)
    status: str  # association status ("lost" while re-localizing)
    target_id: str  # target it was matched to ("" if none)
    d2: float  # Mahalanobis D² to the best candidate


@dataclass(frozen=True)
class FrameRecord:
    """One camera frame.

    Attributes:
        capture_time, fuse_time: s.
        step: control step index at capture.
        observations: per observation.
        accepted: observations fused.
        nis: (k,) NIS of the fused observations.
        observe_ms: render + detect wall time (ms).
        filter_ms: fusion wall time (ms).
        relocalized: this frame confirmed a re-localization.
    """

    capture_time: float
    fuse_time: float
    step: int
    observations: tuple[ObservationRecord, ...]
    accepted: int
    nis: np.ndarray
    observe_ms: float
    filter_ms: float
    relocalized: bool


@dataclass(frozen=True)
class MissionLog:
    """Per-control-step log of a closed-loop run (N steps) and its frames.

    Attributes:
        time, distance: (N,) s, m (true path length so far).
        true_pose, odometry_pose, estimate: (N, 3) (x m, y m, θ rad).
        covariance: (N, 3, 3) covariance of the estimate.
        command: (N, 2) (v m/s, ω rad/s).
        lost: (N,) bool, filter lost after the step.
        step_ms: (N,) wall time of each control step (ms): control, physics, frame and filter work.
        frames: the camera frames in capture order.
        arrivals: (station id, distance of the estimate to it m, distance of the truth to it m,
            position error of the estimate m) when the follower passed each station.
        completed: route finished before the step limit.
        collisions: contact begins.
        rejections, relocalizations, lost_events: filter counters at the end.
        timings: wall seconds spent in "sim", "observe", "filter", "total".
        stations: (station id, x m, y m) of the route.
    """

    time: np.ndarray
    distance: np.ndarray
    true_pose: np.ndarray
    odometry_pose: np.ndarray
    estimate: np.ndarray
    covariance: np.ndarray
    command: np.ndarray
    lost: np.ndarray
    step_ms: np.ndarray
    frames: tuple[FrameRecord, ...]
    arrivals: tuple[tuple[str, float, float, float], ...]
    completed: bool
    collisions: int
    rejections: int
    relocalizations: int
    lost_events: int
    timings: dict


def _frame_record(f: FusedFrame) -> FrameRecord:
    """A fused frame with its observations' association, for the log."""
    res = f.result
    assoc = {a.observation: a for a in res.associations}
    recs = []
    for k, o in enumerate(f.observations):
        a = assoc.get(k)
        recs.append(ObservationRecord(float(o.distance), float(o.beta), float(o.alpha), str(o.polarity),
                                      getattr(o, "truth_id", None), a.status if a else "lost",
                                      a.target_id if a else "", float(a.d2) if a else math.inf))
    return FrameRecord(f.capture_time, f.fuse_time, f.step, tuple(recs), res.accepted, res.nis,
                       f.observe_ms, f.filter_ms, res.relocalized)


def run_mission(world_map, source, rng: np.random.Generator, config: MissionConfig = MissionConfig(),
                progress: Callable[[float], None] | None = None) -> MissionLog:
    """Drive ``config.route`` on ``world_map`` steering on the filter's estimate.

    Args:
        world_map: the map (the world, and the filter's target list).
        source: an observation source (:mod:`agvsim.observe`), or None with ``vision=False``.
        rng: the run's generator; split into odometry and camera streams.
        config: the run's settings.
        progress: called with the route progress (m) each control step.
    """
    if config.vision and source is None:
        raise ValueError("run_mission: vision is on but no observation source was given")
    sim_rng, cam_rng = rng.spawn(2)
    path = RoutePath.from_route(world_map, config.route)
    laps = config.laps
    if config.distance is not None:
        if not path.loop and config.distance > path.length:
            raise ValueError(f"route {config.route!r} is open and {path.length:.1f} m long; "
                             f"cannot drive {config.distance} m")
        laps = config.distance / path.length
    start = tuple(float(v) for v in world_map.route(config.route)[0].pose)
    sc = config.sim
    pursuit = PurePursuit(path, config.follower, laps=laps, max_speed=sc.vehicle.max_speed,
                          max_yaw_rate=sc.vehicle.max_yaw_rate)
    sim = Simulation(world_map, start, sc, sim_rng)
    fcfg = config.filter or filter_config_for(sc, config.vision_config)
    x0 = np.asarray(start) + np.asarray(config.initial_error, dtype=float)
    P0 = np.diag(np.asarray(config.initial_sigma, dtype=float) ** 2)
    ekf = PoseEKF(x0, P0, targets_from_map(world_map), config.vision_config.mount2d, fcfg, t0=0.0)
    max_time = config.max_time
    if max_time is None:
        max_time = 3.0 * pursuit.end_s / max(config.follower.cruise_speed, 0.1) + 60.0
    n_max = int(math.ceil(max_time * sc.control_rate))
    loop = ClosedLoop(sim, ekf, source if config.vision else None, cam_rng, camera_rate=config.camera_rate,
                      latency=config.latency, turn_blur_noise=config.turn_blur_noise)
    rows_t, rows_d, truth, odo, est, cov, cmds, lost, step_ms = [], [], [], [], [], [], [], [], []
    frames: list[FrameRecord] = []
    arrivals: list[tuple[str, float, float, float]] = []
    station_xy = {s.id: s.position for s in world_map.stations}
    collisions = 0
    started = time.perf_counter()

    for _ in range(n_max):
        t_step = time.perf_counter()
        pose_est = ekf.pose()
        n_arr = len(pursuit.arrivals)
        v, w = pursuit.command(tuple(pose_est))
        for sid, d_est in pursuit.arrivals[n_arr:]:
            true_xy = np.asarray(sim.true_pose[:2], dtype=float)
            arrivals.append((sid, d_est, float(np.linalg.norm(true_xy - station_xy[sid])),
                             float(np.linalg.norm(true_xy - pose_est[:2]))))
        if pursuit.finished:
            break
        step = loop.step(v, w)
        collisions += int(step.sim.collided)
        frames.extend(_frame_record(f) for f in step.fused)
        rows_t.append(sim.time)
        rows_d.append(sim.distance)
        truth.append(sim.true_pose)
        odo.append(sim.odometry_pose)
        est.append(ekf.pose())
        cov.append(ekf.covariance())
        cmds.append((v, w))
        lost.append(ekf.lost)
        step_ms.append((time.perf_counter() - t_step) * 1e3)
        if progress is not None:
            progress(pursuit.progress)
    t_sim, t_obs, t_filter = (loop.timings[k] for k in ("sim", "observe", "filter"))
    total = time.perf_counter() - started
    n = len(rows_t)
    return MissionLog(
        time=np.asarray(rows_t), distance=np.asarray(rows_d),
        true_pose=np.asarray(truth, dtype=float).reshape(n, 3),
        odometry_pose=np.asarray(odo, dtype=float).reshape(n, 3),
        estimate=np.asarray(est, dtype=float).reshape(n, 3),
        covariance=np.asarray(cov, dtype=float).reshape(n, 3, 3),
        command=np.asarray(cmds, dtype=float).reshape(n, 2), lost=np.asarray(lost, dtype=bool),
        step_ms=np.asarray(step_ms, dtype=float),
        frames=tuple(frames), arrivals=tuple(arrivals), completed=pursuit.finished,
        collisions=collisions, rejections=ekf.rejections, relocalizations=ekf.relocalizations,
        lost_events=ekf.lost_events,
        timings={"sim": t_sim, "observe": t_obs, "filter": t_filter, "total": total})
