"""The localizer and the pose filter on a logged drive: :func:`track`.

The same filter the closed loop runs (:class:`localizer.filter.PoseEKF`, configured as
:func:`agvsim.loop.closed_loop.filter_config_for` does for the vehicle's odometry preset and the
camera's field of view): each odometry interval is added at its stamp; each frame, in time
order, is searched by :func:`localizer.detect_targets` and its observations fused at its
capture stamp (inflated for motion blur while turning, :func:`~agvsim.loop.closed_loop.with_turn_blur`).
The estimate is kept at every odometry stamp.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from agvsim.replay.drive import DriveLog, VehicleFile, gaps, increments
from localizer.numeric import wrap_angle

__all__ = ["GAP", "TrackResult", "TrackSetup", "dead_reckoned", "track", "truth_at"]

#: s, an odometry interval longer than this is a gap (said once, with their count)
GAP = 0.5


@dataclass(frozen=True)
class TrackSetup:
    """What a drive is tracked against and with.

    Attributes:
        world_map: the plant's map (its targets and free space).
        camera: the camera (:class:`localizer.Camera`); frames of another size are refused.
        vehicle: the vehicle file (track width, ticks per metre, camera mount, odometry preset).
        start: the start pose (x m, y m, θ rad) with ``start_sigma``; None: unknown (the filter
            starts lost and localizes from the targets it sees).
        start_sigma: (σ_x m, σ_y m, σ_θ rad) of ``start``.
    """

    world_map: object
    camera: object
    vehicle: VehicleFile
    start: tuple[float, float, float] | None = None
    start_sigma: tuple[float, float, float] = (0.01, 0.01, 0.002)  # m, m, rad


@dataclass(frozen=True)
class TrackResult:
    """The estimate along a logged drive.

    Attributes:
        time: (N,) odometry stamps (s); estimate: (N, 3) (x m, y m, θ rad); covariance: (N, 3, 3);
        status: (N,) the filter's status after each stamp.
        frames_used, frames_refused, frames_with_targets: counts; targets_seen, targets_fused:
            observations made and fused.
        lost_events: times the filter declared itself lost.
        notes: what was skipped or repaired, one line each.
        truth: (N, 3) the log's true pose at each stamp (interpolated), or None.
        interrupted: Ctrl-C stopped the track: the arrays end at the last stamp it reached.
    """

    time: np.ndarray
    estimate: np.ndarray
    covariance: np.ndarray
    status: np.ndarray
    frames_used: int
    frames_refused: int
    frames_with_targets: int
    targets_seen: int
    targets_fused: int
    lost_events: int
    notes: tuple[str, ...] = ()
    truth: np.ndarray | None = field(default=None)
    interrupted: bool = False

    def errors(self) -> np.ndarray | None:
        """(N,) position error against the truth (m), or None without it."""
        if self.truth is None:
            return None
        return np.linalg.norm(self.estimate[:, :2] - self.truth[:, :2], axis=1)

    def summary(self) -> dict:
        """The figures of ``agvsim track --json``: SI units, None where there is no truth."""
        e = self.errors()
        return {"position_rmse_m": None if e is None else float(np.sqrt(np.mean(e ** 2))),
                "position_max_m": None if e is None else float(e.max()),
                "lost_events": self.lost_events, "frames_used": self.frames_used,
                "frames_refused": self.frames_refused, "frames_with_targets": self.frames_with_targets,
                "targets_seen": self.targets_seen, "targets_fused": self.targets_fused,
                "duration_s": float(self.time[-1] - self.time[0]) if len(self.time) else 0.0,
                "notes": list(self.notes)}


def dead_reckoned(log: DriveLog, setup: TrackSetup) -> tuple[np.ndarray, np.ndarray] | None:
    """The log's odometry integrated alone from ``setup.start``: ``(t (N,) s, poses (N, 3) x m,
    y m, θ rad)`` at the odometry's stamps, or None when the start is unknown. The same
    integration as the simulator's dead reckoning (:class:`agvsim.vehicle.odometry.DeadReckoning`,
    fed each interval's arc as the wheels of a unit vehicle)."""
    from agvsim.vehicle.encoders import WheelTicks
    from agvsim.vehicle.odometry import DeadReckoning

    if setup.start is None:
        return None
    t, ds, dth = increments(log, setup.vehicle)
    # a vehicle of wheel radius 1 m, 1 count per radian and wheelbase 2 m: wheel arcs ds -/+ dθ
    reckoning = DeadReckoning(setup.start, 1.0, 2.0, 1.0, WheelTicks(0.0, 0.0))
    left, right = np.cumsum(ds - dth), np.cumsum(ds + dth)
    poses = np.empty((len(t), 3))
    for i in range(len(t)):
        reckoning.update_counts(float(left[i]), float(right[i]))
        poses[i] = reckoning.pose
    return t, poses


def truth_at(truth: np.ndarray, times: np.ndarray) -> np.ndarray:
    """``(N, 3)`` the true pose at ``times`` (s) from rows (t, x, y, θ): x, y linear, θ along the
    shorter way round."""
    t = truth[:, 0]
    unwrapped = np.unwrap(truth[:, 3])
    return np.stack([np.interp(times, t, truth[:, 1]), np.interp(times, t, truth[:, 2]),
                     wrap_angle(np.interp(times, t, unwrapped))], axis=1)


