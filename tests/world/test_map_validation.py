"""Every class of bad map gives a MapError naming the file, the field, the value
and what was expected. Each test breaks one thing in a small valid room."""
from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from agvsim.world import MapError, load_map


def room() -> dict[str, Any]:
    """A valid 10 x 8 m room, walls drawn counter-clockwise (floor on their left).

    Free floor x 0.1..9.9, y 0.1..7.9; a 1 m crate at (5, 4); stations at the
    corners of a 6 x 4 m loop; two targets facing each other across the room.
    """
    return copy.deepcopy({
        "name": "room",
        "description": "test room",
        "walls": [
            {"id": "south", "points": [[0, 0], [10, 0]], "thickness": 0.2},
            {"id": "east", "points": [[10, 0], [10, 8]], "thickness": 0.2},
            {"id": "north", "points": [[10, 8], [0, 8]], "thickness": 0.2},
            {"id": "west", "points": [[0, 8], [0, 0]], "thickness": 0.2},
        ],
        "obstacles": [
            {"id": "crate", "kind": "pallet", "box": {"center": [5, 4], "size": [1, 1]}, "height": 1.0},
        ],
        "stations": [
            {"id": "A", "pose": [2, 2, 0]},
            {"id": "B", "pose": [8, 2, 1.57]},
            {"id": "C", "pose": [8, 6, 3.14]},
            {"id": "D", "pose": [2, 6, -1.57]},
        ],
        "routes": {"default": ["A", "B", "C", "D", "A"]},
        "lighting": {"default": 1.0, "zones": [
            {"id": "dim", "box": {"center": [2, 6], "size": [2, 2]}, "level": 0.3},
        ]},
        "targets": [
            {"id": "T1", "wall": "south", "at": 3.0, "side": "left", "height": 1.0, "polarity": "positive"},
            {"id": "T2", "wall": "north", "at": 7.0, "side": "left", "height": 1.2, "polarity": "negative"},
        ],
    })


def write(tmp_path: Path, data: Any) -> Path:
    path = tmp_path / "room.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def error_for(tmp_path: Path, data: Any) -> MapError:
    """Load ``data`` as a map file and return the MapError it must raise."""
    path = write(tmp_path, data)
    with pytest.raises(MapError) as info:
        load_map(path)
    err = info.value
    assert err.file == str(path)
    assert str(err).startswith(f"{path}: ")
    return err


def error_for_text(tmp_path: Path, text: str) -> MapError:
    path = tmp_path / "room.yaml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(MapError) as info:
        load_map(path)
    return info.value


def test_the_room_itself_is_valid(tmp_path):
    m = load_map(write(tmp_path, room()))
    assert [t.id for t in m.targets] == ["T1", "T2"]


def test_message_format_names_file_field_value_and_expectation(tmp_path):
    data = room()
    data["targets"][1]["height"] = "high"
    err = error_for(tmp_path, data)
    assert err.path == "targets[1].height"
    assert err.value == "high"
    assert str(err) == (f"{tmp_path / 'room.yaml'}: targets[1].height: wrong type "
                        "(got 'high'; expected a positive number, m)")


# ------------------------------------------------------------ keys

def test_missing_key(tmp_path):
    data = room()
    del data["targets"][0]["polarity"]
    err = error_for(tmp_path, data)
    assert err.path == "targets[0].polarity"
    assert "missing" in err.problem and "'positive' or 'negative'" in err.expected


@pytest.mark.parametrize("where, typo, suggestion, path", [
    (lambda d: d["targets"][0], "heigth", "height", "targets[0].heigth"),
    (lambda d: d["walls"][2], "thicknes", "thickness", "walls[2].thicknes"),
    (lambda d: d["obstacles"][0]["box"], "centre", "center", "obstacles[0].box.centre"),
    (lambda d: d, "wals", "walls", "wals"),
    (lambda d: d["lighting"], "zone", "zones", "lighting.zone"),
])
def test_unknown_key_is_an_error_with_a_suggestion(tmp_path, where, typo, suggestion, path):
    data = room()
    where(data)[typo] = 1.0
    err = error_for(tmp_path, data)
    assert err.path == path
    assert f"did you mean {suggestion!r}" in str(err)


def test_duplicate_yaml_key(tmp_path):
    text = yaml.safe_dump(room(), sort_keys=False).replace("name: room\n", "name: room\nname: other\n")
    err = error_for_text(tmp_path, text)
    assert "duplicate key" in str(err) and "line 2" in str(err)


def test_yaml_syntax_error_names_the_line(tmp_path):
    err = error_for_text(tmp_path, "walls:\n  - {id: a, points: [[0, 0], [1, 0]\n")
    assert "invalid YAML" in str(err) and "line" in err.path


# ------------------------------------------------------------ values

