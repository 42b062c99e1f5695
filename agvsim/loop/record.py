r"""A run's record in bounded memory, whatever its length: :class:`MissionRecorder`.

A short run is recorded in full: every control step, frame and station arrival, and its
figures are computed from that record as they always were. A long one is thinned: the
per-step rows are gathered :data:`CHUNK` steps at a time; each full chunk is folded into the
run's :class:`~agvsim.loop.log.StepTotals` (sums of squared errors, maxima, NEES counts, time
lost and a histogram of the position error, over every step) and into the record, which keeps
every step until it holds :attr:`RecordLimits.steps` rows, then every second step, every
fourth, ... (the log's ``stride``), and always the last one. Frames and arrivals likewise
(``frame_stride``, ``arrival_stride``; :class:`~agvsim.loop.log.EventTotals` counts every one).
The default limits hold about 1.8 km of a drive at the default rates in full; beyond them a
log holds about 3 MB of per-step arrays and 8,192 frames (about 7 MB with geometric
observations) whatever the distance.

The errors and NEES of a pose record are defined here, once (:func:`pose_errors`,
:func:`nees`), for the totals and for :mod:`agvsim.analysis.evaluate`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from agvsim.loop.log import Arrival, EventTotals, FrameRecord, MissionLog, StepTotals
from localizer.numeric import check_number, wrap_angle

__all__ = ["CHUNK", "HISTOGRAM_BINS", "MissionRecorder", "NEES_BOUNDS", "NIS_95", "RecordLimits",
           "histogram_bins", "histogram_percentile", "nees", "pose_errors", "step_totals"]

#: NEES of a consistent filter ~ χ²(3): its two-sided 95 % interval
NEES_BOUNDS = (float(chi2.ppf(0.025, 3)), float(chi2.ppf(0.975, 3)))
#: NIS of a consistent filter ~ χ²(3): its 95th percentile
NIS_95 = float(chi2.ppf(0.95, 3))
#: control steps gathered before they are folded into the totals and the record
CHUNK = 2048
#: the position-error histogram: bins 2^(1/256) wide (0.27 %) from 2^-20 m (1 µm) to 2^15 m;
#: smaller errors count in the first bin, larger ones (and NaN) in the last
HISTOGRAM_PER_OCTAVE = 256
HISTOGRAM_RANGE = (-20, 15)  # powers of two (m)
HISTOGRAM_BINS = (HISTOGRAM_RANGE[1] - HISTOGRAM_RANGE[0]) * HISTOGRAM_PER_OCTAVE


@dataclass(frozen=True)
class RecordLimits:
    """How much of a run its log keeps in full; beyond these the record is thinned (module
    docstring) and the totals still count everything.

    Attributes:
        steps: control steps (rows of the per-step arrays), at least 2.
        frames: camera frames, at least 2.
        arrivals: station arrivals, at least 2.
    """

    steps: int = 2 ** 14
    frames: int = 2 ** 13
    arrivals: int = 2 ** 10

    def __post_init__(self) -> None:
        for name in ("steps", "frames", "arrivals"):
            check_number(f"RecordLimits.{name}", getattr(self, name), low=2, integer=True)


def pose_errors(estimate: np.ndarray, true_pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 2) position error (m) and (N,) heading error wrapped to [-π, π) (rad) of the (N, 3)
    poses ``estimate`` against ``true_pose``."""
    e = estimate[:, :2] - true_pose[:, :2]
    dh = wrap_angle(estimate[:, 2] - true_pose[:, 2])
    return e, dh


