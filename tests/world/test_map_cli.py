"""``agvsim map list`` and ``agvsim map check``."""
from __future__ import annotations

import argparse
import json

import pytest

from agvsim.commands import map as map_command


def run(argv):
    """Parse and run ``agvsim map ...`` with only this command registered."""
    parser = argparse.ArgumentParser(prog="agvsim")
    sub = parser.add_subparsers(dest="command", required=True)
    map_command.register(sub)
    args = parser.parse_args(["map", *argv])
    return args.func(args)


def test_list(capsys):
    assert run(["list"]) == 0
    out = capsys.readouterr().out
    lines = {line.split()[0]: line for line in out.splitlines()}
    assert "targets" in lines["corridor"] and "plant_floor" in lines


def test_list_json(capsys):
    assert run(["list", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    names = {m["name"]: m for m in data["maps"]}
    assert names["plant_floor"]["ok"] and names["plant_floor"]["targets"] >= 25


def test_check_human(capsys):
    assert run(["check", "corridor"]) == 0
    out = capsys.readouterr().out
    assert "corridor: OK" in out and "positive" in out and "sees 12 of 12 targets" in out


def test_check_json_is_one_object(capsys):
    assert run(["check", "plant_floor", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)  # fails unless stdout is exactly one JSON document
    assert data["ok"] is True
    assert data["targets"]["positive"] + data["targets"]["negative"] == data["targets"]["total"]
    assert data["stations"] >= 6 and len(data["bounds"]) == 4
    assert data["default_route_sightings"]["unseen"] == []


def test_check_bad_map_exits_2_with_the_error(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("walls:\n  - {id: w, points: [[0, 0], [1, 0]], thicknes: 0.2}\n", encoding="utf-8")
    assert run(["check", str(bad)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "walls[0].thicknes" in captured.err and "did you mean 'thickness'" in captured.err
    assert run(["check", str(bad), "--json"]) == 2
    data = json.loads(capsys.readouterr().out)
    assert data["ok"] is False and "walls[0].thicknes" in data["error"]


def test_check_unknown_name_exits_2(capsys):
    assert run(["check", "no_such_map"]) == 2
    assert "no shipped map" in capsys.readouterr().err


def test_help_exists():
    with pytest.raises(SystemExit) as info:
        run(["check", "--help"])
    assert info.value.code == 0
