"""Dead reckoning: exact when ideal, drifting as the error model says otherwise."""
import math

import numpy as np
import pytest

from agvsim.vehicle.encoders import OdometryErrorModel

from .conftest import drive_straight, make_sim, turn_in_place, wrap


def mixed_drive(sim, seconds, seed=0):
    """Speeds and turns that change every 2 s (a fixed pseudo-random schedule)."""
    rng = np.random.default_rng(seed)
    steps_per_change = int(2 * sim.config.control_rate)
    v = w = 0.0
    for k in range(int(seconds * sim.config.control_rate)):
        if k % steps_per_change == 0:
            v = float(rng.uniform(-0.3, 1.5))
            w = float(rng.uniform(-1.0, 1.0))
        sim.step(v, w)


def pos_error(sim):
    t, o = np.array(sim.true_pose), np.array(sim.odometry_pose)
    return float(np.hypot(*(t[:2] - o[:2])))


def test_ideal_dead_reckoning_is_exact_over_100m():
    sim = make_sim("ideal")
    mixed_drive(sim, 150.0)
    assert sim.distance > 100.0
    assert pos_error(sim) < 1e-3
    assert abs(sim.true_pose[2] - sim.odometry_pose[2]) < 1e-6


def test_typical_error_grows_with_distance():
    errors_short, errors_long = [], []
    for seed in range(6):
        sim = make_sim("typical", seed=seed)
        mixed_drive(sim, 40.0, seed=seed)
        errors_short.append(pos_error(sim))
        mixed_drive(sim, 120.0, seed=seed + 100)
        errors_long.append(pos_error(sim))
    assert np.mean(errors_long) > 2.0 * np.mean(errors_short)
    assert np.mean(errors_short) > 1e-3  # it does drift


def test_increments_sum_to_the_dead_reckoned_path():
    sim = make_sim("typical", seed=3)
    total_ds = total_dth = 0.0
    for k in range(200):
        result = sim.step(1.0, 0.3 * math.sin(k / 15))
        total_ds += result.ds
        total_dth += result.dtheta
        assert result.command == sim.config.vehicle.clip_command(1.0, 0.3 * math.sin(k / 15))
    assert total_dth == pytest.approx(sim.odometry_pose[2], abs=1e-12)
    assert total_ds == pytest.approx(sim.odometry.distance, rel=1e-12)


def square(sim, side, direction):
    for _ in range(4):
        drive_straight(sim, side)
        turn_in_place(sim, direction * math.pi / 2)


@pytest.mark.parametrize("direction", [1, -1])
def test_umbmark_wheelbase_error_is_direction_dependent(direction):
    """E_b only (type A): heading error (E_b - 1) * (±2π), opposite for CW and CCW."""
    eb = 1.01
    sim = make_sim(OdometryErrorModel(eb=eb))
    square(sim, 4.0, direction)
    err = sim.odometry_pose[2] - sim.true_pose[2]
    assert err == pytest.approx((eb - 1) * direction * 2 * math.pi, rel=0.02)


@pytest.mark.parametrize("direction", [1, -1])
def test_umbmark_diameter_error_curves_the_same_way_both_directions(direction):
    """E_d only (type B): each straight leg of L turns dead reckoning by
    -(E_d - 1)(E_d + 1) L / (2 E_d b), the same sign for CW and CCW."""
    ed = 1.005
    sim = make_sim(OdometryErrorModel(ed=ed))
    square(sim, 4.0, direction)
    b = sim.config.vehicle.track_width
    expected = -4 * (ed - 1) * (ed + 1) * 4.0 / (2 * ed * b)
    err = sim.odometry_pose[2] - sim.true_pose[2]
    assert err == pytest.approx(expected, rel=0.05)


def test_quantization_bounds_the_error_without_noise():
    sim = make_sim(OdometryErrorModel(ticks_per_rev=512))
    mixed_drive(sim, 40.0)
    p = sim.config.vehicle
    tick = 2 * math.pi * p.wheel_radius / 512
    # heading error is at most two counts over the wheelbase
    assert abs(wrap(sim.odometry_pose[2] - sim.true_pose[2])) <= 2 * tick / p.track_width + 1e-9
    assert pos_error(sim) > 0.0


def test_slip_against_a_wall_fools_dead_reckoning():
    from .conftest import bare_world

    world = bare_world(walls=[("w", [[3.0, -5.0], [3.0, 5.0]], 0.1)])
    slip = make_sim(OdometryErrorModel(slip_in_contact=1.0), world=world)
    grip = make_sim(OdometryErrorModel(), world=world)
    for sim in (slip, grip):
        for _ in range(80):
            sim.step(1.0, 0.0)
    # without the slip model only the sideways push of the contact (which no
    # wheel encoder can see) separates dead reckoning from truth
    assert pos_error(grip) < 0.01
    assert slip.odometry_pose[0] > slip.true_pose[0] + 1.0  # wheels spun against the wall


def test_same_seed_same_run_bit_for_bit():
    def run(seed):
        sim = make_sim("worn", seed=seed)
        mixed_drive(sim, 30.0)
        return np.array(sim.odometry_pose), np.array(sim.true_pose)

    a, b, c = run(7), run(7), run(8)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])


@pytest.mark.parametrize("bad", [dict(wheel_noise=-0.1), dict(ed=0.0), dict(slip_in_contact=2.0),
                                 dict(ticks_per_rev=-5), dict(eb=float("nan"))])
def test_bad_error_model_is_rejected(bad):
    with pytest.raises(ValueError):
        OdometryErrorModel(**bad)


def test_unknown_preset_names_the_choices():
    with pytest.raises(ValueError, match="typical"):
        OdometryErrorModel.preset("tipycal")
