"""Localization integrity in the closed loop: pushing into a wall and a kidnapped vehicle, on plant_floor with
the geometric source (fast; the rendered frames are `agvsim bench localization-integrity`'s)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from agvsim.loop.closed_loop import ClosedLoop, LoopConfig
from agvsim.loop.pure_pursuit import FollowerParams, PurePursuit, RoutePath
from agvsim.sensors import GeometricSource, VisionConfig
from agvsim.world import load_map


@pytest.fixture(scope="module")
def plant():
    return load_map("plant_floor")


def _setup(world_map, seed: int, believed=None):
    vision = VisionConfig().for_map(world_map)
    start = tuple(float(v) for v in world_map.route("default")[0].pose)
    loop = ClosedLoop(world_map, start, np.random.default_rng(seed), LoopConfig(vision_config=vision),
                      GeometricSource(world_map, vision), believed_pose=believed)
    path = RoutePath.from_route(world_map, "default")
    vp = loop.config.sim.vehicle
    pursuit = PurePursuit(path, FollowerParams(), laps=10.0, max_speed=vp.max_speed, max_yaw_rate=vp.max_yaw_rate)
    return loop, path, pursuit


def _drive(loop, pursuit, seconds: float, record=None) -> None:
    for _ in range(int(round(seconds * loop.config.sim.control_rate))):
        loop.step(*pursuit.command(tuple(loop.true_pose)))
        if record is not None:
            record.append((loop.ekf.status, float(np.hypot(*(loop.true_pose[:2] - loop.believed_pose[:2])))))


def _honest(loop) -> bool:
    e = loop.true_pose[:2] - loop.believed_pose[:2]
    return loop.ekf.status != "tracking" or float(e @ np.linalg.solve(loop.covariance[:2, :2], e)) <= 11.83


def test_pushing_into_a_wall_stays_honest_then_recovers(plant):
    loop, path, pursuit = _setup(plant, 3)
    _drive(loop, pursuit, 10.0)
    assert loop.ekf.status == "tracking"
    # face the nearest solid straight ahead and push for 30 s with the wheels spinning
    x, y, th = loop.true_pose.tolist()
    heading = min((a for a in np.linspace(-math.pi, math.pi, 72, endpoint=False)),
                  key=lambda a: next((r for r in np.arange(0.5, 8.0, 0.25)
                                      if not plant.line_of_sight((x, y), (x + r * math.cos(a), y + r * math.sin(a)))),
                                     99.0))
    for _ in range(100):
        err = math.remainder(heading - loop.true_pose[2], 2 * math.pi)
        if abs(err) < 0.05:
            break
        loop.step(0.0, max(min(2.0 * err, 1.0), -1.0))
    pushed = honest = steps = 0
    for _ in range(600):
        s = loop.step(0.8, 0.0)
        steps += 1
        honest += _honest(loop)
        pushed += bool(s.sim.in_contact)
        if pushed >= 300:
            break
    assert pushed >= 300, "the vehicle never reached the wall"
    assert honest == steps  # never a confident wrong pose while the wheels spin
    assert loop.ekf.status != "tracking"
    assert loop.localization_info()["reason"]
    # drive on: the filter finds itself again from the targets
    pursuit.progress = path.project(loop.true_pose[:2], 0.0, window=path.length)
    record: list = []
    _drive(loop, pursuit, 60.0, record)
    assert loop.ekf.relocalizations >= 1
    assert record[-1][0] == "tracking" and record[-1][1] < 0.10


def test_kidnapped_vehicle_is_lost_then_found(plant):
    loop, path, pursuit = _setup(plant, 4)
    _drive(loop, pursuit, 15.0)
    assert loop.ekf.status == "tracking"
    s = (pursuit.progress + 12.0) % path.length
    xy = path.point_at(s)
    before = loop.believed_pose.copy()
    loop.kidnap((float(xy[0]), float(xy[1]), 1.0))
    assert np.allclose(loop.true_pose[:2], xy) and np.allclose(loop.believed_pose, before)  # not told
    assert loop.kidnaps == 1
    pursuit.progress = s
    record: list = []
    _drive(loop, pursuit, 45.0, record)
    statuses = [r[0] for r in record]
    assert "lost" in statuses or "relocalizing" in statuses
    assert loop.ekf.relocalizations >= 1
    assert record[-1][0] == "tracking" and record[-1][1] < 0.10
    with pytest.raises(ValueError, match="nearest wall or obstacle"):
        loop.kidnap((plant.obstacles[0].polygon.mean(axis=0)[0], plant.obstacles[0].polygon.mean(axis=0)[1], 0.0))


def test_unknown_start_finds_itself(plant):
    loop, path, pursuit = _setup(plant, 5, believed="unknown")
    assert loop.localization_info()["status"] == "lost"
    assert loop.localization_info()["reason"] == "start pose unknown"
    record: list = []
    _drive(loop, pursuit, 40.0, record)
    assert loop.ekf.relocalizations >= 1
    assert record[-1][0] == "tracking" and record[-1][1] < 0.10