def nees(estimate: np.ndarray, true_pose: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """(N,) NEES ε P⁻¹ ε with ε = (x̂ - x, ŷ - y, wrap(θ̂ - θ)) and P the (N, 3, 3) covariance."""
    e, dh = pose_errors(estimate, true_pose)
    eps = np.concatenate([e, dh[:, None]], axis=1)
    return np.einsum("ni,nij,nj->n", eps, np.linalg.inv(covariance), eps)


def histogram_bins(values) -> np.ndarray:
    """(N,) int64 bin of each error of ``values`` (m) in the position-error histogram."""
    low = HISTOGRAM_RANGE[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.floor((np.log2(np.asarray(values, dtype=float)) - low) * HISTOGRAM_PER_OCTAVE)
    k = np.where(np.isnan(k), HISTOGRAM_BINS - 1, k)
    return np.clip(k, 0, HISTOGRAM_BINS - 1).astype(np.int64)


def histogram_percentile(counts: np.ndarray, q: float, high: float = math.inf) -> float:
    """The ``q``-th percentile (0-100) of the errors counted in ``counts``: the centre of the
    bin holding the value of that rank (within 0.14 % of it), at most ``high`` (the maximum; in
    the last bin, where errors beyond the range count, ``high`` itself if finite)."""
    n = int(np.sum(counts))
    if n == 0:
        return math.nan
    b = int(np.searchsorted(np.cumsum(counts), q / 100.0 * (n - 1), side="right"))
    if b >= HISTOGRAM_BINS - 1 and math.isfinite(high):
        return float(high)
    centre = 2.0 ** (HISTOGRAM_RANGE[0] + (b + 0.5) / HISTOGRAM_PER_OCTAVE)
    return float(min(centre, high))


class _StepSums:
    """The running sums behind :class:`~agvsim.loop.log.StepTotals`."""

    def __init__(self):
        self.steps = self.lost_steps = self.nees_in = self.nees_below = 0
        self.pos_sq = self.dh_sq = self.nees_sum = self.time_lost = 0.0
        self.pos_max = self.dh_max = self.odo_max = 0.0
        self.hist = np.zeros(HISTOGRAM_BINS, dtype=np.int64)
        self.t_prev = 0.0

    def add(self, time, true_pose, odometry_pose, estimate, covariance, lost) -> None:
        if not len(time):
            return
        e, dh = pose_errors(estimate, true_pose)
        pos = np.hypot(e[:, 0], e[:, 1])
        odo = np.hypot(*(odometry_pose[:, :2] - true_pose[:, :2]).T)
        v = nees(estimate, true_pose, covariance)
        lo, hi = NEES_BOUNDS
        self.steps += len(time)
        self.pos_sq += float(np.sum(pos ** 2))
        self.dh_sq += float(np.sum(dh ** 2))
        self.pos_max, self.dh_max, self.odo_max = (float(np.max([a, b.max()])) for a, b in
                                                   ((self.pos_max, pos), (self.dh_max, np.abs(dh)),
                                                    (self.odo_max, odo)))
        self.hist += np.bincount(histogram_bins(pos), minlength=HISTOGRAM_BINS)
        self.nees_sum += float(np.sum(v))
        self.nees_in += int(np.count_nonzero((v >= lo) & (v <= hi)))
        self.nees_below += int(np.count_nonzero(v <= hi))
        self.lost_steps += int(np.count_nonzero(lost))
        self.time_lost += float(np.diff(time, prepend=self.t_prev)[lost].sum())
        self.t_prev = float(time[-1])

    def totals(self) -> StepTotals:
        return StepTotals(self.steps, self.pos_sq, self.pos_max, self.hist.copy(), self.dh_sq, self.dh_max,
                          self.odo_max, self.nees_sum, self.nees_in, self.nees_below, self.lost_steps,
                          self.time_lost)


def step_totals(log) -> StepTotals:
    """The :class:`~agvsim.loop.log.StepTotals` of a log recorded in full (arrays ``time``,
    ``true_pose``, ``odometry_pose``, ``estimate``, ``covariance``, ``lost``)."""
    sums = _StepSums()
    sums.add(np.asarray(log.time, dtype=float), log.true_pose, log.odometry_pose, log.estimate,
             log.covariance, np.asarray(log.lost, dtype=bool))
    return sums.totals()


class _Thinned:
    """A list that keeps the items at every ``stride``-th index, the stride doubled whenever
    more than ``limit`` are kept."""

    def __init__(self, limit: int):
        self.limit, self.stride, self.count = limit, 1, 0
        self.items: list = []
        self.index: list[int] = []

    def add(self, item) -> None:
        i, self.count = self.count, self.count + 1
        if i % self.stride:
            return
        self.items.append(item)
        self.index.append(i)
        while len(self.items) > self.limit:
            self.stride *= 2
            kept = [k for k, j in enumerate(self.index) if j % self.stride == 0]
            self.items = [self.items[k] for k in kept]
            self.index = [self.index[k] for k in kept]


#: the per-step arrays of a MissionLog: (name, dtype, shape of one row)
_STEP_FIELDS = (("time", float, ()), ("distance", float, ()), ("true_pose", float, (3,)),
                ("odometry_pose", float, (3,)), ("estimate", float, (3,)), ("covariance", float, (3, 3)),
                ("command", float, (2,)), ("lost", bool, ()), ("step_ms", float, ()))


class MissionRecorder:
    """Gathers a run's steps, frames and arrivals into a :class:`~agvsim.loop.log.MissionLog`
    held within ``limits`` (module docstring)."""

    def __init__(self, limits: RecordLimits = RecordLimits()):
        self.limits = limits
        self.stride = 1
        self._rows: list[list] = [[] for _ in _STEP_FIELDS]  # the chunk being gathered
        self._kept: dict[str, np.ndarray] | None = None  # the record so far
        self._kept_index = np.zeros(0, dtype=np.int64)
        self._last: dict[str, np.ndarray] | None = None  # the last step folded
        self._n = 0  # steps folded
        self._sums = _StepSums()
        self._frames = _Thinned(limits.frames)
        self._arrivals = _Thinned(limits.arrivals)
        self._ev = dict(frames=0, with_observation=0, with_accepted=0, observed_with_accepted=0, observations=0,
                        accepted=0, wrong=0, false_accepted=0, nis_count=0, nis_sum=0.0, nis_below_95=0,
                        arrivals=0, arrival_error_sum=0.0, arrival_error_max=0.0, arrival_passing_sum=0.0)
        self._statuses: dict[str, int] = {}

    def step(self, time, distance, true_pose, odometry_pose, estimate, covariance, command, lost, step_ms) -> None:
        """One control step: times (s), distance (m), the three poses, the estimate's
        covariance, the (v, ω) command, lost after the step, its wall time (ms)."""
        for rows, v in zip(self._rows, (time, distance, true_pose, odometry_pose, estimate, covariance, command,
                                        lost, step_ms)):
            rows.append(v)
        if len(self._rows[0]) >= CHUNK:
            self._fold()

    def frame(self, record: FrameRecord) -> None:
        """One fused frame."""
        ev, obs = self._ev, record.observations
        ev["frames"] += 1
        ev["with_observation"] += bool(obs)
        ev["with_accepted"] += record.accepted > 0
        ev["observed_with_accepted"] += bool(obs) and record.accepted > 0
        ev["observations"] += len(obs)
        for o in obs:
            self._statuses[o.status] = self._statuses.get(o.status, 0) + 1
            if o.status == "accepted":
                ev["accepted"] += 1
                ev["wrong"] += o.truth_id is not None and o.truth_id != o.target_id
                ev["false_accepted"] += o.truth_id is None
        nis = np.asarray(record.nis, dtype=float).ravel().tolist()
        ev["nis_count"] += len(nis)
        ev["nis_sum"] += math.fsum(nis)
        ev["nis_below_95"] += sum(v <= NIS_95 for v in nis)
        self._frames.add(record)

    def arrival(self, arrival: Arrival) -> None:
        """The follower passing a station."""
        ev = self._ev
        ev["arrivals"] += 1
        ev["arrival_error_sum"] += arrival[3]
        ev["arrival_error_max"] = max(ev["arrival_error_max"], arrival[3])
        ev["arrival_passing_sum"] += arrival[2]
        self._arrivals.add(arrival)

    def _fold(self) -> None:
        """The gathered chunk into the totals and the record (thinned to the limit)."""
        m = len(self._rows[0])
        if not m:
            return
        chunk = {}
        for (name, dtype, shape), rows in zip(_STEP_FIELDS, self._rows):
            chunk[name] = np.asarray(rows, dtype=dtype).reshape((m, *shape))
            rows.clear()
        self._sums.add(chunk["time"], chunk["true_pose"], chunk["odometry_pose"], chunk["estimate"],
                       chunk["covariance"], chunk["lost"])
        index = np.arange(self._n, self._n + m, dtype=np.int64)
        self._n += m
        self._last = {k: v[-1:].copy() for k, v in chunk.items()}
        if self._kept is None:
            self._kept, self._kept_index = chunk, index
        else:
            self._kept = {k: np.concatenate([self._kept[k], v]) for k, v in chunk.items()}
            self._kept_index = np.concatenate([self._kept_index, index])
        keep = self._kept_index % self.stride == 0
        while np.count_nonzero(keep) > self.limits.steps:
            self.stride *= 2
            keep = self._kept_index % self.stride == 0
        if not keep.all():
            self._kept = {k: v[keep] for k, v in self._kept.items()}
            self._kept_index = self._kept_index[keep]

    def finish(self, **fields) -> MissionLog:
        """The log: the record (with the last step whatever the stride), the totals, and the
        other :class:`~agvsim.loop.log.MissionLog` ``fields`` (completed, counters, timings ...)."""
        self._fold()
        if self._kept is None:
            arrays = {name: np.zeros((0, *shape), dtype=dtype) for name, dtype, shape in _STEP_FIELDS}
        else:
            arrays = self._kept
            if self._kept_index[-1] != self._n - 1:
                arrays = {k: np.concatenate([v, self._last[k]]) for k, v in arrays.items()}
        events = EventTotals(statuses=dict(self._statuses), **self._ev)
        return MissionLog(**arrays, frames=tuple(self._frames.items), arrivals=tuple(self._arrivals.items),
                          stride=self.stride, frame_stride=self._frames.stride, arrival_stride=self._arrivals.stride,
                          step_totals=self._sums.totals(), event_totals=events, **fields)
