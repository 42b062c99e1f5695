"""Full speed into walls and obstacles: the chassis stops outside them."""
import math

import numpy as np
import pytest

from .conftest import bare_world, make_sim


def chassis_corners(sim):
    x, y, th = sim.true_pose
    p = sim.config.vehicle
    c, s = math.cos(th), math.sin(th)
    local = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * [p.length / 2, p.width / 2]
    return local @ np.array([[c, s], [-s, c]]) + [x, y]


@pytest.mark.parametrize("thickness", [0.04, 0.2])
@pytest.mark.parametrize("heading", [0.0, 0.5])
def test_full_speed_into_a_wall_stops_outside(thickness, heading):
    wall_x = 8.0
    world = bare_world(walls=[("north", [[wall_x, -20.0], [wall_x, 20.0]], thickness)])
    sim = make_sim(world=world, pose=(0.0, 0.0, heading))
    touched = set()
    collided = False
    for _ in range(150):  # 15 s at full speed: far more than enough to reach the wall
        result = sim.step(1.5, 0.0)
        touched |= result.contacts
        collided |= result.collided
    corners = chassis_corners(sim)
    assert np.all(corners[:, 0] <= wall_x - thickness / 2 + 0.005), corners
    assert collided and "north" in touched
    assert sim.contacts.in_contact
    # it stays stopped against the wall: no creeping through
    x_before = sim.true_pose[0]
    for _ in range(50):
        sim.step(1.5, 0.0)
    assert sim.true_pose[0] <= x_before + 0.002


def test_obstacle_polygon_blocks_the_vehicle():
    box = [[5.0, -1.0], [6.0, -1.0], [6.0, 1.0], [5.0, 1.0]]
    sim = make_sim(world=bare_world(obstacles=[("machine_1", box)]))
    touched = set()
    for _ in range(100):
        touched |= sim.step(1.5, 0.0).contacts
    assert np.all(chassis_corners(sim)[:, 0] <= 5.0 + 0.005)
    assert "machine_1" in touched


def test_backing_away_ends_the_contact():
    world = bare_world(walls=[("w", [[4.0, -5.0], [4.0, 5.0]], 0.1)])
    sim = make_sim(world=world)
    for _ in range(60):
        sim.step(1.0, 0.0)
    assert sim.contacts.in_contact
    for _ in range(30):
        sim.step(-0.5, 0.0)
    assert not sim.contacts.in_contact


def test_concave_obstacle_collides_as_its_shape_not_its_hull():
    """An L-shaped machine: the vehicle drives into the notch, which the
    convex hull would have filled."""
    # L shape: x in [4, 8], y in [-3, 3] minus the notch x in [4, 7], y in [-1, 1]... as a U opening west
    u_shape = [[4.0, -3.0], [8.0, -3.0], [8.0, 3.0], [4.0, 3.0], [4.0, 1.5], [7.0, 1.5], [7.0, -1.5], [4.0, -1.5]]
    sim = make_sim(world=bare_world(obstacles=[("press", u_shape)]))
    for _ in range(100):
        sim.step(1.0, 0.0)
    front = chassis_corners(sim)[:, 0].max()
    assert 6.9 <= front <= 7.0 + 0.005  # stopped by the back of the notch, not at its mouth (x = 4)
