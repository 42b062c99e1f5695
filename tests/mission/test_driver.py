"""The one route driver: steer_on, one log type, one seeding scheme; the closed loop's modes."""
from __future__ import annotations

import numpy as np
import pytest

import agvsim
from agvsim.loop.closed_loop import ClosedLoop, LoopConfig
from agvsim.loop.log import Arrival


@pytest.fixture(scope="module")
def corridor():
    return agvsim.load_map("corridor")


def test_steer_on_truth_follows_the_route_while_dead_reckoning_drifts(corridor):
    cfg = agvsim.MissionConfig(vision=False, steer_on="truth", distance=40.0,
                               sim=agvsim.SimConfig(odometry=agvsim.OdometryErrorModel.preset("worn")))
    log = agvsim.run_mission(corridor, None, np.random.default_rng(0), cfg)
    assert log.completed and log.steer_on == "truth"
    assert all(isinstance(a, Arrival) for a in log.arrivals)
    assert max(a.true_distance for a in log.arrivals) < 0.45  # the truth passes the stations
    assert log.odometry_error()[-1] > 0.05  # dead reckoning drifted
    # no camera: the estimate is dead reckoning (composed per control step, not per physics step)
    assert not log.frames
    np.testing.assert_allclose(log.estimate[:, :2], log.odometry_pose[:, :2], atol=5e-3)


def test_steer_on_estimate_carries_dead_reckoning_error_into_the_path(corridor):
    cfg = agvsim.MissionConfig(vision=False, steer_on="estimate", distance=40.0,
                               sim=agvsim.SimConfig(odometry=agvsim.OdometryErrorModel.preset("worn")))
    log = agvsim.run_mission(corridor, None, np.random.default_rng(0), cfg)
    # the follower passes the stations on its belief; the truth misses them by the drift
    assert max(a.steer_distance for a in log.arrivals) < 0.45
    assert max(a.true_distance for a in log.arrivals) > max(a.steer_distance for a in log.arrivals)


def test_same_seed_same_run_and_one_split(corridor):
    src = agvsim.GeometricSource(corridor)
    cfg = agvsim.MissionConfig(distance=15.0)
    a = agvsim.run_mission(corridor, src, np.random.default_rng(7), cfg)
    b = agvsim.run_mission(corridor, src, np.random.default_rng(7), cfg)
    np.testing.assert_array_equal(a.estimate, b.estimate)
    np.testing.assert_array_equal(a.true_pose, b.true_pose)
    # the loop splits the run's generator once: odometry from the first child, camera from the second
    loop = ClosedLoop(corridor, corridor.route()[0].pose, np.random.default_rng(7), LoopConfig())
    sim_rng, cam_rng = np.random.default_rng(7).spawn(2)
    assert loop.camera_rng.random() == cam_rng.random()


def test_closed_loop_localization_modes(corridor):
    start = corridor.route()[0].pose
    loops = {m: ClosedLoop(corridor, start, np.random.default_rng(1), LoopConfig(), localization=m)
             for m in ("ekf", "odometry", "truth")}
    for loop in loops.values():
        for _ in range(30):
            step = loop.step(1.0, 0.05)
    assert step.sim.command == (1.0, 0.05) and len(step.wheel_speeds) == 2
    np.testing.assert_array_equal(loops["truth"].covariance, np.zeros((3, 3)))
    np.testing.assert_array_equal(loops["truth"].believed_pose, loops["truth"].true_pose)
    np.testing.assert_array_equal(loops["odometry"].believed_pose, loops["odometry"].odometry_pose)
    assert np.linalg.eigvalsh(loops["odometry"].covariance)[-1] > 0  # dead reckoning's covariance grows
    with pytest.raises(ValueError, match="localization must be one of ekf, odometry, truth"):
        ClosedLoop(corridor, start, np.random.default_rng(1), localization="gps")


def test_mission_config_validates(corridor):
    with pytest.raises(ValueError, match="MissionConfig.steer_on must be one of estimate, truth"):
        agvsim.MissionConfig(steer_on="map")
    with pytest.raises(ValueError, match=r"MissionConfig.camera_rate must be a finite number > 0 \(Hz\)"):
        agvsim.MissionConfig(camera_rate=0.0)
    with pytest.raises(ValueError, match="vision is on but no observation source"):
        agvsim.run_mission(corridor, None, np.random.default_rng(0), agvsim.MissionConfig())
