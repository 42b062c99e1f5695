"""The chassis reaches commanded speeds within its limits and moves as commanded."""
import math

import numpy as np
import pytest

from agvsim.vehicle.dynamics import VehicleParams

from .conftest import bare_world, drive_straight, make_sim, turn_in_place, wrap


def run(sim, v, w, seconds):
    for _ in range(int(round(seconds * sim.config.control_rate))):
        sim.step(v, w)


def test_commanded_speed_is_reached():
    sim = make_sim()
    run(sim, 1.0, 0.0, 3.0)
    v, w = sim.vehicle.velocity
    assert v == pytest.approx(1.0, abs=1e-6)
    assert w == pytest.approx(0.0, abs=1e-9)


def test_speed_is_clipped_to_the_limit():
    sim = make_sim()
    run(sim, 5.0, 0.0, 4.0)
    assert sim.vehicle.velocity[0] == pytest.approx(VehicleParams().max_speed, abs=1e-6)


def test_acceleration_is_limited():
    sim = make_sim()
    run(sim, 1.5, 0.0, 0.5)
    limit = VehicleParams().max_accel * 0.5
    assert sim.vehicle.velocity[0] <= limit + 1e-6
    assert sim.vehicle.velocity[0] >= 0.9 * limit


def test_yaw_rate_is_reached_and_wheels_stay_within_limits():
    sim = make_sim()
    run(sim, 0.0, 0.7, 2.0)
    assert sim.vehicle.velocity[1] == pytest.approx(0.7, abs=1e-6)
    # full speed and full turn at once: wheel rim speeds must stay <= max_speed
    run(sim, 1.5, 1.5, 3.0)
    left, right = sim.vehicle.wheel_speeds()
    assert max(abs(left), abs(right)) <= VehicleParams().max_speed + 1e-9
    v, w = sim.vehicle.velocity
    half_track = 0.5 * VehicleParams().track_width
    assert v == pytest.approx(1.5 * 1.5 / (1.5 + 1.5 * half_track), rel=1e-3)  # scaled, curvature kept
    assert w / v == pytest.approx(1.0, rel=1e-3)


def test_no_sideways_slip_in_a_turn():
    """At constant (v, ω) the chassis centre runs on a circle of radius v/ω."""
    sim = make_sim()
    run(sim, 1.2, 0.6, 4.0)  # reach the command
    pts = []
    for _ in range(40):
        sim.step(1.2, 0.6)
        pts.append(sim.true_pose[:2])
    pts = np.array(pts)
    # algebraic circle fit: x^2 + y^2 + D x + E y + F = 0
    A = np.column_stack([pts, np.ones(len(pts))])
    b = -(pts ** 2).sum(axis=1)
    D, E, F = np.linalg.lstsq(A, b, rcond=None)[0]
    centre = np.array([-D / 2, -E / 2])
    radii = np.linalg.norm(pts - centre, axis=1)
    assert np.ptp(radii) < 1e-4
    assert radii.mean() == pytest.approx(1.2 / 0.6, abs=1e-3)


def test_straight_10m_run_ends_on_target():
    """Open loop: 1 m/s for 10 s, then stop. The slew at 1 m/s² makes a
    trapezoid whose area is exactly 10 m."""
    sim = make_sim(pose=(1.0, 2.0, 0.3))
    run(sim, 1.0, 0.0, 10.0)
    run(sim, 0.0, 0.0, 2.0)
    x, y, th = sim.true_pose
    travelled = np.hypot(x - 1.0, y - 2.0)
    assert travelled == pytest.approx(10.0, abs=1e-3)
    assert math.atan2(y - 2.0, x - 1.0) == pytest.approx(0.3, abs=1e-6)
    assert th == pytest.approx(0.3, abs=1e-9)
    assert sim.vehicle.velocity[0] == pytest.approx(0.0, abs=1e-9)


def test_closed_loop_straight_run_stays_on_the_line():
    sim = make_sim()
    drive_straight(sim, 10.0)
    x, y, th = sim.true_pose
    assert x == pytest.approx(10.0, abs=0.05)
    assert abs(y) < 0.005
    assert abs(wrap(th)) < math.radians(0.1)


def test_full_turn_returns_to_heading_in_place():
    sim = make_sim(pose=(3.0, -2.0, 0.4))
    turn_in_place(sim, 2 * math.pi)
    x, y, th = sim.true_pose
    assert th - 0.4 == pytest.approx(2 * math.pi, abs=math.radians(0.05))
    assert math.hypot(x - 3.0, y + 2.0) < 0.005


def test_non_finite_command_is_an_error():
    sim = make_sim()
    with pytest.raises(ValueError, match="finite"):
        sim.step(float("nan"), 0.0)


@pytest.mark.parametrize("field,value", [("mass", 0.0), ("max_speed", -1.0), ("width", float("inf"))])
def test_bad_vehicle_params_are_rejected(field, value):
    with pytest.raises(ValueError, match=field):
        VehicleParams(**{field: value})


def test_control_rate_must_divide_physics_rate():
    from agvsim.vehicle.simulation import SimConfig

    with pytest.raises(ValueError, match="whole multiple"):
        SimConfig(physics_rate=100.0, control_rate=30.0)
    assert SimConfig(physics_rate=100.0, control_rate=25.0).substeps == 4
    assert np.isclose(SimConfig().control_dt, 0.1)


def test_drive_matches_track_and_space_step_bit_for_bit():
    """``DiffDriveVehicle.drive`` (the hot path) inlines ``track``; both move the chassis alike."""
    world = bare_world(walls=[("w", [[3.0, -5.0], [3.0, 5.0]], 0.1)])
    a, b = make_sim(world=world), make_sim(world=world)
    dt, n = a.config.physics_dt, a.config.substeps
    commands = [(1.5, 0.0), (1.2, 0.8), (-0.4, -1.5), (1.5, 0.3)] * 15
    for v, w in commands:
        v, w = a.config.vehicle.clip_command(v, w)
        a.vehicle.drive(v, w, dt, n)
        for _ in range(n):
            b.vehicle.track(v, w, dt)
            b.space.step(dt)
        assert a.vehicle.pose == b.vehicle.pose
        assert a.vehicle.commanded == b.vehicle.commanded
    assert a.contacts.events > 0 and a.contacts.events == b.contacts.events
