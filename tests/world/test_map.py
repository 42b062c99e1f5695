"""Loading maps and the data model: shipped maps, derived target poses, lookups."""
from __future__ import annotations

import dataclasses
import math
import textwrap

import numpy as np
import pytest

import agvsim
from agvsim.world import (Map, MapError, MapTarget, Wall, load_map, map_from_dict,
                              maps_dir, shipped_maps)
from localizer.model.target import TargetSpec

#: A 10 x 6 m room whose south wall is a polyline: east along y = 0, then north-east.
ROOM = """
walls:
  - {id: south, points: [[0, 0], [6, 0], [10, 4]], thickness: 0.2}
  - {id: east,  points: [[10, 4], [10, 6]], thickness: 0.2}
  - {id: north, points: [[10, 6], [0, 6]], thickness: 0.4, height: 4.0, surface: brick}
  - {id: west,  points: [[0, 6], [0, 0]], thickness: 0.2}
targets:
  - {id: L, wall: south, at: 3.0, side: left, height: 1.0, polarity: positive}
  - {id: D, wall: south, at: 8.0, side: left, height: 1.5, polarity: negative,
     size: {bar_width: 0.1}}
  - {id: N, wall: north, at: 4.0, side: left, height: 1.2, polarity: negative}
"""


def load_text(tmp_path, text, name="room.yaml") -> Map:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return load_map(path)


# ------------------------------------------------------------ shipped maps

@pytest.mark.parametrize("name", ["corridor", "plant_floor"])
def test_every_shipped_map_loads(name):
    m = load_map(name)
    assert m.name == name and m.source == maps_dir() / f"{name}.yaml"
    assert m.walls and m.targets and "default" in m.routes


def test_all_listed_maps_load():
    names = shipped_maps()
    assert {"corridor", "plant_floor"} <= set(names)
    for name in names:
        assert isinstance(load_map(name), Map)


def test_corridor_facts():
    m = load_map("corridor")
    width, depth = m.size
    assert 38.0 <= width <= 42.0 and 2.5 <= depth <= 4.0
    assert len(m.targets) >= 8
    facing = {tuple(np.round(t.normal).astype(int)) for t in m.targets}
    assert facing == {(0, 1), (0, -1), (1, 0), (-1, 0)}  # both sides and both end walls
    assert {t.polarity for t in m.targets} == {"positive", "negative"}
    surfaces = {w.surface for w in m.walls}
    assert {"door", "poster"} <= surfaces


def test_plant_floor_facts():
    m = load_map("plant_floor")
    width, depth = m.size
    assert 58.0 <= width <= 62.0 and 38.0 <= depth <= 42.0
    assert len(m.stations) >= 6 and len(m.targets) >= 25
    assert {t.polarity for t in m.targets} == {"positive", "negative"}
    assert all(0.8 <= t.height <= 1.8 for t in m.targets)
    kinds = {o.kind for o in m.obstacles}
    assert {"machine", "rack", "pillar", "pallet"} <= kinds
    levels = [z.level for z in m.lighting_zones]
    assert min(levels) <= 0.35 and max(levels) >= 2.5
    # the dim zone and the bright zone are where the map says
    assert m.lighting_at(5.0, 38.0) == pytest.approx(0.3)
    assert m.lighting_at(58.0, 17.0) == pytest.approx(2.8)
    assert m.lighting_at(35.0, 20.0) == pytest.approx(1.0)


def test_agvsim_exports_load_map():
    assert agvsim.load_map is load_map and agvsim.MapError is MapError
    assert agvsim.Map is Map


# ------------------------------------------------------------ finding map files

