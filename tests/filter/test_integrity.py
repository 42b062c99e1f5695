"""The estimate never lies. Slip-aware motion noise, lost detection far from the truth,
global re-localization (kidnapped robot, symmetric maps), the status the filter reports."""
from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.filter import (LOST, RELOCALIZING, STATUSES, TRACKING, ContactSlip, FilterConfig, GateConfig,
                              OdometryNoise, PoseEKF, RelocalizeConfig, TargetMap)
from tests.filter.conftest import LIMITS, MOUNT, NOISE, corridor_targets, drive, measure

CONFIG = FilterConfig(noise=NOISE, gate=GateConfig(view=LIMITS))
DT = 0.1


def irregular_targets() -> TargetMap:
    """Targets on the wall y = -4 at uneven spacing (no two stretches alike)."""
    xs = np.array([2.0, 5.0, 12.0, 14.5, 22.0, 27.0, 29.0, 36.5, 41.0, 47.5, 50.0, 58.0])
    return TargetMap(tuple(f"U{i:02d}" for i in range(len(xs))), np.stack([xs, np.full_like(xs, -4.0)], 1),
                     np.full(len(xs), math.pi / 2),
                     tuple("positive" if i % 3 else "negative" for i in range(len(xs))))


def run(ekf, rng, targets, poses, incs, frame_every=2, start=0, stop=None, on_step=None):
    """Feed odometry every step and a frame every ``frame_every`` steps (no latency); results."""
    results = []
    stop = len(incs) if stop is None else stop
    for k in range(start, stop):
        t = (k + 1) * DT
        ekf.add_odometry(t, *incs[k])
        if (k + 1) % frame_every == 0:
            results.append((k + 1, ekf.process_frame(t, [m for _, m in measure(poses[k + 1], targets, rng)])))
        if on_step is not None:
            on_step(k + 1)
    return results


# ----------------------------------------------------------------------------- 1. slip


def test_contact_slip_variance_grows_with_the_counted_wheel_motion():
    """In contact, each wheel's slip error has σ = k D (D its arc since the contact began):
    pushing straight for 10 m of counted motion gives var Δs = k² (D_L² + D_R²) / 4."""
    ekf = PoseEKF(np.zeros(3), np.diag([1e-6, 1e-6, 1e-8]), corridor_targets(), MOUNT, CONFIG)
    for k in range(100):
        ekf.add_odometry((k + 1) * DT, 0.1, 0.0, in_contact=True)
    P = ekf.covariance()
    k = CONFIG.contact_slip
    expected = math.sqrt(k ** 2 * (10.0 ** 2 + 10.0 ** 2) / 4.0)
    assert math.sqrt(P[0, 0]) == pytest.approx(expected, rel=0.02)
    assert ekf.position_sigma() > 5.0
    # the same motion out of contact: the wheel noise only (millimetres)
    free = PoseEKF(np.zeros(3), np.diag([1e-6, 1e-6, 1e-8]), corridor_targets(), MOUNT, CONFIG)
    for k in range(100):
        free.add_odometry((k + 1) * DT, 0.1, 0.0)
    assert free.position_sigma() < 0.1


def test_contact_slip_off_only_when_asked_and_restarts_after_contact():
    off = PoseEKF(np.zeros(3), np.eye(3) * 1e-8, corridor_targets(), MOUNT,
                  FilterConfig(noise=NOISE, gate=GateConfig(view=LIMITS), contact_slip=0.0))
    for k in range(50):
        off.add_odometry((k + 1) * DT, 0.1, 0.0, in_contact=True)
    assert off.position_sigma() < 0.1
    slip = ContactSlip(1.0, 0.6, release=1.0)
    first = slip.extra(0.1, 0.0, True, 0.1)
    second = slip.extra(0.1, 0.0, True, 0.2)
    assert second[0] > first[0]  # the bias grows with the motion counted in the contact
    assert slip.extra(0.1, 0.0, False, 0.3) is None and slip.slipping  # a flicker: still counting
    assert slip.extra(0.1, 0.0, True, 0.4)[0] > second[0]
    assert slip.extra(0.1, 0.0, False, 1.5) is None and not slip.slipping  # free for 1.1 s: over
    assert slip.extra(0.1, 0.0, True, 1.6) == pytest.approx(first)  # a new contact counts from zero
    with pytest.raises(ValueError, match="FilterConfig.contact_slip"):
        FilterConfig(contact_slip=-1.0)


