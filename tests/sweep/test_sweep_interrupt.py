"""An interrupted sweep loses nothing and computes nothing twice: after a Ctrl-C (one line,
exit 130) or a SIGKILL of the whole command at a random moment, every row file in the folder
is whole, the same command runs only the runs not yet finished, and the rows in the end are
those of an uninterrupted sweep."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from agvsim.sweep.folder import read_rows
from agvsim.sweep.runs import TIMING_COLUMNS

SPEC = "base: {distance: 120, observations: geometric}\ngrid: {odometry: [typical, worn]}\nseeds: 4\n"


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # (an xdist worker's children inherit an ignored SIGINT)


def _start(spec: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "agvsim", "sweep", str(spec), "--out", str(out), "--workers", "2",
                             "--no-progress", "--no-plots", "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True, preexec_fn=_default_sigint)


def _rows_on_disk(out: Path) -> list[Path]:
    return sorted((out / "runs").glob("p*_s*.json")) if (out / "runs").is_dir() else []


def _wait_for_rows(out: Path, p: subprocess.Popen, n: int, timeout: float = 120.0) -> None:
    t0 = time.time()
    while len(_rows_on_disk(out)) < n:
        assert p.poll() is None, p.communicate()
        assert time.time() - t0 < timeout
        time.sleep(0.02)


def _figures(out: Path) -> dict:
    return {k: {c: v for c, v in r.items() if c not in TIMING_COLUMNS} for k, r in read_rows(out).items()}


def _resume(spec: Path, out: Path, before: dict[str, int]) -> dict:
    """The same command again: the rows there before are skipped and left as they were."""
    p = subprocess.run([sys.executable, "-m", "agvsim", "sweep", str(spec), "--out", str(out), "--workers", "2",
                        "--no-progress", "--no-plots", "--json"], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    result = json.loads(p.stdout)
    assert result["skipped"] == len(before) and result["finished"] == 8 - len(before), result
    assert {f.name: f.stat().st_mtime_ns for f in _rows_on_disk(out) if f.name in before} == before
    return result


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> tuple[Path, dict]:
    folder = tmp_path_factory.mktemp("sweep")
    spec = folder / "spec.yaml"
    spec.write_text(SPEC)
    p = subprocess.run([sys.executable, "-m", "agvsim", "sweep", str(spec), "--out", str(folder / "whole"),
                        "--workers", "2", "--no-progress", "--no-plots", "--json"], capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    return spec, _figures(folder / "whole")


@pytest.mark.slow
def test_ctrl_c_then_the_same_command(tmp_path, reference):
    spec, whole = reference
    out = tmp_path / "o"
    p = _start(spec, out)
    _wait_for_rows(out, p, 2)
    os.killpg(p.pid, signal.SIGINT)  # a terminal's Ctrl-C: the whole group
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if "interrupted" in ln]
    assert len(lines) == 1 and "runs finished and saved in" in lines[0] and "run the same command to resume" in lines[0]
    saved = int(lines[0].split("interrupted; ")[1].split(" of ")[0])
    before = {f.name: f.stat().st_mtime_ns for f in _rows_on_disk(out)}
    assert saved == len(before) >= 2
    _resume(spec, out, before)
    assert _figures(out) == whole


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.05, 0.4])
def test_sigkill_at_any_moment_leaves_whole_files(tmp_path, reference, delay):
    spec, whole = reference
    out = tmp_path / "o"
    p = _start(spec, out)
    _wait_for_rows(out, p, 1)
    time.sleep(delay)  # (a moment within the next runs: mid-run, or mid-write)
    os.killpg(p.pid, signal.SIGKILL)  # the command and its workers, no chance to clean up
    p.communicate(timeout=60)
    rows = _rows_on_disk(out)
    for f in rows:  # every file under a final name is whole
        json.loads(f.read_text())
    before = {f.name: f.stat().st_mtime_ns for f in rows}
    _resume(spec, out, before)
    assert not list(out.rglob(".tmp-*"))  # an interrupted write's leftovers are cleaned up
    assert _figures(out) == whole