def test_load_by_path_string_and_pathlike(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text(textwrap.dedent(ROOM), encoding="utf-8")
    assert load_map(str(path)).name == "mine"  # no `name:` -> the file stem
    assert load_map(path).source == path


def test_shipped_file_name_works_from_any_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert load_map("corridor.yaml").source == maps_dir() / "corridor.yaml"


def test_maps_dir_override(tmp_path, monkeypatch):
    (tmp_path / "tiny.yaml").write_text(textwrap.dedent(ROOM), encoding="utf-8")
    monkeypatch.setenv("AGVSIM_MAPS_DIR", str(tmp_path))
    assert maps_dir() == tmp_path
    assert shipped_maps() == ["tiny"]
    assert len(load_map("tiny").targets) == 3


def test_unknown_map_name_lists_the_shipped_ones():
    with pytest.raises(FileNotFoundError, match="corridor"):
        load_map("no_such_map")
    with pytest.raises(FileNotFoundError):
        load_map("missing/dir/map.yaml")


# ------------------------------------------------------------ derived target poses

def test_target_on_a_wall_along_x_facing_left(tmp_path):
    t = load_text(tmp_path, ROOM).target("L")
    # wall along +x at y = 0, thickness 0.2: "left" faces +y, face 0.1 m above the centreline
    np.testing.assert_allclose(t.normal, [0.0, 1.0])
    np.testing.assert_allclose(t.position, [3.0, 0.1])
    assert t.yaw == pytest.approx(math.pi / 2)
    np.testing.assert_allclose(t.center_3d, [3.0, 0.1, 1.0])
    assert t.spec == TargetSpec()


def test_right_side_faces_the_other_way(tmp_path):
    text = ROOM.replace("{id: N, wall: north, at: 4.0, side: left",
                        "{id: N, wall: north, at: 4.0, side: right")
    text = text.replace("[10, 6], [0, 6]]", "[0, 6], [10, 6]]")  # north wall drawn west -> east
    t = load_text(tmp_path, text).target("N")
    np.testing.assert_allclose(t.normal, [0.0, -1.0])
    np.testing.assert_allclose(t.position, [4.0, 5.8])  # thickness 0.4 -> 0.2 m below y = 6
    assert t.yaw == pytest.approx(-math.pi / 2)


def test_target_on_the_second_piece_of_a_polyline(tmp_path):
    m = load_text(tmp_path, ROOM)
    t = m.target("D")
    # 8 m along: 2 m past the corner at (6, 0), on the piece heading north-east
    d = np.array([1.0, 1.0]) / math.sqrt(2.0)
    centre = np.array([6.0, 0.0]) + 2.0 * d
    normal = np.array([-d[1], d[0]])
    np.testing.assert_allclose(t.normal, normal, atol=1e-12)
    np.testing.assert_allclose(t.position, centre + 0.1 * normal, atol=1e-12)
    assert t.yaw == pytest.approx(3 * math.pi / 4)
    assert t.spec == TargetSpec.from_bar_width(0.1)


def test_target_fields():
    names = [f.name for f in dataclasses.fields(MapTarget)]
    assert names == ["id", "wall", "at", "side", "height", "polarity", "spec", "position", "normal"]


# ------------------------------------------------------------ walls

def test_wall_length_segments_and_point_at():
    w = Wall(id="w", points=np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0]]), thickness=0.2)
    assert w.length == pytest.approx(7.0) and w.height == 3.0
    assert w.segments().shape == (2, 2, 2)
    p, t = w.point_at(1.5)
    np.testing.assert_allclose(p, [1.5, 0.0]) and np.testing.assert_allclose(t, [1.0, 0.0])
    p, t = w.point_at(5.0)
    np.testing.assert_allclose(p, [3.0, 2.0]) and np.testing.assert_allclose(t, [0.0, 1.0])
    p, t = w.point_at(7.0)
    np.testing.assert_allclose(p, [3.0, 4.0]) and np.testing.assert_allclose(t, [0.0, 1.0])
    with pytest.raises(ValueError):
        w.point_at(7.5)


# ------------------------------------------------------------ the Map object

def test_map_is_immutable(tmp_path):
    m = load_text(tmp_path, ROOM)
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.name = "other"
    with pytest.raises(ValueError):
        m.walls[0].points[0, 0] = 5.0
    with pytest.raises(ValueError):
        m.target("L").position[0] = 5.0
    with pytest.raises(TypeError):
        m.routes["new"] = ("a", "b")


def test_defaults_and_bounds(tmp_path):
    m = load_text(tmp_path, ROOM)
    north = m.wall("north")
    assert (north.height, north.surface, north.thickness) == (4.0, "brick", 0.4)
    assert m.wall("south").surface == "painted" and m.wall("south").height == 3.0
    # walls are thickened by thickness / 2 all round (round ends): the 0.4 m north wall
    # reaches 0.2 m past its end points
    assert m.bounds == pytest.approx((-0.2, -0.1, 10.2, 6.2))
    assert m.lighting_default == 1.0 and m.lighting_zones == ()
    assert m.description == "" and m.stations == () and dict(m.routes) == {}


