"""A run's log holds a bounded record whatever the distance (thinned past ``MissionConfig.record``)
and its figures stay those of every step and frame; a run within the limits is recorded in full."""
from __future__ import annotations

import math

import numpy as np
import pytest

from agvsim.analysis.evaluate import pooled, run_metrics
from agvsim.loop.log import StepTotals
from agvsim.loop.mission import MissionConfig, run_mission
from agvsim.loop.record import HISTOGRAM_BINS, RecordLimits, histogram_bins, histogram_percentile, step_totals
from agvsim.sensors import GeometricNoise, GeometricSource, VisionConfig
from agvsim.world import load_map

LIMITS = RecordLimits(steps=64, frames=32, arrivals=2)
#: the figures of a thinned record that come from a histogram (0.27 % bins)
FROM_HISTOGRAM = {"position_p95_m"}
#: wall-clock figures, from the frames recorded
TIMING = {"observe_ms_median", "filter_ms_median", "wall_time_s"}


def _drive(distance: float, limits: RecordLimits = RecordLimits()):
    floor = load_map("plant_floor")
    vision = VisionConfig().for_map(floor)
    source = GeometricSource(floor, vision, noise=GeometricNoise(false_rate=0.5))  # every counter moves
    return run_mission(floor, source, np.random.default_rng(3),
                       MissionConfig(vision_config=vision, distance=distance, record=limits))


@pytest.fixture(scope="module")
def drives():
    """The same 100 m drive recorded in full and thinned to :data:`LIMITS`."""
    return _drive(100.0), _drive(100.0, LIMITS)


def _nbytes(log) -> int:
    return sum(getattr(log, k).nbytes for k in ("time", "distance", "true_pose", "odometry_pose", "estimate",
                                                 "covariance", "command", "lost", "step_ms"))


def test_the_record_stays_within_its_limits(drives):
    full, thin = drives
    n = len(full.time)
    assert full.stride == full.frame_stride == full.arrival_stride == 1  # (within the default limits)
    assert n > 10 * LIMITS.steps and len(full.frames) > 10 * LIMITS.frames and len(full.arrivals) > 2 * LIMITS.arrivals
    assert LIMITS.steps // 2 <= len(thin.time) <= LIMITS.steps + 1  # (+ the last step)
    assert LIMITS.frames // 2 <= len(thin.frames) <= LIMITS.frames
    assert LIMITS.arrivals // 2 <= len(thin.arrivals) <= LIMITS.arrivals
    assert _nbytes(thin) <= (LIMITS.steps + 1) * _nbytes(full) / n
    # every stride-th step, exactly as recorded in full, and the last one
    kept = np.r_[np.arange(0, n, thin.stride), n - 1] if (n - 1) % thin.stride else np.arange(0, n, thin.stride)
    for k in ("time", "true_pose", "estimate", "covariance", "lost"):
        assert np.array_equal(getattr(thin, k), getattr(full, k)[kept]), k
    assert [f.step for f in thin.frames] == [f.step for f in full.frames[::thin.frame_stride]]
    assert thin.arrivals == full.arrivals[::thin.arrival_stride]


def test_twice_the_distance_keeps_no_more():
    a, b = _drive(40.0, LIMITS), _drive(80.0, LIMITS)
    assert b.step_totals.steps > 1.8 * a.step_totals.steps
    assert _nbytes(b) <= (LIMITS.steps + 1) * _nbytes(a) / len(a.time) and len(b.frames) <= LIMITS.frames


def test_a_thinned_record_gives_the_figures_of_every_step(drives):
    full, thin = drives
    exact, thinned = run_metrics(full), run_metrics(thin)
    assert exact["steps"] > 10 * LIMITS.steps and exact["false_detections_accepted"] + exact["observations"] > 0
    assert len(exact["association_statuses"]) > 1  # (false detections make other statuses)
    assert exact.keys() == thinned.keys() and list(exact) == list(thinned)
    for k, v in exact.items():
        if k in TIMING:
            continue
        if k in FROM_HISTOGRAM:
            assert thinned[k] == pytest.approx(v, rel=1.4e-3), k
        elif isinstance(v, float) and math.isfinite(v):
            assert thinned[k] == pytest.approx(v, rel=1e-12, abs=1e-15), k  # the same sums, in another order
        else:
            assert thinned[k] == v, k  # counts, maxima, final values
    assert thin.time_lost() == full.time_lost()


def test_pooled_figures_from_totals_match_the_arrays(drives):
    full, thin = drives
    exact, mixed = pooled([full, full]), pooled([thin, full])
    assert exact.keys() == mixed.keys()
    for k, v in exact.items():
        assert mixed[k] == pytest.approx(v, rel=1.4e-3 if k in FROM_HISTOGRAM else 1e-12), k
    saved = StepTotals.from_arrays(thin.step_totals.to_arrays())  # as a saved seed reads back
    assert all(np.array_equal(getattr(saved, k), getattr(thin.step_totals, k)) for k in StepTotals.__dataclass_fields__)
    again = step_totals(full)  # the totals of a full record, from its arrays
    assert again.steps == thin.step_totals.steps and again.position_max == thin.step_totals.position_max
    assert np.array_equal(again.position_histogram, thin.step_totals.position_histogram)


def test_the_histogram_percentile_is_within_its_bin():
    rng = np.random.default_rng(0)
    errors = np.concatenate([rng.lognormal(-4.0, 1.0, 20000), [0.0, 1e-9, 1e5]])
    counts = np.bincount(histogram_bins(errors), minlength=HISTOGRAM_BINS)
    assert counts.sum() == len(errors) and counts[0] == 2 and counts[-1] == 1
    for q in (5, 50, 95, 99):
        assert histogram_percentile(counts, q) == pytest.approx(np.percentile(errors, q), rel=1.4e-3), q
    assert histogram_percentile(counts, 100, high=1e5) == 1e5 and histogram_percentile(counts, 0) < 2e-6 and math.isnan(histogram_percentile(counts * 0, 95))


def test_record_limits_are_checked():
    with pytest.raises(ValueError, match=r"RecordLimits.steps must be a whole number >= 2"):
        RecordLimits(steps=1)
