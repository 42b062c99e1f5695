"""One update path: the main filter and the re-localization hypotheses both go through filterpy's
EKF update, and the NIS is read from filterpy's innovation and its covariance.

The by-hand references below are plain filterpy ``ExtendedKalmanFilter`` objects fed the same
numbers; equality is exact (a hand-written update, e.g. ``S = (H P) Hᵀ + R`` instead of
filterpy's ``H (P Hᵀ) + R``, differs in the last bits for some of these cases).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

import localizer.numeric
from localizer.filter import (ACCEPTED, FilterConfig, GateConfig, Hypothesis, Measurement, OdometryAccumulator,
                              OdometryNoise, PoseEKF, RelocalizeConfig, Relocalizer, ViewLimits, associate, compose,
                              compose_jacobians, innovation, measurement_jacobian, predict_all,
                              predict_measurement)
from tests.filter.conftest import LIMITS, MOUNT, corridor_targets

GATE = GateConfig(view=LIMITS)
CASES = range(12)


def by_hand(x, P, m: Measurement, pos, yaw):
    """A plain filterpy EKF update of (x, P) with m; returns the filter."""
    kf = ExtendedKalmanFilter(dim_x=3, dim_z=3)
    kf.x = np.asarray(x, dtype=float).reshape(3, 1).copy()
    kf.P = np.asarray(P, dtype=float).copy()
    kf.update(m.z.reshape(3, 1), lambda s: measurement_jacobian(s, pos, yaw, MOUNT),
              lambda s: predict_measurement(s, pos, yaw, MOUNT).reshape(3, 1), R=m.R, residual=innovation)
    return kf


def case(k: int):
    """A pose near (21.5, 0, 0) with a random covariance and a noisy measurement of one target in view."""
    rng = np.random.default_rng(1000 + k)
    targets = corridor_targets()
    truth = np.array([21.5 + rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3), rng.uniform(-0.1, 0.1)])
    A = rng.normal(size=(3, 3)) * np.array([0.05, 0.05, 0.01])
    P = A @ A.T + np.diag([1e-4, 1e-4, 1e-6])
    x = truth + rng.multivariate_normal(np.zeros(3), P)
    Z, visible = predict_all(truth, targets, MOUNT, LIMITS)
    j = int(np.nonzero(visible)[0][0])
    pos, yaw = targets.positions[j], float(targets.yaws[j])
    R = np.diag([1e-4, 1e-6, 1e-4])
    z = predict_measurement(truth, pos, yaw, MOUNT) + rng.multivariate_normal(np.zeros(3), R)
    return targets, j, x, P, Measurement(z, R, targets.polarities[j])


@pytest.mark.parametrize("k", CASES)
def test_hypothesis_update_is_filterpys_update(k):
    targets, j, x, P, m = case(k)
    reloc = Relocalizer(targets, MOUNT, GATE, RelocalizeConfig(confirm_targets=5))
    reloc.hypotheses = [Hypothesis(x.copy(), P.copy())]
    # the target must be the one associated, else no update happens and the test says nothing
    (a,) = associate(x, P, [m], targets, MOUNT, GATE)
    assert a.status == ACCEPTED and a.target == j
    assert reloc.update([m]) is None
    (h,) = reloc.hypotheses
    ref = by_hand(x, P, m, targets.positions[j], float(targets.yaws[j]))
    assert not np.array_equal(h.x, x)  # it moved
    assert np.array_equal(h.x, ref.x.reshape(-1))
    assert np.array_equal(h.P, ref.P)
    assert h.matched == {targets.ids[j]}


@pytest.mark.parametrize("k", CASES)
def test_main_filter_update_and_nis_are_filterpys(k):
    targets, j, x, P, m = case(k)
    config = FilterConfig(noise=OdometryNoise(), gate=GATE, measurement_floor=(0.0, 0.0, 0.0))
    ekf = PoseEKF(x, P, targets, MOUNT, config)
    res = ekf.process_frame(0.0, [m])
    assert res.accepted == 1
    ref = by_hand(x, 0.5 * (P + P.T), m, targets.positions[j], float(targets.yaws[j]))
    y = ref.y.reshape(-1)
    assert res.nis[0] == float(y @ np.linalg.solve(ref.S, y))
    # ... which is the filter's own filterpy state after the update, not a recomputation
    assert np.array_equal(ekf.kf.y, ref.y) and np.array_equal(ekf.kf.S, ref.S)
    expected_x = ref.x.reshape(-1).copy()
    expected_x[2] = localizer.numeric.wrap_angle(float(expected_x[2]))
    assert np.array_equal(ekf.x, expected_x)
    assert np.array_equal(ekf.P, ref.P)


def test_hypothesis_predict_is_the_main_filters_predict():
    x = np.array([1.0, 2.0, 0.3])
    P = np.diag([0.01, 0.02, 0.003]) ** 2
    noise = OdometryNoise(wheel_noise=0.002, diameter_bias=0.001)
    ekf = PoseEKF(x, P, corridor_targets(), MOUNT, FilterConfig(noise=noise, gate=GATE))
    acc = OdometryAccumulator(noise)
    for k, (ds, dth) in enumerate([(0.1, 0.01), (0.12, -0.02), (0.11, 0.03)]):
        ekf.add_odometry(0.1 * (k + 1), ds, dth)
        acc.add(ds, dth)
    ekf.flush(0.3)
    reloc = Relocalizer(corridor_targets(), MOUNT, GATE)
    reloc.hypotheses = [Hypothesis(x, P)]
    reloc.predict(acc.u, acc.Q)
    (h,) = reloc.hypotheses
    F, G = compose_jacobians(x, acc.u)
    np.testing.assert_allclose(h.x, compose(x, acc.u), rtol=0, atol=1e-15)
    np.testing.assert_allclose(h.P, F @ P @ F.T + G @ acc.Q @ G.T, rtol=1e-12, atol=0)
    assert not np.array_equal(h.P, P)
    # the same filterpy predict; only the main filter wraps its heading afterwards
    wrapped = h.x.copy()
    wrapped[2] = localizer.numeric.wrap_angle(float(wrapped[2]))
    assert np.array_equal(wrapped, ekf.x) and np.array_equal(h.P, ekf.P)


def test_one_wrap_angle():
    import localizer.filter
    import localizer.filter.measurement

    assert localizer.filter.wrap_angle is localizer.numeric.wrap_angle
    assert "wrap_angle" not in localizer.filter.measurement.__all__


@pytest.mark.parametrize("make, message", [
    (lambda: FilterConfig(lost_rejected_frames=0), "FilterConfig.lost_rejected_frames must be a whole number >= 1"),
    (lambda: FilterConfig(lost_position_sigma=0.0), "FilterConfig.lost_position_sigma must be a finite number > 0 (m)"),
    (lambda: FilterConfig(measurement_floor=(0.1, -1.0, 0.1)), "FilterConfig.measurement_floor[1] must be"),
    (lambda: FilterConfig(measurement_floor=(0.1, 0.1)), "FilterConfig.measurement_floor must be 3 numbers"),
    (lambda: GateConfig(gate_probability=1.0), "GateConfig.gate_probability must be a finite number > 0 and < 1"),
    (lambda: GateConfig(ambiguity_margin=math.nan), "GateConfig.ambiguity_margin must be"),
    (lambda: OdometryNoise(wheel_noise=-1.0), "OdometryNoise.wheel_noise must be a finite number >= 0"),
    (lambda: OdometryNoise(track_width=0.0), "OdometryNoise.track_width must be a finite number > 0 (m)"),
    (lambda: RelocalizeConfig(max_misses=0), "RelocalizeConfig.max_misses must be a whole number >= 1"),
    (lambda: RelocalizeConfig(merge_heading=-0.1), "RelocalizeConfig.merge_heading must be a finite number >= 0 (rad)"),
    (lambda: ViewLimits(min_range=5.0, max_range=1.0), "ViewLimits.max_range must be a finite number > 5 (m), got 1.0"),
    (lambda: ViewLimits(half_fov=4.0), "ViewLimits.half_fov must be"),
])
def test_config_messages_name_field_value_and_expectation(make, message):
    with pytest.raises(ValueError) as err:
        make()
    assert str(err.value).startswith(message), str(err.value)
