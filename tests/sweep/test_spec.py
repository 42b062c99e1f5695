"""Sweep specs: a grid expands to every combination in axis order, a sample is seeded and
within its ranges, and every mistake is one line naming the file, the field, the value and
what was expected, before anything runs; the axis list feeds the CLI's help."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from agvsim.cli import build_parser
from agvsim.sweep.spec import AXES, BASE_FIELDS, SpecError, drive_fields, load_spec

EXAMPLE = Path(__file__).parents[2] / "examples" / "sweep_small.yaml"


def _spec(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    return path


def test_example_grid_expands_in_axis_order():
    spec = load_spec(EXAMPLE)
    assert spec.axes == ("odometry", "targets_removed")
    assert len(spec.points) == 6 and spec.seeds == (0, 1)
    assert [tuple(p.values()) for p in spec.points[:3]] == [("typical", 0.0), ("typical", 0.33), ("typical", 0.5)]
    settings = spec.settings(4)
    assert (settings.odometry, settings.targets_removed, settings.distance) == ("worn", 0.33, 100.0)
    assert settings.observations == "geometric"


def test_sample_is_seeded_and_within_its_ranges(tmp_path):
    text = """
base: {distance: 50, observations: geometric}
sample:
  points: 40
  seed: 3
  axes:
    camera_rate: {low: 1.0, high: 8.0}
    odometry: [typical, worn]
seeds: 1
"""
    a, b = load_spec(_spec(tmp_path, text)), load_spec(_spec(tmp_path, text))
    assert a.points == b.points
    rates = [p["camera_rate"] for p in a.points]
    assert all(1.0 <= r < 8.0 for r in rates) and len(set(rates)) == 40
    assert {p["odometry"] for p in a.points} == {"typical", "worn"}
    c = load_spec(_spec(tmp_path, text.replace("seed: 3", "seed: 4")))
    assert c.points != a.points


def test_map_axis_takes_files_relative_to_the_spec(tmp_path):
    maps = Path(__file__).parents[2] / "maps"
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "c.yaml").write_text((maps / "corridor.yaml").read_text())
    spec = load_spec(_spec(tmp_path, "base: {distance: 20}\ngrid: {map: [plant_floor, m/c.yaml]}\nseeds: 1\n"))
    assert spec.settings(1).map == str((tmp_path / "m" / "c.yaml").resolve())
    assert spec.settings(1).world().name == spec.settings(1).world().name  # loads


@pytest.mark.parametrize("text, expected", [
    ("grid: {odometry: [typical, wron]}\nseeds: 1\n", "point 1 (odometry=wron): odometry must be one of"),
    ("grid: {odometry: [typical]}\nseeds: 0\n", "seeds: 0; expected a whole number >= 1"),
    ("grid: {odometry: [typical]}\n", "seeds: missing"),
    ("grid: {odometry: [typical]}\nsample: {points: 2, seed: 0, axes: {latency: [0.1]}}\nseeds: 1\n",
     "expected exactly one of grid"),
    ("grid: {speed: [1, 2]}\nseeds: 1\n", "grid.speed: unknown field; expected one of map, odometry"),
    ("grid: {camera_rate: 4}\nseeds: 1\n", "grid.camera_rate: 4; expected a non-empty list"),
    ("grid: {camera_rate: [4, fast]}\nseeds: 1\n", "grid.camera_rate[1]: 'fast' is not a number"),
    ("grid: {camera_rate: [4, 4]}\nseeds: 1\n", "repeats a value"),
    ("base: {odometry: worn}\ngrid: {odometry: [typical]}\nseeds: 1\n", "base.odometry: also an axis"),
    ("base: {route: nowhere}\ngrid: {odometry: [typical]}\nseeds: 1\n", "base.route (map 'plant_floor') must be one of"),
    ("base: {map: no_such_map}\ngrid: {odometry: [typical]}\nseeds: 1\n", "base.map:"),
    ("grid: {lens: [16, 17]}\nseeds: 1\n", "point 1 (lens=17.0): lens must be one of"),
    ("grid: {camera_mount: [map, sideways]}\nseeds: 1\n", "grid.camera_mount[1]: 'sideways': expected one of map, forward"),
    ("grid: {targets_removed: [0.5, 1.0]}\nseeds: 1\n", "point 1 (targets_removed=1.0): targets_removed must be"),
    ("base: {lighting: 0}\ngrid: {odometry: [typical]}\nseeds: 1\n", "base.lighting: lighting must be a finite number > 0"),
    ("sample: {points: 3, seed: 1, axes: {latency: {low: 0.5, high: 0.1}}}\nseeds: 1\n", "low 0.5 >= high 0.1"),
    ("sample: {points: 3, axes: {latency: [0.1]}}\nseeds: 1\n", "sample.seed: missing"),
    ("grid: [odometry]\nseeds: 1\n", "grid: ['odometry']; expected a mapping"),
    ("grid: {odometry: [typical\nseeds: 1\n", "not valid YAML"),
])
def test_mistakes_are_one_line_naming_file_field_value(tmp_path, text, expected):
    path = _spec(tmp_path, text)
    with pytest.raises(SpecError) as info:
        load_spec(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(path)), message
    assert expected in message, message


def test_missing_file_and_cli_error_are_one_line(tmp_path):
    missing = tmp_path / "none.yaml"
    with pytest.raises(SpecError, match="cannot read the spec"):
        load_spec(missing)
    bad = _spec(tmp_path, "grid: {odometry: [typical, wron]}\nseeds: 1\n")
    p = subprocess.run([sys.executable, "-m", "agvsim", "sweep", str(bad), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.strip().count("\n") == 0 and "did you mean 'worn'" in p.stderr, p.stderr
    assert not (tmp_path / "o").exists()  # refused before anything was written


def test_axes_are_defined_once_and_feed_the_cli():
    assert set(AXES) <= set(BASE_FIELDS) and set(BASE_FIELDS) == set(drive_fields())
    sweep = build_parser()._subparsers._group_actions[0].choices["sweep"]
    assert all(f"{a.name}: {a.help}" in sweep.description for a in AXES.values())