def _filter(setup: TrackSetup, t0: float):
    from agvsim.sensors.vision import targets_from_map
    from agvsim.loop.closed_loop import odometry_noise_for
    from agvsim.vehicle.dynamics import VehicleParams
    from agvsim.vehicle.encoders import OdometryErrorModel
    from agvsim.vehicle.simulation import SimConfig
    from localizer.filter import FilterConfig, GateConfig, PoseEKF, ViewLimits

    v = setup.vehicle
    sim = SimConfig(vehicle=VehicleParams(track_width=v.track_width), odometry=OdometryErrorModel.preset(v.odometry))
    cam = setup.camera
    half_fov = math.atan(0.5 * cam.width / cam.fx)
    view = ViewLimits(half_fov=half_fov, min_range=0.3, max_range=11.0, max_incidence=math.radians(75.0))
    cfg = FilterConfig(noise=odometry_noise_for(sim), gate=GateConfig(view=view))
    world = setup.world_map
    if setup.start is None:
        xmin, ymin, xmax, ymax = world.bounds
        x0, P0 = np.array([0.5 * (xmin + xmax), 0.5 * (ymin + ymax), 0.0]), np.diag([1.0, 1.0, 0.1])
    else:
        x0, P0 = np.asarray(setup.start, dtype=float), np.diag(np.asarray(setup.start_sigma, dtype=float) ** 2)
    ekf = PoseEKF(x0, P0, targets_from_map(world), v.mount, cfg, t0=t0, free_space=world.is_free)
    if setup.start is None:
        ekf.declare_lost("start pose unknown")
    return ekf


def _frame(log: DriveLog, k: int, camera, notes: dict) -> np.ndarray | None:
    """The k-th frame, or None (counted in ``notes`` by reason) when it cannot be used."""
    try:
        image = log.read_frame(k)
    except ValueError as exc:
        notes.setdefault("unreadable", [0, str(exc)])[0] += 1
        return None
    if image.shape[:2] != (camera.height, camera.width):
        what = notes.setdefault("size", [0, f"{log.source}: frame {k} is {image.shape[1]} x {image.shape[0]} px, "
                                            f"the camera file's {camera.width} x {camera.height}: refused"])
        what[0] += 1
        return None
    return image


def track(log: DriveLog, setup: TrackSetup, progress: Callable[[int], None] | None = None,
          on_frame: Callable | None = None) -> TrackResult:
    """Run the localizer and the filter along ``log`` (the module docstring).

    Args:
        log: the drive.
        setup: the map, camera, vehicle and start.
        progress: called with the number of frames done after each frame.
        on_frame: called as ``on_frame(t, image, detections, ekf, result)`` after each frame fused
            (a recording); ``result`` the filter's :class:`~localizer.filter.FrameResult`.

    Ctrl-C ends the track where it is: the result holds what was tracked up to then
    (``interrupted``), so that its caller can keep it.
    """
    from agvsim.loop.closed_loop import LoopConfig, with_turn_blur
    from localizer import detect_targets
    from localizer.model.target import TargetSpec

    t, ds, dth = increments(log, setup.vehicle)
    ekf = _filter(setup, float(log.odometry_times[0]))
    spec = setup.world_map.targets[0].spec if setup.world_map.targets else TargetSpec()
    blur = LoopConfig().turn_blur_noise
    n = len(t)
    rates = dth / np.maximum(np.diff(log.odometry_times), 1e-9)  # rad/s over each interval
    est, cov, status = np.empty((n, 3)), np.empty((n, 3, 3)), np.empty(n, dtype=object)
    counts = {"used": 0, "with": 0, "seen": 0, "fused": 0}
    problems: dict = {}
    frames = log.frame_times
    inside = (frames >= log.odometry_times[0]) & (frames <= log.odometry_times[-1])
    notes = list(log.notes)
    if (~inside).any():
        notes.append(f"{log.source}: {int((~inside).sum())} frames outside the odometry's time span: skipped")
    if gaps(log.odometry_times, GAP):
        notes.append(f"{log.source}: {gaps(log.odometry_times, GAP)} gaps of more than {GAP:g} s in the odometry "
                     "(the filter predicts across them)")
    i, interrupted = 0, False
    try:
        for k in range(len(frames)):
            if not inside[k]:
                continue
            while i < n and t[i] <= frames[k]:
                ekf.add_odometry(float(t[i]), float(ds[i]), float(dth[i]))
                est[i], cov[i], status[i] = ekf.pose(), ekf.covariance(), ekf.status
                i += 1
            image = _frame(log, k, setup.camera, problems)
            if image is not None:
                yaw_rate = float(rates[i - 1]) if i else 0.0
                found = detect_targets(image, setup.camera, spec)
                result = ekf.process_frame(float(frames[k]), [with_turn_blur(o, yaw_rate, blur) for o in found])
                counts["used"] += 1
                counts["with"] += bool(found)
                counts["seen"] += len(found)
                counts["fused"] += result.accepted
                if on_frame is not None:
                    on_frame(float(frames[k]), image, found, ekf, result)
            if progress is not None:
                progress(k + 1)
        while i < n:
            ekf.add_odometry(float(t[i]), float(ds[i]), float(dth[i]))
            est[i], cov[i], status[i] = ekf.pose(), ekf.covariance(), ekf.status
            i += 1
    except KeyboardInterrupt:  # (Ctrl-C: what was tracked so far, up to the last stamp reached)
        interrupted = True
        t, est, cov, status = t[:i], est[:i], cov[:i], status[:i]
    notes += [f"{message} ({count} frames)" if count > 1 else message for count, message in problems.values()]
    refused = sum(c for c, _ in problems.values())
    truth = truth_at(log.truth, t) if log.truth is not None and len(log.truth) > 1 else None
    return TrackResult(t, est, cov, status.astype(str), counts["used"], refused, counts["with"], counts["seen"],
                       counts["fused"], ekf.lost_events, tuple(notes), truth, interrupted)