def test_pushing_into_a_wall_makes_the_filter_lost_not_confident():
    """Wheels spinning against a wall (the encoders count 5 m, the vehicle stays put): the
    covariance covers the error, and the filter says it is lost."""
    targets = corridor_targets()
    ekf = PoseEKF(np.zeros(3), np.diag([1e-4, 1e-4, 1e-6]), targets, MOUNT, CONFIG)
    for k in range(50):
        ekf.add_odometry((k + 1) * DT, 0.1, 0.0, in_contact=True)
        if (k + 1) % 4 == 0:
            ekf.process_frame((k + 1) * DT, [])
    e = ekf.pose()[:2] - np.zeros(2)
    m2 = float(e @ np.linalg.solve(ekf.covariance()[:2, :2], e))
    assert m2 < 11.83 or ekf.status != TRACKING
    assert ekf.status in (LOST, RELOCALIZING)
    assert "sigma" in ekf.lost_reason


# ----------------------------------------------------------------------------- 2. lost detection


def test_lost_far_from_the_truth_when_real_detections_line_up(targets):
    """The estimate 30 m off: no target is predicted in view of it, so nothing is 'refused'
    the old way; the detections of one real target line up where the estimate places them."""
    rng = np.random.default_rng(3)
    poses, incs = drive(rng, 200)
    ekf = PoseEKF(np.array([30.0, 0.0, 0.0]), np.diag([1e-4, 1e-4, 1e-6]), targets, MOUNT, CONFIG)
    results = run(ekf, rng, targets, poses, incs, stop=60)
    assert ekf.lost
    assert "line up" in ekf.lost_reason
    first_seen = next(k for k, r in results if r.associations)
    lost_at = next(k for k, r in results if r.lost)
    assert (lost_at - first_seen) * DT <= 2.0  # frames every 0.2 s: four misfit frames, and one spare


def test_false_detections_scattered_do_not_line_up(targets):
    """Detections at random places every frame, no real target: the filter stays tracking."""
    rng = np.random.default_rng(5)
    ekf = PoseEKF(np.zeros(3), np.diag([1e-4, 1e-4, 1e-6]), targets, MOUNT, CONFIG)
    from localizer.filter import Measurement

    for k in range(300):
        t = (k + 1) * DT
        ekf.add_odometry(t, 0.0, 0.0)
        if k % 2:
            ms = []
            for _ in range(2):
                d, b = rng.uniform(1.0, 8.0), rng.uniform(-0.25, 0.25)
                ms.append(Measurement([d, b, b + rng.uniform(-1, 1)], np.diag([1e-4, 1e-8, 1e-4]),
                                      str(rng.choice(["positive", "negative"]))))
            ekf.process_frame(t, ms)
    assert ekf.status == TRACKING


def test_estimate_outside_free_space_is_lost(targets):
    free = lambda x, y: not (9.0 <= x <= 11.0)  # noqa: E731  (an obstacle across the corridor)
    ekf = PoseEKF(np.array([8.5, 0.0, 0.0]), np.diag([1e-4, 1e-4, 1e-6]), targets, MOUNT, CONFIG, free_space=free)
    for k in range(10):
        ekf.add_odometry((k + 1) * DT, 0.2, 0.0)
        ekf.process_frame((k + 1) * DT, [])
    assert ekf.status == LOST
    assert "free space" in ekf.lost_reason


def test_persistently_high_nis_is_lost(targets):
    """Observations off by 1.9σ in each component, signs at random (each inside the gate, NIS
    about 11 where χ²(3) averages 3)."""
    rng = np.random.default_rng(8)
    poses, incs = drive(rng, 400)
    ekf = PoseEKF(np.zeros(3), np.diag([1e-4, 1e-4, 1e-6]), targets, MOUNT, CONFIG)
    for k in range(400):
        t = (k + 1) * DT
        ekf.add_odometry(t, *incs[k])
        if (k + 1) % 2 == 0:
            ms = []
            for _, m in measure(poses[k + 1], targets, rng):
                sd = np.sqrt(np.diag(m.R) + np.array([0.002, 3e-4, 2e-3]) ** 2)
                ms.append(type(m)(m.z + 1.9 * rng.choice([-1.0, 1.0], 3) * sd, m.R, m.polarity))
            ekf.process_frame(t, ms)
        if ekf.lost:
            break
    assert ekf.lost and "NIS" in ekf.lost_reason


