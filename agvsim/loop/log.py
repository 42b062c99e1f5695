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

__all__ = ["Arrival", "EventTotals", "FrameRecord", "MissionLog", "ObservationRecord", "StepTotals", "frame_record"]


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
class StepTotals:
    """Figures over every control step of a run, whatever its record kept
    (:mod:`agvsim.loop.record`): the errors of the estimate against the truth.

    Attributes:
        steps: control steps.
        position_sq_sum: Σ e² of the position error e (m²).
        position_max: max e (m).
        position_histogram: (:data:`~agvsim.loop.record.HISTOGRAM_BINS`,) counts of e per bin
            (:func:`~agvsim.loop.record.histogram_bins`), for its percentiles.
        heading_sq_sum: Σ of the squared wrapped heading error (rad²).
        heading_max: max |heading error| (rad).
        odometry_max: max dead-reckoning position error (m).
        nees_sum: Σ NEES; nees_in_bounds, nees_below_upper: steps with the NEES in the two-sided
            95 % interval, under its upper bound (:data:`~agvsim.loop.record.NEES_BOUNDS`).
        lost_steps: steps after which the filter was lost; time_lost: their seconds (s).
    """

    steps: int
    position_sq_sum: float  # m²
    position_max: float  # m
    position_histogram: np.ndarray
    heading_sq_sum: float  # rad²
    heading_max: float  # rad
    odometry_max: float  # m
    nees_sum: float
    nees_in_bounds: int
    nees_below_upper: int
    lost_steps: int
    time_lost: float  # s

    def to_arrays(self, prefix: str = "totals_") -> dict[str, np.ndarray]:
        """The figures as named arrays (for an ``.npz``); :meth:`from_arrays` reads them back."""
        return {prefix + k: np.asarray(getattr(self, k)) for k in self.__dataclass_fields__}

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "totals_") -> StepTotals | None:
        """The figures saved by :meth:`to_arrays` in the mapping ``arrays`` (None if absent)."""
        if prefix + "steps" not in arrays:
            return None
        kinds = {"steps": int, "nees_in_bounds": int, "nees_below_upper": int, "lost_steps": int}
        values = {}
        for k in cls.__dataclass_fields__:
            v = np.asarray(arrays[prefix + k])
            values[k] = v.astype(np.int64) if k == "position_histogram" else kinds.get(k, float)(v)
        return cls(**values)


@dataclass(frozen=True)
class EventTotals:
    """Counts over every camera frame and station arrival of a run, whatever its record kept.

    Attributes:
        frames: frames fused; with_observation: of them with an observation; with_accepted:
            with an accepted one; observed_with_accepted: with an observation and an accepted one.
        observations, accepted: observations, and those fused.
        wrong: accepted but not the target really seen; false_accepted: accepted false detections.
        statuses: association status -> observations.
        nis_count, nis_sum, nis_below_95: fused observations' NIS: count, Σ, count ≤ χ²₃(0.95).
        arrivals: stations passed; arrival_error_sum, arrival_error_max: the estimate's position
            error then (m); arrival_passing_sum: Σ of the true distances to the stations (m).
    """

    frames: int
    with_observation: int
    with_accepted: int
    observed_with_accepted: int
    observations: int
    accepted: int
    wrong: int
    false_accepted: int
    statuses: dict
    nis_count: int
    nis_sum: float
    nis_below_95: int
    arrivals: int
    arrival_error_sum: float  # m
    arrival_error_max: float  # m
    arrival_passing_sum: float  # m


@dataclass(frozen=True)
class MissionLog:
    """Per-control-step log of a driven run (N recorded steps) and its frames.

    A long run's record is thinned to bound its memory (:mod:`agvsim.loop.record`): the arrays
    then hold every ``stride``-th step and the last, ``frames`` every ``frame_stride``-th frame,
    ``arrivals`` every ``arrival_stride``-th arrival, and :attr:`step_totals` and
    :attr:`event_totals` the figures over all of them (a stride of 1: everything is recorded).

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
        stride, frame_stride, arrival_stride: the record keeps every stride-th item (1: all).
        step_totals, event_totals: figures over every step, frame and arrival (None in a log
            made by hand: the record is then all there is).
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
    stride: int = 1
    frame_stride: int = 1
    arrival_stride: int = 1
    step_totals: StepTotals | None = None
    event_totals: EventTotals | None = None

    def odometry_error(self) -> np.ndarray:
        """(N,) dead-reckoning position error at the recorded steps (m)."""
        return np.linalg.norm(self.odometry_pose[:, :2] - self.true_pose[:, :2], axis=1)

    def odometry_heading_error(self) -> np.ndarray:
        """(N,) dead-reckoning heading error at the recorded steps, wrapped to [-π, π) (rad)."""
        return wrap_angle(self.odometry_pose[:, 2] - self.true_pose[:, 2])

    def time_lost(self) -> float:
        """Simulated seconds the filter spent lost (the steps after which :attr:`lost` is set,
        each counted for its own duration; over every step, also in a thinned record)."""
        if self.stride > 1 and self.step_totals is not None:
            return self.step_totals.time_lost
        if not len(self.time):
            return 0.0
        durations = np.diff(self.time, prepend=0.0)
        return float(durations[self.lost].sum())

    def estimate_error(self) -> np.ndarray:
        """(N,) position error of the filter's estimate at the recorded steps (m)."""
        return np.linalg.norm(self.estimate[:, :2] - self.true_pose[:, :2], axis=1)
