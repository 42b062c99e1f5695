"""The shipped maps' default routes: drivable, closed, and they see every target.

"Sees": some point on the route lies 1.5-8 m in front of the target, within
55° of its normal, with a clear line of sight. Checked here by brute force,
independently of :func:`agvsim.world.checks.route_sightings` (tested below
on a small map).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from agvsim.world.checks import route_sightings
from agvsim.world import load_map, map_from_dict, shipped_maps

SHIPPED = ["corridor", "plant_floor"]
CLEARANCE = 0.6  # m, for the 1.0 x 0.7 m AGV
STEP = 0.1  # m between route samples


def route_samples(m, name="default", step=STEP):
    stations = [s.position for s in m.route(name)]
    out = []
    for a, b in zip(stations[:-1], stations[1:]):
        n = max(1, math.ceil(np.linalg.norm(b - a) / step))
        out.extend(a + (b - a) * k / n for k in range(n + 1))
    return np.array(out)


def sees(m, target, p) -> bool:
    offset = p - target.position
    dist = float(np.linalg.norm(offset))
    if not 1.5 <= dist <= 8.0:
        return False
    angle = math.degrees(math.acos(np.clip(offset @ target.normal / dist, -1.0, 1.0)))
    return angle <= 55.0 and m.line_of_sight(target.position, p)


def test_both_maps_are_shipped():
    assert set(SHIPPED) <= set(shipped_maps())


@pytest.mark.parametrize("name", SHIPPED)
def test_default_route_sees_every_target(name):
    m = load_map(name)
    pts = route_samples(m)
    unseen = [t.id for t in m.targets if not any(sees(m, t, p) for p in pts)]
    assert unseen == []


@pytest.mark.parametrize("name", SHIPPED)
def test_every_route_leg_keeps_vehicle_clearance(name):
    m = load_map(name)
    for route in m.routes:
        pts = route_samples(m, route, step=0.05)
        clearance = np.array([m.clearance(x, y) for x, y in pts])
        assert clearance.min() >= CLEARANCE, (route, pts[np.argmin(clearance)])


@pytest.mark.parametrize("name", SHIPPED)
def test_default_route_is_a_loop_back_to_its_start(name):
    ids = load_map(name).routes["default"]
    assert ids[0] == ids[-1]


@pytest.mark.parametrize("name", SHIPPED)
def test_default_route_never_drives_a_leg_twice(name):
    # A path follower that projects its pose onto the route gets confused where the
    # route retraces itself, so the shipped loops go in one way and out another.
    ids = load_map(name).routes["default"]
    legs = [frozenset(leg) for leg in zip(ids[:-1], ids[1:])]
    assert len(set(legs)) == len(legs)


def test_plant_floor_default_route_length():
    length = load_map("plant_floor").route_length()
    assert 150.0 <= length <= 300.0  # a 1 km run is a few laps


# ------------------------------------------------------------ route_sightings on a small map

def hall(crate_y: float):
    """A 12 x 6 m hall, one target on the south wall at x = 6, a route along y = 4.5,
    and a crate at (6, crate_y)."""
    return map_from_dict({
        "walls": [
            {"id": "south", "points": [[0, 0], [12, 0]], "thickness": 0.2},
            {"id": "east", "points": [[12, 0], [12, 6]], "thickness": 0.2},
            {"id": "north", "points": [[12, 6], [0, 6]], "thickness": 0.2},
            {"id": "west", "points": [[0, 6], [0, 0]], "thickness": 0.2},
        ],
        "obstacles": [{"id": "crate", "kind": "pallet",
                       "box": {"center": [6, crate_y], "size": [6.0, 0.6]}, "height": 1}],
        "stations": [{"id": "A", "pose": [1, 4.5, 0]}, {"id": "B", "pose": [11, 4.5, 0]}],
        "routes": {"default": ["A", "B"]},
        "targets": [{"id": "T", "wall": "south", "at": 6, "side": "left", "height": 1,
                     "polarity": "positive"}],
    })


def test_route_sightings_sees_an_unobstructed_target():
    seen = route_sightings(hall(crate_y=5.5), "default")  # crate beyond the route
    assert seen["T"] == pytest.approx(4.4)  # straight ahead: 4.5 m minus half the wall


def test_route_sightings_misses_a_target_behind_a_crate():
    # A 6 m crate between target and route hides it from every point within 55°.
    assert route_sightings(hall(crate_y=2.0), "default") == {"T": None}