# ----------------------------------------------------------------------------- 3. re-localization


def test_kidnapped_vehicle_relocalizes_from_nothing():
    """Tracking, then carried 13 m without telling the filter: lost, then found again from
    the targets, within 10 cm, with no wrong confirmation on the way."""
    targets = irregular_targets()
    rng = np.random.default_rng(11)
    poses, incs = drive(rng, 500)
    shift = np.array([13.0, 0.0, 0.0])
    kidnapped = poses.copy()
    kidnapped[150:] += shift  # the truth jumps at step 150; the odometry does not
    ekf = PoseEKF(np.zeros(3), np.diag([1e-4, 1e-4, 1e-6]), targets, MOUNT, CONFIG)
    wrong = []

    def check(k):
        if ekf.relocalizations > len(wrong_or_right):
            wrong_or_right.append(np.hypot(*(ekf.x[:2] - kidnapped[k][:2])))

    wrong_or_right: list[float] = []
    results = run(ekf, rng, targets, kidnapped, incs, on_step=check)
    assert ekf.lost_events >= 1 and ekf.relocalizations >= 1
    wrong = [e for e in wrong_or_right if e > 0.5]
    assert not wrong
    assert ekf.status == TRACKING
    assert np.hypot(*(ekf.pose()[:2] - kidnapped[-1][:2])) < 0.10
    lost_at = next(k for k, r in results if k > 150 and r.lost)
    assert (lost_at - 150) * DT < 5.0


def test_unknown_start_relocalizes_and_status_codes():
    targets = irregular_targets()
    rng = np.random.default_rng(12)
    poses, incs = drive(rng, 300)
    ekf = PoseEKF(np.array([40.0, 1.0, 2.0]), np.eye(3), targets, MOUNT, CONFIG)
    ekf.declare_lost("start pose unknown")
    assert ekf.status == LOST and ekf.lost_reason == "start pose unknown"
    seen = []
    run(ekf, rng, targets, poses, incs, on_step=lambda k: seen.append(ekf.status))
    assert RELOCALIZING in seen
    assert ekf.status == TRACKING and ekf.lost_reason is None
    assert np.hypot(*(ekf.pose()[:2] - poses[-1][:2])) < 0.10
    assert STATUSES == (TRACKING, LOST, RELOCALIZING)
    assert ekf.since_fix(30.0) < 1.0


def test_symmetric_map_is_never_confirmed_while_ambiguous():
    """Targets every 6 m with alternating polarity: every 12 m the map repeats. Driving along
    the middle of it, hypotheses 12 m apart explain the data equally well: the filter stays
    relocalizing rather than pick one."""
    targets = corridor_targets()  # x = 2, 8, ..., 56
    rng = np.random.default_rng(13)
    poses, incs = drive(rng, 150)  # x 0 .. 18 m: the targets at 2 .. 20 (the left end is visible!)
    start = np.array([20.0, 0.0, 0.0])
    poses = poses + start  # drive 20 .. 38 m: targets 20 .. 44 seen, shifts of 12 m look alike
    ekf = PoseEKF(np.array([0.0, 0.0, 0.0]), np.eye(3), targets, MOUNT, CONFIG)
    ekf.declare_lost("start pose unknown")
    run(ekf, rng, targets, poses, incs)
    assert ekf.relocalizations == 0
    assert ekf.status == RELOCALIZING
    offsets = sorted(round(float(h.x[0] - poses[-1][0])) for h in ekf.relocalizer.hypotheses
                     if len(h.matched) >= 2)
    assert 0 in offsets and any(abs(o) == 12 for o in offsets)


def test_hypotheses_are_bounded():
    targets = corridor_targets()
    rng = np.random.default_rng(14)
    poses, incs = drive(rng, 100)
    cfg = FilterConfig(noise=NOISE, gate=GateConfig(view=LIMITS), relocalize=RelocalizeConfig(max_hypotheses=5))
    ekf = PoseEKF(np.zeros(3), np.eye(3), targets, MOUNT, cfg)
    ekf.declare_lost("start pose unknown")
    run(ekf, rng, targets, poses + np.array([20.0, 0.0, 0.0]), incs,
        on_step=lambda k: None)
    assert len(ekf.relocalizer.hypotheses) <= 5
