"""The filter's inputs and numbers: every input validated at the filter's boundary
with nothing half-applied, re-localization confirmed only from informative observations,
the covariance bounded, refusals counted by reason."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

from localizer.filter import FilterConfig, GateConfig, Measurement, PoseEKF, TargetMap, predict_all
from localizer.filter.ekf import MAX_POSITION_SIGMA, UNINFORMATIVE
from tests.filter.conftest import LIMITS, MOUNT, NOISE, corridor_targets, measure

CONFIG = FilterConfig(noise=NOISE, gate=GateConfig(view=LIMITS))
P0 = np.diag([1e-4, 1e-4, 1e-6])


def new_filter(x0=(0.0, 0.0, 0.0), targets=None):
    return PoseEKF(np.array(x0), P0, corridor_targets() if targets is None else targets, MOUNT, CONFIG)


def test_measurement_refuses_a_covariance_not_positive_semi_definite():
    with pytest.raises(ValueError, match=r"Measurement\.R must be a finite symmetric positive semi-definite"):
        Measurement([3, 0.1, 0.1], -np.eye(3))
    with pytest.raises(ValueError, match=r"Measurement\.R"):
        Measurement([3, 0.1, 0.1], [[1e-4, 0, 0], [0, 1e-4, 0], [0, 1.0, 1e-4]])  # not symmetric
    # through the filter: the frame is refused whole, the state untouched
    ekf = new_filter()
    x, P = ekf.x, ekf.P
    ekf.add_odometry(0.1, 0.1, 0.0)
    bad = Measurement.__new__(Measurement)
    object.__setattr__(bad, "z", np.array([3.0, 0.1, 0.1]))
    object.__setattr__(bad, "R", -np.eye(3))
    object.__setattr__(bad, "polarity", None)
    with pytest.raises(ValueError, match=r"observations\[0\].*R"):
        ekf.process_frame(0.1, [bad])
    assert np.array_equal(ekf.x, x) and np.array_equal(ekf.P, P) and ekf.time == 0.0
    assert ekf.diagnostics()["refusals"]["measurement_invalid"] == 1


def test_nan_in_r_is_named_r_not_z():
    R = np.diag([1e-4, 1e-6, 1e-4])
    R[0, 0] = math.nan
    with pytest.raises(ValueError) as err:
        Measurement([3, 0.1, 0.1], R)
    assert str(err.value).startswith("Measurement.R must be"), str(err.value)
    assert "z=" not in str(err.value)


def test_nan_odometry_leaves_nothing_queued_and_no_motion_lost():
    ekf = new_filter()
    for k in range(10):
        ekf.add_odometry((k + 1) * 0.1, 0.1, 0.0)
    with pytest.raises(ValueError, match=r"PoseEKF\.add_odometry ds must be a finite number"):
        ekf.add_odometry(1.05, math.nan, 0.0)
    with pytest.raises(ValueError, match=r"PoseEKF\.add_odometry dtheta"):
        ekf.add_odometry(1.05, 0.1, math.inf)
    assert len(ekf._pending) == 10
    assert ekf.pose()[0] == pytest.approx(1.0)
    ekf.process_frame(1.0, [])
    assert ekf.x[0] == pytest.approx(1.0)  # the metre queued since the last frame is kept
    assert ekf.diagnostics()["refusals"]["odometry_increment"] == 2


@pytest.mark.parametrize("t, message", [
    (math.nan, "PoseEKF.add_odometry t must be a finite number (s), got nan"),
    (math.inf, "PoseEKF.add_odometry t must be a finite number (s), got inf"),
    (0.05, "PoseEKF.add_odometry t must not decrease"),
])
def test_bad_odometry_time_stamps_are_refused(t, message):
    ekf = new_filter()
    ekf.add_odometry(0.1, 0.1, 0.0)
    with pytest.raises(ValueError) as err:
        ekf.add_odometry(t, 0.1, 0.0)
    assert str(err.value).startswith(message), str(err.value)
    assert len(ekf._pending) == 1
    # the filter carries on
    ekf.add_odometry(0.2, 0.1, 0.0)
    ekf.process_frame(0.2, [])
    assert ekf.x[0] == pytest.approx(0.2) and not ekf._pending
    assert ekf.diagnostics()["refusals"]["odometry_time"] == 1


@pytest.mark.parametrize("t", [math.nan, math.inf, -math.inf, 0.05])
def test_bad_frame_time_stamps_are_refused(t):
    ekf = new_filter()
    ekf.add_odometry(0.1, 0.1, 0.0)
    ekf.process_frame(0.1, [])
    with pytest.raises(ValueError, match=r"PoseEKF\.process_frame t_capture"):
        ekf.process_frame(t, [])
    with pytest.raises(ValueError, match=r"PoseEKF\.flush t"):
        ekf.flush(t)
    assert ekf.time == 0.1
    ekf.add_odometry(0.2, 0.1, 0.0)
    ekf.process_frame(0.2, [])
    assert ekf.x[0] == pytest.approx(0.2)
    assert ekf.diagnostics()["refusals"]["frame_time"] == 2


def test_a_huge_step_is_refused():
    ekf = new_filter()
    with pytest.raises(ValueError, match=r"PoseEKF\.add_odometry ds must be a finite number >= -10 and <= 10 \(m\)"):
        ekf.add_odometry(0.1, 1e200, 0.0)
    with pytest.raises(ValueError, match=r"in_contact must be a bool"):
        ekf.add_odometry(0.1, 0.1, 0.0, in_contact="yes")
    assert not ekf._pending
    ekf.process_frame(0.1, [])
    assert np.isfinite(ekf.P).all() and ekf.status == "tracking"


def test_an_uninformative_observation_is_refused_and_counted():
    targets = corridor_targets()
    ekf = new_filter((8.0, 0.0, 0.0), targets)
    rng = np.random.default_rng(1)
    ms = [m for _, m in measure(np.array([8.0, 0.0, 0.0]), targets, rng)]
    assert ms
    loose = Measurement(ms[0].z + [1.0, 0.0, 0.0], ms[0].R * 1e8, ms[0].polarity)
    res = ekf.process_frame(0.0, [loose] + ms)
    assert res.associations[0].status == UNINFORMATIVE and res.associations[0].observation == 0
    assert [a.observation for a in res.associations] == list(range(len(ms) + 1))
    assert res.accepted == len(ms)
    assert ekf.diagnostics()["refusals"]["measurement_uninformative"] == 1


def test_relocalization_is_not_confirmed_from_uninformative_observations():
    """Lost near T0; a precise observation of T0 seeds a right hypothesis near x = 0 and a wrong
    one near x = 28 (T1 has T0's polarity). A loose observation of a negative target fits
    only the wrong one (T2 in its view): it must not confirm it."""
    targets = TargetMap(("T0", "T1", "T2"), [[4.4, -4.0], [32.4, -4.0], [33.0, -5.0]],
                        [math.pi / 2] * 3, ("positive", "positive", "negative"))
    truth = np.array([0.0, 0.0, 0.0])
    ekf = PoseEKF(truth, P0, targets, MOUNT, CONFIG)
    ekf.declare_lost("test")
    Z, vis = predict_all(truth, targets, MOUNT, LIMITS)
    assert vis[0]
    good = Measurement(Z[0], np.diag([1e-6, 1e-8, 1e-6]), "positive")
    res = ekf.process_frame(0.0, [good])
    assert not res.relocalized and res.hypotheses >= 2
    wrong = np.array([28.0, 0.0, 0.0])
    Zw, visw = predict_all(wrong, targets, MOUNT, LIMITS)
    assert visw[2]
    # as the soak's: the observation of T2 from the wrong pose with a loose covariance (within
    # the sane bounds, σ_d 0.9 m, σ_α 0.3 rad: it places the vehicle only within metres)
    loose = Measurement(Zw[2], np.diag([0.9 ** 2, 1e-8, 0.3 ** 2]), "negative")
    for k in range(3):
        res = ekf.process_frame(0.0, [loose])
        assert not res.relocalized, ekf.x
    assert ekf.lost
    assert ekf.diagnostics()["refusals"]["uninformative_match"] >= 1
    # precise observations of two targets, each explained twice (confirm_sightings), two frames in
    # a row (confirm_frames), do confirm: the first one (T0 from the truth) is T1 from x = 28
    ekf2 = PoseEKF(truth, P0, targets, MOUNT, CONFIG)
    ekf2.declare_lost("test")
    ekf2.process_frame(0.0, [good])  # seeds (the seed explains nothing)
    precise = Measurement(Zw[2], np.diag([1e-6, 1e-8, 1e-6]), "negative")
    assert not ekf2.process_frame(0.0, [precise]).relocalized  # T2 once: it could be a chance fit
    assert [ekf2.process_frame(0.0, [good, precise]).relocalized for _ in range(3)] == [False, False, True]
    assert abs(ekf2.x[0] - 28.0) < 0.1  # what precise observations say is believed


def test_covariance_bounded_under_garbage():
    """A short soak: odometry, consistent frames, far-off garbage, covariances x1e3..x1e300,
    near-singular ones, empty frames, and spells of being lost; the covariance stays finite,
    symmetric, positive definite and bounded, and no re-localization lands far off."""
    xs = np.array([2.0, 5.0, 12.0, 14.5, 22.0, 27.0, 29.0, 36.5, 41.0, 47.5, 50.0, 58.0])  # no two stretches alike
    targets = TargetMap(tuple(f"U{i:02d}" for i in range(len(xs))), np.stack([xs, np.full_like(xs, -4.0)], 1),
                        np.full(len(xs), math.pi / 2), tuple("positive" if i % 3 else "negative" for i in range(len(xs))))
    rng = np.random.default_rng(7)
    ekf = new_filter((1.0, 0.0, 0.0), targets)
    from localizer.filter import arc_motion, compose
    x = np.array([1.0, 0.0, 0.0])
    v, dt = 1.0, 0.02
    start = time.perf_counter()
    worst_eig = 0.0
    for k in range(6000):
        t = (k + 1) * dt
        if x[0] > 58:
            v = -1.0
        if x[0] < 2:
            v = 1.0
        x = compose(x, arc_motion(v * dt, 0.0))
        ekf.add_odometry(t, v * dt + rng.normal(0, 1e-4), rng.normal(0, 1e-5))
        if (k + 1) % 1000 == 0:
            ekf.declare_lost("test")
        if (k + 1) % 10:
            continue
        obs = [m for _, m in measure(x, targets, rng)]
        kind = rng.choice(5, p=[0.8, 0.05, 0.05, 0.05, 0.05])
        if kind == 1:
            obs = [Measurement([rng.uniform(0.6, 11), rng.uniform(-0.3, 0.3), rng.uniform(-1, 1)],
                               np.diag([1e-4, 1e-8, 1e-4]), str(rng.choice(["positive", "negative"])))
                   for _ in range(2)]
        elif kind == 2:
            obs = [Measurement(np.abs(m.z + rng.normal(0, 1, 3) * [3, 0.1, 0.3]), m.R * 10.0 ** rng.uniform(3, 300),
                               m.polarity) for m in obs]
        elif kind == 3:
            u = rng.normal(size=3)
            R = np.outer(u, u) * 10.0 ** rng.uniform(-4, 4) + np.eye(3) * 1e-15
            obs = [Measurement(np.abs(m.z + rng.normal(0, 1, 3) * [3, 0.1, 0.3]), R, m.polarity) for m in obs]
        elif kind == 4:
            obs = []
        res = ekf.process_frame(t, obs)
        P = ekf.P
        assert np.isfinite(P).all() and np.allclose(P, P.T, rtol=1e-9, atol=0)
        eig = np.linalg.eigvalsh(P)
        assert eig[0] > 0
        worst_eig = max(worst_eig, eig[-1])
        if res.relocalized:
            assert math.hypot(*(ekf.x[:2] - x[:2])) < 1.0
    assert worst_eig <= MAX_POSITION_SIGMA ** 2
    assert ekf.relocalizations >= 1
    d = ekf.diagnostics()
    assert d["refusals"]["measurement_uninformative"] > 0
    assert time.perf_counter() - start < 5.0


def test_refusal_counters_in_diagnostics():
    ekf = new_filter()
    d = ekf.diagnostics()
    assert d["refusals"] == {} and d["status"] == "tracking" and math.isnan(d["nis"])
    for bad in ((math.nan, 0.1, 0.0), (0.1, 1e200, 0.0)):
        with pytest.raises(ValueError):
            ekf.add_odometry(*bad)
    with pytest.raises(ValueError):
        ekf.process_frame(math.nan, [])
    assert ekf.diagnostics()["refusals"] == {"odometry_time": 1, "odometry_increment": 1, "frame_time": 1}
    assert set(d) >= {"status", "lost_reason", "position_sigma", "heading_sigma", "nis", "rejections",
                      "relocalizations", "lost_events", "refusals"}


def test_covariance_beyond_the_bound_is_lost_not_growing():
    ekf = new_filter()
    ekf.kf.P = np.diag([1e9, 1e9, 1e-6])  # as after a long drift (σ 31.6 km)
    ekf.add_odometry(0.1, 0.1, 0.0)
    ekf.process_frame(0.1, [])
    assert ekf.status in ("lost", "relocalizing")
    assert ekf.position_sigma() <= 2 * CONFIG.lost_sigma[0]
    assert ekf.diagnostics()["refusals"]["covariance_bound"] == 1