def test_lookups_and_routes():
    m = load_map("plant_floor")
    assert m.station("charger").pose == pytest.approx((4.0, 20.0, -math.pi / 2), abs=1e-5)
    route = m.route()
    assert route[0].id == "charger" and route[-1].id == "charger"
    assert m.route("default") == route
    assert m.obstacle("M1").kind == "machine"
    for lookup, key in [(m.station, "nope"), (m.target, "nope"), (m.wall, "nope"), (m.route, "nope")]:
        with pytest.raises(KeyError):
            lookup(key)


def test_lighting_last_matching_zone_wins():
    data = {
        "walls": [{"id": "w", "points": [[0, -1], [10, -1]], "thickness": 0.2}],
        "lighting": {"default": 0.8, "zones": [
            {"id": "big", "box": {"center": [5, 5], "size": [10, 10]}, "level": 2.0},
            {"id": "small", "polygon": [[4, 4], [6, 4], [5, 6]], "level": 0.25},
        ]},
    }
    m = map_from_dict(data)
    assert m.lighting_at(5.0, 4.5) == 0.25
    assert m.lighting_at(1.0, 1.0) == 2.0
    assert m.lighting_at(-5.0, 1.0) == 0.8


def test_obstacle_polygons_are_stored_counter_clockwise():
    data = {
        "walls": [{"id": "w", "points": [[0, -1], [10, -1]], "thickness": 0.2}],
        "obstacles": [
            {"id": "cw", "kind": "rack", "polygon": [[0, 0], [0, 1], [2, 1], [2, 0]], "height": 2},
            {"id": "rotated", "kind": "rack", "box": {"center": [5, 5], "size": [2, 1], "yaw": 0.5},
             "height": 2},
        ],
    }
    m = map_from_dict(data)
    for o in m.obstacles:
        x, y = o.polygon[:, 0], o.polygon[:, 1]
        assert np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0
    np.testing.assert_allclose(m.obstacle("rotated").polygon.mean(axis=0), [5.0, 5.0])


def test_map_from_dict_errors_use_the_given_label():
    with pytest.raises(MapError, match=r"^<map>: walls: empty map"):
        map_from_dict({"walls": []})
    with pytest.raises(MapError, match=r"^mine: walls"):
        map_from_dict({}, source="mine")


def test_clearance_and_line_of_sight():
    m = load_map("corridor")
    assert m.clearance(15.0, 0.0) == pytest.approx(1.5)  # centreline: 1.5 m to each wall face
    assert m.clearance(9.5, 0.0) == pytest.approx(1.5 - 0.35)  # the 0.35 m deep fountain
    assert m.clearance(15.0, 1.6) < 0  # inside the north wall
    assert m.line_of_sight((2.0, 0.0), (38.0, 0.0))
    assert not m.line_of_sight((2.0, 0.0), (2.0, 3.0))  # through the north wall
    assert not m.line_of_sight((19.5, 0.5), (19.5, 1.45))  # into the bench
    assert m.line_of_sight((19.5, 0.5), (19.5, 1.1))  # stops short of it


def test_summary_counts():
    s = load_map("plant_floor").summary()
    assert s["targets"]["total"] == s["targets"]["positive"] + s["targets"]["negative"]
    assert s["routes"]["default"]["loop"] is True
    assert len(s["bounds"]) == 4


def test_shipped_descriptions_state_the_maps_own_counts():
    import re

    from agvsim.world import shipped_maps

    for name in shipped_maps():
        m = load_map(name)
        for n in re.findall(r"(\d+) (?:wall )?targets", m.description):
            assert int(n) == len(m.targets), (name, m.description)
        for n in re.findall(r"(\d+) m ring route", m.description):
            assert float(n) == pytest.approx(m.route_length("default"), abs=0.5), name


def test_a_loop_route_counts_its_start_once_as_the_follower_does():
    from agvsim.loop.mission import MissionConfig, run_mission

    m = load_map("corridor")
    ids = m.routes["default"]
    assert ids[0] == ids[-1]  # a loop: the list ends at its start again
    routes = m.summary()["routes"]
    assert routes["default"]["stations"] == len(ids) - 1 == len(set(ids))
    assert routes["one_way"]["stations"] == len(m.routes["one_way"])
    # one lap passes every station of the loop once: the demo's and drift's stations_reached
    log = run_mission(m, None, np.random.default_rng(0), MissionConfig(vision=False, steer_on="truth"))
    assert log.completed and len(log.arrivals) == routes["default"]["stations"]
