"""Interrupted drift runs lose nothing: Ctrl-C ends with one line and exit status 130, the seeds
finished are saved (atomically) and the same command resumes after them; a killed run leaves no
process behind; a folder holding other settings is not overwritten without ``--restart``."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from agvsim.commands.run_folder import RunFolder, atomic_write

CMD = [sys.executable, "-m", "agvsim", "drift", "--observations", "geometric", "--distance", "150", "--seeds", "6",
       "--workers", "2", "--no-plots", "--no-progress"]


def _session(sid: int) -> list[int]:
    """The live processes of session ``sid`` (Linux /proc)."""
    pids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[3]) == sid and fields[0] != "Z":
                pids.append(int(d.name))
    return pids


def _default_sigint() -> None:
    # a process started by an xdist worker inherits its ignored SIGINT (Python keeps an ignored
    # SIGINT ignored): the run under test gets the default, as from a terminal
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start(out: Path) -> subprocess.Popen:
    return subprocess.Popen(CMD + ["--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=_default_sigint)


def _wait_for_seeds(out: Path, p: subprocess.Popen, n: int = 1, timeout: float = 120.0) -> None:
    t0 = time.time()
    while len(list((out / "seeds").glob("seed_*.json"))) < n:
        assert p.poll() is None, p.communicate()
        assert time.time() - t0 < timeout
        time.sleep(0.05)


def _gone(sid: int, timeout: float = 10.0) -> bool:
    t0 = time.time()
    while _session(sid):
        if time.time() - t0 > timeout:
            return False
        time.sleep(0.1)
    return True


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_ctrl_c_saves_the_finished_seeds_and_the_same_command_resumes(tmp_path):
    out = tmp_path / "run"
    p = _start(out)
    _wait_for_seeds(out, p)
    os.killpg(p.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole group
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if "interrupted" in ln]
    assert len(lines) == 1 and "run the same command to resume" in lines[0]
    assert _gone(p.pid), "a worker outlived the interrupted run"
    saved = sorted((out / "seeds").glob("seed_*.json"))
    assert saved and not list(out.rglob(".tmp-*"))
    before = {f.name: f.stat().st_mtime_ns for f in (out / "seeds").iterdir()}
    r = subprocess.run(CMD + ["--out", str(out), "--json"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert f"resuming: {len(saved)} seed" in r.stderr
    after = {f.name: f.stat().st_mtime_ns for f in (out / "seeds").iterdir()}
    assert all(after[k] == v for k, v in before.items())  # nothing computed twice
    res = json.loads(r.stdout)
    assert [m["seed"] for m in res["per_seed"]] == list(range(6)) and res["floors"]["position_rmse_m"]["met"]


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc and prctl")
def test_a_killed_run_leaves_no_process(tmp_path):
    out = tmp_path / "run"
    p = _start(out)
    _wait_for_seeds(out, p)
    os.kill(p.pid, signal.SIGKILL)  # the main process alone
    p.communicate(timeout=30)
    assert _gone(p.pid), f"left running: {_session(p.pid)}"


def test_a_folder_with_other_settings_is_kept_unless_restart(tmp_path):
    a = RunFolder(tmp_path, {"distance": 100.0, "odometry": "typical"})
    a.save_seed(0, {"seed": 0, "x": 1.0}, {"time": np.arange(3.0)})
    with pytest.raises(ValueError, match=r"holds a run with other settings \(distance\); use --restart"):
        RunFolder(tmp_path, {"distance": 200.0, "odometry": "typical"})
    assert set(RunFolder(tmp_path, {"distance": 100.0, "odometry": "typical"}).finished([0, 1])) == {0}
    b = RunFolder(tmp_path, {"distance": 200.0, "odometry": "typical"}, restart=True)
    assert b.finished([0, 1]) == {} and json.loads((tmp_path / "run.json").read_text())["distance"] == 200.0


def test_writes_are_atomic_and_half_files_are_not_finished_seeds(tmp_path):
    folder = RunFolder(tmp_path, {"k": 1})
    with pytest.raises(RuntimeError):
        with atomic_write(tmp_path / "seeds" / "seed_005.npz") as tmp:
            tmp.write_bytes(b"PK\x03\x04 half")
            raise RuntimeError("killed mid-write")
    assert not (tmp_path / "seeds" / "seed_005.npz").exists() and not list(tmp_path.rglob(".tmp-*"))
    folder.save_seed(1, {"seed": 1}, {"time": np.arange(4.0)})
    (tmp_path / "seeds" / "seed_002.json").write_text(json.dumps({"seed": 2}))
    (tmp_path / "seeds" / "seed_002.npz").write_bytes(b"PK\x03\x04 truncated")  # a write cut short
    (tmp_path / "seeds" / ".tmp-seed_003-x.npz").write_bytes(b"left by a kill")
    again = RunFolder(tmp_path, {"k": 1})
    assert set(again.finished([1, 2, 3])) == {1} and not list(tmp_path.rglob(".tmp-*"))
    metrics, log = again.finished([1])[1]
    assert metrics == {"seed": 1} and np.array_equal(log.time, np.arange(4.0))
