"""Same seed, same numbers: figures recorded before the run-layer restructure, pinned exactly.

``tests/golden/*.json`` were written by the code before the restructure with::

    agvsim drift --observations geometric --distance 300 --seeds 3 --json
    agvsim reproduce thesis --json
    agvsim bench localizer --samples 600 --skip-peers --json   (accuracy, false_positives)

Any change to these figures is a change of behaviour and must be deliberate:
re-record the file in the same commit and say why.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from agvsim.cli import main

GOLDEN = Path(__file__).parent / "golden"
#: wall-clock and machine fields: they differ from run to run
TIMING = {"observe_ms_median", "filter_ms_median", "ms_median", "ms_p90", "wall_time_s", "machine", "files"}


def _differences(expected, actual, path: str = "") -> list[str]:
    if isinstance(expected, dict) and isinstance(actual, dict):
        out = []
        for key in sorted(set(expected) | set(actual)):
            if key in TIMING:
                continue
            if key not in expected or key not in actual:
                out.append(f"{path}.{key}: present in only one")
            else:
                out += _differences(expected[key], actual[key], f"{path}.{key}")
        return out
    if isinstance(expected, list) and isinstance(actual, list):
        if len(expected) != len(actual):
            return [f"{path}: {len(expected)} items != {len(actual)}"]
        return [d for i, (e, a) in enumerate(zip(expected, actual)) for d in _differences(e, a, f"{path}[{i}]")]
    return [] if expected == actual else [f"{path}: {expected!r} != {actual!r}"]


def _run_json(argv: list[str], capsys) -> dict:
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_differences_sees_a_changed_figure():
    assert _differences({"a": [1.0, {"b": 2.0}], "wall_time_s": 1}, {"a": [1.0, {"b": 2.0}], "wall_time_s": 9}) == []
    assert _differences({"a": [1.0, {"b": 2.0}]}, {"a": [1.0, {"b": 2.0000000000000004}]}) == [
        ".a[1].b: 2.0 != 2.0000000000000004"]


@pytest.mark.slow
def test_drift_geometric_figures_are_unchanged(tmp_path, capsys):
    out = _run_json(["drift", "--observations", "geometric", "--distance", "300", "--seeds", "3", "--json",
                     "--no-progress", "--no-plots", "--out", str(tmp_path)], capsys)
    expected = json.loads((GOLDEN / "drift_geometric_300m_3seeds.json").read_text())
    assert _differences(expected, out) == []


def test_thesis_reproduction_is_unchanged(capsys):
    out = _run_json(["reproduce", "thesis", "--json"], capsys)
    expected = json.loads((GOLDEN / "reproduce_thesis.json").read_text())
    assert _differences(expected, out) == []


@pytest.mark.slow
def test_localizer_accuracy_figures_are_unchanged(capsys):
    out = _run_json(["bench", "localizer", "--samples", "600", "--skip-peers", "--json"], capsys)
    expected = json.loads((GOLDEN / "bench_localizer_600_accuracy.json").read_text())
    assert _differences(expected, {k: out[k] for k in expected}) == []
