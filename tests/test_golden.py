"""Same seed, same numbers: figures recorded before the run-layer restructure, pinned exactly.

``tests/golden/*.json`` were written by the code before the restructure with (the drift's second
file, ``_avx2``, by the same code on an AMD EPYC without AVX-512)::

    agvsim drift --observations geometric --distance 300 --seeds 3 --json
    agvsim reproduce thesis --json
    agvsim bench localizer --samples 600 --skip-peers --json   (accuracy, false_positives)

Any change to these figures is a change of behaviour and must be deliberate:
re-record the file in the same commit and say why.

Figures added since, not re-recorded: ``time_lost_s`` (the seconds the filter spent
lost; 0 in these runs, as ``lost`` is), inserted by hand next to ``lost``.

Floats are compared to :data:`REL` (relative): the same seed gives the same numbers bit for bit
on one machine (the determinism tests hold that), but not across CPUs: numpy's BLAS and LLVM
choose their kernels by CPU, which changes the last bits (on an AMD Zen 5 the figures recorded
on an Intel Xeon come out within 2e-11 for drift and the thesis table, and the localizer's means
within 1e-8: its iterative fits carry the last bits further). A change of behaviour moves them
by orders of magnitude more.

The drift's figures go further: over 300 m a last-bit difference can flip one gate decision (an
observation accepted or not), and every figure after it moves. Its figures are recorded per kind
of CPU (:data:`DRIFT_FILES`: an Intel Xeon with AVX-512, and an AMD EPYC without it, where one
observation of 1,645 fell the other way) and a run must match one of them exactly.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from agvsim.cli import main

GOLDEN = Path(__file__).parent / "golden"
#: wall-clock and machine fields: they differ from run to run
TIMING = {"observe_ms_median", "filter_ms_median", "ms_median", "ms_p90", "wall_time_s", "machine", "files"}
#: relative tolerance of a float figure (module docstring: the last bits differ between CPUs)
REL = 1e-7


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
    if (isinstance(expected, float) and isinstance(actual, float)
            and math.isclose(expected, actual, rel_tol=REL, abs_tol=REL * 1e-3)):
        return []
    return [] if expected == actual else [f"{path}: {expected!r} != {actual!r}"]


def _run_json(argv: list[str], capsys) -> dict:
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_differences_sees_a_changed_figure():
    assert _differences({"a": [1.0, {"b": 2.0}], "wall_time_s": 1}, {"a": [1.0, {"b": 2.0}], "wall_time_s": 9}) == []
    assert _differences({"a": [1.0, {"b": 2.0}]}, {"a": [1.0, {"b": 2.0 * (1 + 1e-8)}]}) == []  # last bits
    assert _differences({"a": [1.0, {"b": 2.0}]}, {"a": [1.0, {"b": 2.000001}]}) == [".a[1].b: 2.0 != 2.000001"]
    assert _differences({"n": 3}, {"n": 4}) == [".n: 3 != 4"]


#: the drift's figures as recorded on the two kinds of CPU the project is run on (module docstring)
DRIFT_FILES = ("drift_geometric_300m_3seeds_avx512.json", "drift_geometric_300m_3seeds_avx2.json")


@pytest.mark.slow
def test_drift_geometric_figures_are_unchanged(tmp_path, capsys):
    out = _run_json(["drift", "--observations", "geometric", "--distance", "300", "--seeds", "3", "--json",
                     "--no-progress", "--no-plots", "--out", str(tmp_path)], capsys)
    differences = {name: _differences(json.loads((GOLDEN / name).read_text()), out) for name in DRIFT_FILES}
    assert any(not d for d in differences.values()), differences


def test_thesis_reproduction_is_unchanged(capsys):
    out = _run_json(["reproduce", "thesis", "--json"], capsys)
    expected = json.loads((GOLDEN / "reproduce_thesis.json").read_text())
    assert _differences(expected, out) == []


@pytest.mark.slow
def test_localizer_accuracy_figures_are_unchanged(capsys):
    out = _run_json(["bench", "localizer", "--samples", "600", "--skip-peers", "--json"], capsys)
    expected = json.loads((GOLDEN / "bench_localizer_600_accuracy.json").read_text())
    assert _differences(expected, {k: out[k] for k in expected}) == []