@pytest.mark.parametrize("mutate, path", [
    (lambda d: d["walls"][0].update(thickness="thick"), "walls[0].thickness"),
    (lambda d: d["walls"][0].update(thickness=True), "walls[0].thickness"),
    (lambda d: d["stations"][0].update(pose=[1, 2]), "stations[0].pose"),
    (lambda d: d["walls"][1].update(points=[[10, 0]]), "walls[1].points"),
    (lambda d: d["targets"][0].update(side="up"), "targets[0].side"),
    (lambda d: d["targets"][0].update(polarity="positve"), "targets[0].polarity"),
    (lambda d: d["targets"][0].update(id=7), "targets[0].id"),
    (lambda d: d.update(targets={"T1": {}}), "targets"),
])
def test_wrong_types_and_shapes(tmp_path, mutate, path):
    data = room()
    mutate(data)
    assert error_for(tmp_path, data).path == path


def test_a_near_miss_choice_gets_a_suggestion(tmp_path):
    data = room()
    data["targets"][0]["polarity"] = "positve"
    assert "did you mean 'positive'" in str(error_for(tmp_path, data))


@pytest.mark.parametrize("literal", [".nan", ".inf", "-.inf"])
def test_non_finite_numbers(tmp_path, literal):
    text = yaml.safe_dump(room(), sort_keys=False).replace("height: 1.2", f"height: {literal}")
    err = error_for_text(tmp_path, text)
    assert err.path == "targets[1].height" and "finite" in err.problem


def test_exponent_without_a_dot_is_a_number(tmp_path):
    text = yaml.safe_dump(room(), sort_keys=False).replace("thickness: 0.2", "thickness: 2e-1", 1)
    path = tmp_path / "room.yaml"
    path.write_text(text, encoding="utf-8")
    assert load_map(path).walls[0].thickness == pytest.approx(0.2)


@pytest.mark.parametrize("mutate, path", [
    (lambda d: d["walls"][0].update(thickness=0), "walls[0].thickness"),
    (lambda d: d["walls"][0].update(height=-3), "walls[0].height"),
    (lambda d: d["obstacles"][0]["box"].update(size=[1, -1]), "obstacles[0].box.size[1]"),
    (lambda d: d["obstacles"][0].update(height=0), "obstacles[0].height"),
    (lambda d: d["targets"][0].update(size={"bar_width": 0}), "targets[0].size.bar_width"),
    (lambda d: d["targets"][0].update(height=-1), "targets[0].height"),
    (lambda d: d["targets"][0].update(at=-0.5), "targets[0].at"),
])
def test_negative_or_zero_sizes(tmp_path, mutate, path):
    data = room()
    mutate(data)
    assert error_for(tmp_path, data).path == path


@pytest.mark.parametrize("level", [0, -0.5])
def test_lighting_levels_must_be_positive(tmp_path, level):
    data = room()
    data["lighting"]["zones"][0]["level"] = level
    assert error_for(tmp_path, data).path == "lighting.zones[0].level"
    data = room()
    data["lighting"]["default"] = level
    assert error_for(tmp_path, data).path == "lighting.default"


def test_repeated_wall_point(tmp_path):
    data = room()
    data["walls"][0]["points"] = [[0, 0], [0, 0], [10, 0]]
    assert error_for(tmp_path, data).path == "walls[0].points[1]"


# ------------------------------------------------------------ polygons

def test_polygon_with_too_few_vertices(tmp_path):
    data = room()
    data["obstacles"][0] = {"id": "crate", "kind": "pallet", "polygon": [[4, 4], [5, 4]], "height": 1}
    err = error_for(tmp_path, data)
    assert err.path == "obstacles[0].polygon" and "at least 3" in err.expected


def test_self_intersecting_polygon(tmp_path):
    data = room()
    bowtie = [[4, 3.5], [6, 4.5], [6, 3.5], [4, 4.5]]
    data["obstacles"][0] = {"id": "crate", "kind": "pallet", "polygon": bowtie, "height": 1}
    err = error_for(tmp_path, data)
    assert err.path == "obstacles[0].polygon" and "self-intersecting" in err.problem


def test_self_intersecting_lighting_zone(tmp_path):
    data = room()
    data["lighting"]["zones"][0] = {"id": "dim", "polygon": [[1, 1], [3, 3], [3, 1], [1, 3]], "level": 0.5}
    assert "self-intersecting" in error_for(tmp_path, data).problem


def test_shape_needs_exactly_one_of_box_or_polygon(tmp_path):
    data = room()
    data["obstacles"][0]["polygon"] = [[4, 3.5], [6, 3.5], [6, 4.5]]
    assert "exactly one" in error_for(tmp_path, data).problem
    data = room()
    del data["obstacles"][0]["box"]
    assert error_for(tmp_path, data).path == "obstacles[0]"


