"""The one log type of a driven run: :class:`MissionLog` and its records.

Written by :func:`agvsim.loop.mission.run_mission` whatever the follower steers on;
read by :mod:`agvsim.analysis` and the commands.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from localizer.numeric import wrap_angle

__all__ = ["Arrival", "FrameRecord", "MissionLog", "ObservationRecord", "frame_record"]


class Arrival(NamedTuple):
    """The follower passing a station of the route.

    Attributes:
        station: station id.
        steer_distance: distance from the pose steered on to the station (m).
        true_distance: distance from the true pose to the station (m).
        estimate_error: the filter estimate's position error then (m).
    """

    station: str
    steer_distance: float  # m
    true_distance: float  # m
    estimate_error: float  # m


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


def frame_record(fused) -> FrameRecord:
    """A fused frame (:class:`agvsim.loop.closed_loop.FusedFrame`) with its observations'
    association, for the log."""
    res = fused.result
    assoc = {a.observation: a for a in res.associations}
    recs = []
    for k, o in enumerate(fused.observations):
        a = assoc.get(k)
        recs.append(ObservationRecord(float(o.distance), float(o.beta), float(o.alpha), str(o.polarity),
                                      o.truth_id, a.status if a else "lost",
                                      a.target_id if a else "", float(a.d2) if a else math.inf))
    return FrameRecord(fused.capture_time, fused.fuse_time, fused.step, tuple(recs), res.accepted, res.nis,
                       fused.observe_ms, fused.filter_ms, res.relocalized)


@dataclass(frozen=True)
class MissionLog:
    """Per-control-step log of a driven run (N steps) and its frames.

    Attributes:
        time, distance: (N,) s, m (true path length so far).
        true_pose, odometry_pose, estimate: (N, 3) (x m, y m, θ rad).
        covariance: (N, 3, 3) covariance of the estimate.
        command: (N, 2) (v m/s, ω rad/s) as requested by the follower.
        lost: (N,) bool, filter lost after the step.
        step_ms: (N,) wall time of each control step (ms): control, physics, frame and filter work.
        frames: the camera frames in capture order.
        arrivals: the follower passing each station (:class:`Arrival`).
        completed: route finished before the step limit.
        collisions: contact begins.
        rejections, relocalizations, lost_events: filter counters at the end (a re-localization
            is a recovery from being lost; :meth:`time_lost` sums the lost steps).
        timings: wall seconds spent in "sim", "observe", "filter", "total".
        steer_on: what the follower steered on ("estimate" or "truth").
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
    arrivals: tuple[Arrival, ...]
    completed: bool
    collisions: int
    rejections: int
    relocalizations: int
    lost_events: int
    timings: dict
    steer_on: str = "estimate"

    def odometry_error(self) -> np.ndarray:
        """(N,) dead-reckoning position error (m)."""
        return np.linalg.norm(self.odometry_pose[:, :2] - self.true_pose[:, :2], axis=1)

    def odometry_heading_error(self) -> np.ndarray:
        """(N,) dead-reckoning heading error wrapped to [-π, π) (rad)."""
        return wrap_angle(self.odometry_pose[:, 2] - self.true_pose[:, 2])

    def time_lost(self) -> float:
        """Simulated seconds the filter spent lost (the steps after which :attr:`lost` is set,
        each counted for its own duration)."""
        if not len(self.time):
            return 0.0
        durations = np.diff(self.time, prepend=0.0)
        return float(durations[self.lost].sum())

    def estimate_error(self) -> np.ndarray:
        """(N,) position error of the filter's estimate (m)."""
        return np.linalg.norm(self.estimate[:, :2] - self.true_pose[:, :2], axis=1)
