"""The pose EKF on synthetic data: convergence, consistency, false detections, latency, re-localization."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from localizer.filter import (ACCEPTED, AMBIGUOUS, FilterConfig, GateConfig, Measurement, PoseEKF, TargetMap,
                              associate, predict_measurement)
from tests.filter.conftest import LIMITS, MOUNT, NOISE, drive, measure

CONFIG = FilterConfig(noise=NOISE, gate=GateConfig(view=LIMITS))
DT = 0.1


def run_filter(rng, targets, x0_est, P0, steps=400, frame_every=2, config=CONFIG, false_per_frame=0,
               latency_steps=0):
    """Drive past the targets; returns (true poses, estimates, covariances, results)."""
    poses, incs = drive(rng, steps)
    ekf = PoseEKF(x0_est, P0, targets, MOUNT, config)
    est, cov, results = [], [], []
    in_flight = []
    for k in range(steps):
        t = (k + 1) * DT
        ekf.add_odometry(t, *incs[k])
        while in_flight and in_flight[0][0] <= k:
            _, tc, ms = in_flight.pop(0)
            results.append(ekf.process_frame(tc, ms))
        if (k + 1) % frame_every == 0:
            ms = [m for _, m in measure(poses[k + 1], targets, rng)]
            for _ in range(false_per_frame):
                d = rng.uniform(1, 8)
                b = rng.uniform(-0.25, 0.25)
                ms.append(Measurement([d, b, b + rng.uniform(-1, 1)], np.diag([1e-4, 1e-8, 1e-4]),
                                      rng.choice(["positive", "negative"])))
            in_flight.append((k + latency_steps, t, ms))
            if latency_steps == 0:
                _, tc, ms = in_flight.pop(0)
                results.append(ekf.process_frame(tc, ms))
        est.append(ekf.pose())
        cov.append(ekf.covariance())
    return poses[1:], np.array(est), np.array(cov), results


def nees(poses, est, cov):
    e = est - poses
    e[:, 2] = (e[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return np.einsum("ni,nij,nj->n", e, np.linalg.inv(cov), e)


def test_converges_from_wrong_initial_pose(targets):
    rng = np.random.default_rng(3)
    x0 = np.array([0.3, -0.25, math.radians(4.0)])  # truth starts at (0, 0, 0)
    P0 = np.diag([0.3, 0.3, math.radians(5.0)]) ** 2
    poses, est, cov, results = run_filter(rng, targets, x0, P0)
    err = np.hypot(*(est[:, :2] - poses[:, :2]).T)
    assert err[0] > 0.25
    assert err[-100:].max() < 0.03
    assert sum(r.accepted for r in results) > 20
    assert all(not r.lost for r in results)


def test_nees_and_nis_consistent_on_synthetic_measurements(targets):
    """Monte Carlo: the time-averaged NEES and the NIS follow χ²(3)."""
    all_nees, all_nis = [], []
    for seed in range(12):
        rng = np.random.default_rng(100 + seed)
        poses, est, cov, results = run_filter(rng, targets, np.zeros(3), np.diag([0.01, 0.01, 0.002]) ** 2,
                                              steps=300)
        all_nees.append(nees(poses, est, cov))
        all_nis.extend(float(v) for r in results for v in r.nis)
    n = np.concatenate(all_nees)
    nis = np.array(all_nis)
    assert 2.4 < n.mean() < 3.6, n.mean()
    lo, hi = chi2.ppf([0.025, 0.975], 3)
    assert np.mean((n >= lo) & (n <= hi)) > 0.88
    assert 2.6 < nis.mean() < 3.4, nis.mean()
    assert np.mean(nis <= chi2.ppf(0.95, 3)) > 0.92


def test_false_detections_rejected_without_harm(targets):
    clean = run_filter(np.random.default_rng(7), targets, np.zeros(3), np.diag([0.01, 0.01, 0.002]) ** 2)
    dirty = run_filter(np.random.default_rng(7), targets, np.zeros(3), np.diag([0.01, 0.01, 0.002]) ** 2,
                       false_per_frame=2)
    poses, est, _, results = dirty
    err_clean = np.hypot(*(clean[1][:, :2] - clean[0][:, :2]).T)
    err = np.hypot(*(est[:, :2] - poses[:, :2]).T)
    rejected = sum(1 for r in results for a in r.associations if a.status != ACCEPTED)
    assert rejected >= 0.9 * 2 * len(results)  # nearly all false detections refused
    assert err.max() < 0.05
    assert np.sqrt(np.mean(err ** 2)) < 1.5 * np.sqrt(np.mean(err_clean ** 2)) + 0.003
    assert not any(r.lost for r in results)


def test_ambiguous_match_is_refused():
    # two identical targets 0.2 m apart: an observation between them is ambiguous
    tm = TargetMap(("A", "B"), [[5.0, 0.1], [5.0, -0.1]], [math.pi, math.pi], ("positive", "positive"))
    x = np.zeros(3)
    from localizer.filter import CameraMount, ViewLimits

    mount = CameraMount(forward=0.0)
    z = predict_measurement(x, [5.0, 0.0], math.pi, mount)
    m = Measurement(z, np.diag([1e-4, 1e-6, 1e-4]), "positive")
    a = associate(x, np.diag([0.3, 0.3, 0.01]) ** 2, [m], tm, mount, GateConfig(view=ViewLimits()))
    assert a[0].status == AMBIGUOUS
    # a confident prior picks the right one
    zA = predict_measurement(x, [5.0, 0.1], math.pi, mount)
    a = associate(x, np.diag([0.01, 0.01, 0.001]) ** 2, [Measurement(zA, m.R, "positive")], tm, mount,
                  GateConfig(view=ViewLimits()))
    assert a[0].status == ACCEPTED and a[0].target_id == "A"
    # polarity decides too
    a = associate(x, np.diag([0.3, 0.3, 0.01]) ** 2, [Measurement(z, m.R, "negative")], tm, mount,
                  GateConfig(view=ViewLimits()))
    assert a[0].status == "no_candidate"


def test_latency_gives_the_same_estimate(targets):
    """Fusing a frame later, at its capture time, ends where fusing it at once does."""
    P0 = np.diag([0.01, 0.01, 0.002]) ** 2
    a = run_filter(np.random.default_rng(11), targets, np.zeros(3), P0)
    b = run_filter(np.random.default_rng(11), targets, np.zeros(3), P0, latency_steps=3)
    np.testing.assert_allclose(a[1][-1], b[1][-1], atol=1e-9)
    np.testing.assert_allclose(a[2][-1], b[2][-1], atol=1e-12)


def test_relocalizes_when_lost(targets):
    """Started 3 m off with a huge covariance the filter is lost, then re-localizes from two targets."""
    rng = np.random.default_rng(5)
    x0 = np.array([3.0, 1.0, 0.2])
    P0 = np.diag([3.0, 3.0, 1.0]) ** 2
    poses, est, cov, results = run_filter(rng, targets, x0, P0, steps=500)
    assert any(r.relocalized for r in results)
    err = np.hypot(*(est[:, :2] - poses[:, :2]).T)
    assert err[-50:].max() < 0.05
    assert not results[-1].lost


def test_deterministic(targets):
    a = run_filter(np.random.default_rng(9), targets, np.zeros(3), np.eye(3) * 1e-4, false_per_frame=1)
    b = run_filter(np.random.default_rng(9), targets, np.zeros(3), np.eye(3) * 1e-4, false_per_frame=1)
    assert np.array_equal(a[1], b[1]) and np.array_equal(a[2], b[2])


def test_bad_inputs(targets):
    with pytest.raises(ValueError):
        PoseEKF([0, 0], np.eye(3), targets, MOUNT)
    with pytest.raises(ValueError):
        PoseEKF([0, 0, 0], -np.eye(3), targets, MOUNT)
    ekf = PoseEKF([0, 0, 0], np.eye(3) * 1e-4, targets, MOUNT)
    ekf.add_odometry(1.0, 0.1, 0.0)
    with pytest.raises(ValueError):
        ekf.add_odometry(0.5, 0.1, 0.0)
    ekf.flush(1.0)
    with pytest.raises(ValueError):
        ekf.process_frame(0.5, [])
    with pytest.raises(ValueError):
        FilterConfig(measurement_floor=(0.1, 0.1))