# ------------------------------------------------------------ empty and duplicate

def test_empty_map(tmp_path):
    err = error_for_text(tmp_path, "")
    assert "empty map" in str(err)
    data = room()
    data["walls"] = []
    err = error_for(tmp_path, data)
    assert err.path == "walls" and "empty map" in err.problem
    data = room()
    del data["walls"]
    assert error_for(tmp_path, data).path == "walls"


def test_duplicate_ids_within_a_section(tmp_path):
    data = room()
    data["targets"][1]["id"] = "T1"
    err = error_for(tmp_path, data)
    assert err.path == "targets[1].id" and "targets[0]" in err.problem


def test_duplicate_ids_across_sections(tmp_path):
    data = room()
    data["stations"][2]["id"] = "crate"
    data["routes"]["default"] = ["A", "B", "crate", "D", "A"]
    err = error_for(tmp_path, data)
    assert err.path == "stations[2].id" and "obstacles[0]" in err.problem


# ------------------------------------------------------------ targets

def test_target_on_an_unknown_wall(tmp_path):
    data = room()
    data["targets"][0]["wall"] = "sooth"
    err = error_for(tmp_path, data)
    assert err.path == "targets[0].wall"
    assert "unknown wall" in err.problem and "did you mean 'south'" in err.problem


@pytest.mark.parametrize("at", [0.1, 9.9, 12.0])
def test_target_not_on_any_wall(tmp_path, at):
    data = room()
    data["targets"][0]["at"] = at  # the face is 0.3 m wide, the wall 10 m long
    err = error_for(tmp_path, data)
    assert err.path == "targets[0].at" and "target not on any wall" in err.problem


def test_target_straddling_a_wall_corner(tmp_path):
    data = room()
    data["walls"][0]["points"] = [[0, 0], [5, 0], [5, -1], [10, -1]]
    data["walls"][1]["points"] = [[10, -1], [10, 8]]
    data["targets"][0]["at"] = 5.05  # 5 m along: the first corner
    err = error_for(tmp_path, data)
    assert err.path == "targets[0].at" and "corner" in err.problem


def test_target_facing_into_an_obstacle(tmp_path):
    data = room()
    data["obstacles"].append({"id": "pillar", "kind": "pillar",
                              "box": {"center": [3, 0.5], "size": [0.6, 0.4]}, "height": 8})
    err = error_for(tmp_path, data)
    assert err.path == "targets[0].side" and "'pillar'" in err.problem


def test_target_facing_into_a_wall(tmp_path):
    data = room()
    data["walls"].append({"id": "partition", "points": [[2, 0.4], [4, 0.4]], "thickness": 0.1})
    err = error_for(tmp_path, data)
    assert err.path == "targets[0].side" and "'partition'" in err.problem


def test_target_facing_a_wall_further_than_half_a_metre_is_fine(tmp_path):
    data = room()
    data["walls"].append({"id": "partition", "points": [[2, 0.8], [4, 0.8]], "thickness": 0.1})
    assert load_map(write(tmp_path, data)).target("T1").normal.tolist() == [0.0, 1.0]


def test_target_facing_out_of_the_floor(tmp_path):
    data = room()
    data["targets"][0]["side"] = "right"
    err = error_for(tmp_path, data)
    assert err.path == "targets[0].side" and "out of the floor" in err.problem


def test_target_taller_than_its_wall(tmp_path):
    data = room()
    data["walls"][0]["height"] = 1.0
    err = error_for(tmp_path, data)
    assert err.path == "targets[0].height" and "taller than its wall" in err.problem


def test_big_target_taller_than_its_wall(tmp_path):
    data = room()
    data["targets"][0].update(height=2.5, size={"bar_width": 0.5})  # 1.5 m tall face
    assert "taller than its wall" in error_for(tmp_path, data).problem


def test_target_reaching_below_the_floor(tmp_path):
    data = room()
    data["targets"][0]["height"] = 0.05
    assert "below the floor" in error_for(tmp_path, data).problem


def test_overlapping_targets(tmp_path):
    data = room()
    data["targets"].append({"id": "T3", "wall": "south", "at": 3.2, "side": "left",
                            "height": 1.05, "polarity": "negative"})
    err = error_for(tmp_path, data)
    assert err.path == "targets[2].at" and "overlaps" in err.problem


def test_targets_one_above_the_other_do_not_overlap(tmp_path):
    data = room()
    data["targets"].append({"id": "T3", "wall": "south", "at": 3.0, "side": "left",
                            "height": 1.5, "polarity": "negative"})
    assert len(load_map(write(tmp_path, data)).targets) == 3


# ------------------------------------------------------------ stations and routes

