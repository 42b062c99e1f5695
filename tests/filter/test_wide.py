"""The wide belief: past the one-Gaussian limits the filter keeps tracking with an honest mixture,
and the first targets seen narrow it again; detections the map explains are no misfits."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

from localizer.filter import FilterConfig, GateConfig, Measurement, OdometryNoise, PoseEKF, arc_motion, compose
from localizer.filter.misfits import explained_by_map, place
from localizer.filter.wide import WideBelief, WideConfig, split
from tests.filter.conftest import LIMITS, MOUNT, corridor_targets, measure

NOISE = OdometryNoise(wheel_noise=0.02, track_width=0.6)
#: one Gaussian is given up past 5° of heading σ, so four turns in place (about 7°) make it wide
WIDE = WideConfig(component_heading_sigma=math.radians(1.5), spacing=math.radians(2.0),
                  split_heading_sigma=math.radians(3.0), narrow_heading_sigma=math.radians(4.0))
CONFIG = FilterConfig(noise=NOISE, gate=GateConfig(view=LIMITS), lost_heading_sigma=math.radians(5.0), wide=WIDE)
SPIN = 150  # steps turning in place, camera off
DT = 0.1


def spin_then_drive(seed: int, config: FilterConfig, steps: int = 300):
    """Four turns in place with no target in view, then east along the corridor with the camera on.
    Returns per step ``(status, hypotheses, error (3,), covariance (3, 3))`` and the filter."""
    rng = np.random.default_rng(seed)
    targets = corridor_targets()
    x = np.zeros(3)
    ekf = PoseEKF(x, np.diag([0.01, 0.01, 0.01]) ** 2, targets, MOUNT, config)
    rows = []
    for k in range(steps):
        t = (k + 1) * DT
        ds, dth = (0.0, 8.0 * math.pi / SPIN) if k < SPIN else (0.1, 0.0)
        x = compose(x, arc_motion(ds, dth))
        vs, c, vt = NOISE.covariance(ds, dth)
        e = rng.multivariate_normal(np.zeros(2), [[vs, c], [c, vt]])
        ekf.add_odometry(t, ds + e[0], dth + e[1])
        if k >= SPIN and k % 2 == 0:
            ekf.process_frame(t, [m for _, m in measure(x, targets, rng)])
        else:
            ekf.flush(t)
        err = ekf.pose() - x
        err[2] = (err[2] + math.pi) % (2 * math.pi) - math.pi
        rows.append((ekf.status, ekf.hypotheses, err, ekf.covariance()))
    return rows, ekf


@pytest.mark.parametrize("seed", range(4))
def test_a_long_unseen_turn_stays_tracking_with_an_honest_wide_belief(seed):
    rows, ekf = spin_then_drive(seed, CONFIG)
    assert ekf.wide_events >= 1
    spin = rows[:SPIN]
    assert all(status == "tracking" for status, *_ in rows[:SPIN + 1])
    assert max(h for _, h, _, _ in spin) > 1  # a mixture, not one Gaussian
    for status, h, err, P in spin[-10:]:  # the belief is as wide as the truth needs
        assert math.degrees(math.sqrt(P[2, 2])) > 5.0
        assert float(err @ np.linalg.solve(P, err)) <= chi2.ppf(0.999, 3)


@pytest.mark.parametrize("seed", range(4))
def test_the_first_targets_seen_narrow_the_wide_belief(seed):
    rows, _ = spin_then_drive(seed, CONFIG, steps=SPIN + 50)
    after = rows[SPIN + 20:]  # ten frames of driving past the first target
    assert all(status == "tracking" for status, *_ in after)
    assert all(h == 1 for _, h, _, _ in after)  # one Gaussian again
    assert max(float(np.hypot(*err[:2])) for _, _, err, _ in after) < 0.1


def test_without_a_wide_belief_the_same_turn_is_lost():
    rows, ekf = spin_then_drive(0, replace(CONFIG, wide=None), steps=SPIN)
    assert ekf.lost_events == 1 and "heading sigma" in ekf.lost_reason
    assert rows[-1][0] != "tracking"


def test_split_keeps_the_gaussians_moments_within_its_component_budget():
    x = np.array([1.0, -2.0, 0.3])
    P = np.array([[0.04, 0.01, 0.02], [0.01, 0.09, -0.03], [0.02, -0.03, math.radians(25.0) ** 2]])
    means, covs, w = split(x, P, WideConfig())
    assert 3 <= len(w) <= WideConfig().max_components and w.sum() == pytest.approx(1.0)
    belief = WideBelief(x, P, corridor_targets(), MOUNT, GateConfig(view=LIMITS), WideConfig())
    assert len(belief) == len(w)
    mean, cov = belief.moments()
    np.testing.assert_allclose(mean, x, atol=1e-9)
    np.testing.assert_allclose(cov, P, rtol=0.02, atol=1e-6)
    few = split(x, P, WideConfig(), most=5)[2]
    assert len(few) <= 5


def test_a_detection_the_map_explains_is_no_misfit():
    targets = corridor_targets()
    x = np.array([-1.6, 0.0, 0.0])  # the target at (2, -4) ahead of the camera
    cam = MOUNT.camera_pose(x)
    (j, m), *_ = measure(x, targets, np.random.default_rng(1), floor=(1e-4, 1e-5, 1e-4))
    px, py, _ = place(m, cam)
    assert math.hypot(px - targets.positions[j][0], py - targets.positions[j][1]) < 0.05
    assert explained_by_map(m, cam, targets, 0.3, math.radians(10.0))
    moved = Measurement(m.z + np.array([1.0, 0.0, 0.0]), m.R, m.polarity)  # 1 m further: nothing there
    assert not explained_by_map(moved, cam, targets, 0.3, math.radians(10.0))
    other = "negative" if m.polarity == "positive" else "positive"
    assert not explained_by_map(Measurement(m.z, m.R, other), cam, targets, 0.3, math.radians(10.0))


def test_a_loose_detection_is_explained_within_its_own_uncertainty():
    """A far, steep target's detection: its alpha known to 30 deg, its range to 0.5 m. Placed 0.4 m
    from the map target and facing 20 deg off, it is that target within 3 sigma (a real target the
    filter's view limits leave out is no misfit); the same offsets measured tightly are not."""
    targets = corridor_targets()
    x = np.array([-1.6, 0.0, 0.0])
    cam = MOUNT.camera_pose(x)
    (j, m), *_ = measure(x, targets, np.random.default_rng(1), floor=(1e-4, 1e-5, 1e-4))
    off = m.z + np.array([0.4, 0.0, math.radians(20.0)])
    loose = Measurement(off, np.diag([0.5, 2e-4, math.radians(30.0)]) ** 2, m.polarity)
    tight = Measurement(off, m.R, m.polarity)
    assert explained_by_map(loose, cam, targets, 0.3, math.radians(10.0))
    assert not explained_by_map(tight, cam, targets, 0.3, math.radians(10.0))