def test_overlapping_stations(tmp_path):
    data = room()
    data["stations"].append({"id": "E", "pose": [2.6, 2.5, 0]})
    err = error_for(tmp_path, data)
    assert err.path == "stations[4].pose" and "overlapping stations" in err.problem


@pytest.mark.parametrize("xy, word", [([5, 4], "inside 'crate'"), ([5.2, 3.1], "0.400 m from 'crate'"),
                                      ([0.5, 5], "from 'west'"), ([0.05, 5], "inside 'west'")])
def test_station_inside_or_too_close_to_a_solid(tmp_path, xy, word):
    data = room()
    data["stations"].append({"id": "E", "pose": [*xy, 0]})
    err = error_for(tmp_path, data)
    assert err.path == "stations[4].pose" and word in err.problem


def test_route_naming_an_unknown_station(tmp_path):
    data = room()
    data["routes"]["default"][2] = "c"
    err = error_for(tmp_path, data)
    assert err.path == "routes.default[2]" and "unknown station" in err.problem


def test_route_with_fewer_than_two_stations(tmp_path):
    data = room()
    data["routes"]["short"] = ["A"]
    assert error_for(tmp_path, data).path == "routes.short"


def test_route_repeating_a_station_back_to_back(tmp_path):
    data = room()
    data["routes"]["default"] = ["A", "B", "B", "C"]
    assert error_for(tmp_path, data).path == "routes.default[2]"


def test_route_leg_too_close_to_an_obstacle(tmp_path):
    data = room()
    data["routes"]["default"] = ["A", "C"]  # the diagonal runs through the crate
    err = error_for(tmp_path, data)
    assert err.path == "routes.default[1]" and "'crate'" in err.problem


def test_route_leg_grazing_a_wall(tmp_path):
    data = room()
    data["stations"].append({"id": "E", "pose": [0.8, 4.0, 0]})  # 0.7 m from west: ok
    data["stations"].append({"id": "F", "pose": [0.8, 7.0, 0]})
    data["walls"].append({"id": "stub", "points": [[0.1, 5.5], [0.35, 5.5]], "thickness": 0.2})
    data["routes"]["west_side"] = ["E", "F"]  # passes 0.35 m from the stub's end
    err = error_for(tmp_path, data)
    assert err.path == "routes.west_side[1]" and "'stub'" in err.problem


# ------------------------------------------------------------ defaults block

def test_defaults_fill_in_and_are_checked_where_written(tmp_path):
    data = room()
    for wall in data["walls"]:
        del wall["thickness"]
    data["defaults"] = {"wall": {"thickness": 0.25, "surface": "brick"}}
    m = load_map(write(tmp_path, data))
    assert {w.thickness for w in m.walls} == {0.25} and {w.surface for w in m.walls} == {"brick"}
    data["defaults"]["wall"]["thickness"] = -1
    assert error_for(tmp_path, data).path == "defaults.wall.thickness"
    data["defaults"] = {"wall": {"points": [[0, 0], [1, 0]]}}
    assert error_for(tmp_path, data).path == "defaults.wall.points"


# ---------------------------------------------------------------- camera_mount

def _with_mount(tmp_path, mount_yaml: str):
    import yaml

    from agvsim.world import maps_dir

    data = yaml.safe_load((maps_dir() / "corridor.yaml").read_text())
    data.pop("camera_mount", None)
    path = tmp_path / "m.yaml"
    text = yaml.safe_dump(data)
    if mount_yaml:
        text += "camera_mount: " + mount_yaml + "\n"
    path.write_text(text)
    return path


def test_camera_mount_is_read_and_defaults_to_forward_looking(tmp_path):
    from localizer.model.mount import CameraMount

    m = load_map(_with_mount(tmp_path, "{forward: 0.1, lateral: -0.2, height: 1.0, yaw: 0.5}"))
    assert m.camera_mount == CameraMount(forward=0.1, lateral=-0.2, height=1.0, yaw=0.5)
    assert load_map(_with_mount(tmp_path, "")).camera_mount == CameraMount()


@pytest.mark.parametrize("text, field, what", [
    ("{forward: 0.1, lateral: 0, height: 1.0}", "camera_mount.yaw", "missing required key"),
    ("{forward: 0.1, lateral: 0, height: -1.0, yaw: 0}", "camera_mount.height", "must be positive"),
    ("{forward: 0.1, lateral: 0, height: 1.0, yaw: 0, heigth: 2}", "camera_mount.heigth", "unknown key"),
    ("[0.4, 0, 1.2, 0]", "camera_mount", "wrong type"),
])
def test_bad_camera_mount_names_the_field(tmp_path, text, field, what):
    with pytest.raises(MapError) as err:
        load_map(_with_mount(tmp_path, text))
    assert field in str(err.value) and what in str(err.value)
