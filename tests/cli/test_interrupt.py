"""Interrupted drift runs lose nothing: Ctrl-C ends with one line and exit status 130, the seeds
finished are saved (atomically) and the same command resumes after them; a killed run leaves no
process behind; a folder holding other settings is not overwritten without ``--restart``; a soak
of Ctrl-C and SIGKILL at random moments, each followed by the same command."""
from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from agvsim.commands.run_folder import RunFolder, atomic_write
from agvsim.commands.workers import sigint_blocked

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


def _start(out: Path, cmd: list[str] = CMD) -> subprocess.Popen:
    return subprocess.Popen(cmd + ["--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
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
    # a finished seed's files (its figures, written last, mark it finished: RunFolder.save_seed); an
    # interrupt between a seed's arrays and its figures leaves arrays that the resumed run rewrites
    finished = [f for s in saved for f in (s, s.with_suffix(".npz"))]
    before = {f.name: f.stat().st_mtime_ns for f in finished}
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



def _blocks_sigint(pid: int) -> bool:
    """Whether process ``pid`` blocks SIGINT (Linux /proc: the SigBlk mask)."""
    status = Path(f"/proc/{pid}/status").read_text()
    mask = int(re.search(r"^SigBlk:\s*([0-9a-f]+)", status, re.M).group(1), 16)
    return bool(mask >> (signal.SIGINT - 1) & 1)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_ctrl_c_while_workers_start_is_held_back_then_raised():
    """What a pool's start runs under: a SIGINT to this process or taken by another thread (as a
    BLAS thread may) does not cut the block short; it is raised on leaving; a process started in
    the block inherits SIGINT blocked (a worker still starting up cannot take it)."""
    handler = signal.signal(signal.SIGINT, signal.default_int_handler)  # (an xdist worker ignores it)
    stop = threading.Event()
    other = threading.Thread(target=stop.wait, daemon=True)
    other.start()  # (started before the block: SIGINT not blocked in it)
    reached, child = [], None
    try:
        with pytest.raises(KeyboardInterrupt):
            with sigint_blocked():
                os.kill(os.getpid(), signal.SIGINT)
                signal.pthread_kill(other.ident, signal.SIGINT)
                child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
                time.sleep(0.05)
                reached.append("end of the block")
        assert reached == ["end of the block"] and _blocks_sigint(child.pid)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler and not _blocks_sigint(os.getpid())
    finally:
        stop.set()
        signal.signal(signal.SIGINT, handler)
        if child is not None:
            child.kill()
            child.wait()


SOAK = [sys.executable, "-m", "agvsim", "drift", "--observations", "geometric", "--distance", "30", "--seeds", "4",
        "--workers", "2", "--no-progress", "--json"]
#: figures that are wall-clock times or name the folder: they differ between two runs
UNEQUAL = {"wall_time_s", "observe_ms_median", "filter_ms_median", "machine", "files"}


def _finished(out: Path) -> dict[int, tuple[int, int]]:
    """The seeds finished in ``out`` (both files there and loading): seed -> their mtimes (ns)."""
    done = {}
    for meta in (out / "seeds").glob("seed_*.json") if (out / "seeds").is_dir() else ():
        npz = meta.with_suffix(".npz")
        try:
            seed = json.loads(meta.read_text())["seed"]
            with np.load(npz) as data:
                assert len(data["time"]) > 0
        except (OSError, ValueError, KeyError, AssertionError):
            continue
        done[seed] = (meta.stat().st_mtime_ns, npz.stat().st_mtime_ns)
    return done


def _unreadable(out: Path) -> list[str]:
    """Files under a final name in ``out`` that do not load (a temporary ``.tmp-*`` is not one)."""
    bad = []
    for f in out.rglob("*") if out.is_dir() else ():
        if not f.is_file() or f.name.startswith(".tmp-"):
            continue
        try:
            if f.suffix == ".json":
                json.loads(f.read_text())
            elif f.suffix == ".npz":
                with np.load(f) as data:
                    [data[k] for k in data.files]
            elif f.suffix == ".png":
                assert f.read_bytes()[-8:-4] == b"IEND"
        except Exception as exc:  # noqa: BLE001 (whatever makes it unreadable)
            bad.append(f"{f.name}: {exc!r}")
    return bad


def _resumed(err: str) -> set[int] | None:
    """The seeds a run said it skipped (None: it said nothing of resuming)."""
    m = re.search(r"resuming: \d+ seeds? of \d+ already finished in .* \(seeds? ([\d, -]+): not run again", err)
    if m is None:
        return None
    seeds = set()
    for part in m.group(1).split(", "):
        a, _, b = part.partition("-")
        seeds.update(range(int(a), int(b or a) + 1))
    return seeds


def _completed(printed: str) -> bool:
    """Whether a run printed its whole result (``--json``)."""
    try:
        return "per_seed" in json.loads(printed)
    except ValueError:
        return False


def _figures(result: dict):
    if isinstance(result, dict):
        return {k: _figures(v) for k, v in result.items() if k not in UNEQUAL}
    return [_figures(v) for v in result] if isinstance(result, list) else result


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc and prctl")
def test_interrupts_at_random_moments_lose_nothing_and_compute_nothing_twice(tmp_path):
    """Ctrl-C (to the process group, as a terminal sends it, once the command has said what it
    runs: before that the interpreter is still importing and building the parser) and SIGKILL
    (to the main process alone, from its start) at random moments of a run, each followed by
    the same command: no traceback, exit 130 on Ctrl-C, no process left, every file under a
    final name loads, each run skips exactly the seeds finished before it and leaves their
    files alone, and the last run's figures are those of a run never interrupted."""
    rng = np.random.default_rng(7)
    t0 = time.monotonic()
    p = subprocess.Popen(SOAK + ["--out", str(tmp_path / "reference")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    p.stderr.readline()
    started = time.monotonic() - t0  # (imports, then the command's first line)
    reference, _ = p.communicate(timeout=300)
    span = time.monotonic() - t0
    assert p.returncode == 0
    out = tmp_path / "run"
    outcomes = []
    for attempt in range(6):
        sig = (signal.SIGINT, signal.SIGKILL)[attempt % 2]
        before = _finished(out)
        p = _start(out, SOAK)
        first = p.stderr.readline() if sig == signal.SIGINT else ""  # (the command has started)
        time.sleep(rng.uniform(0.0, 0.8) * (span - started if sig == signal.SIGINT else span))
        try:
            os.killpg(p.pid, sig) if sig == signal.SIGINT else os.kill(p.pid, sig)
        except ProcessLookupError:  # (it had finished)
            pass
        printed, err = p.communicate(timeout=120)
        err = first + err
        outcomes.append((sig.name, p.returncode, len(before)))
        assert _gone(p.pid), f"left running after {sig.name}: {_session(p.pid)}"
        assert "Traceback" not in err, err
        # (a Ctrl-C in the interpreter's teardown, after the command returned, ends it by SIGINT)
        done = p.returncode == 0 or (sig == signal.SIGINT and p.returncode == -signal.SIGINT and _completed(printed))
        assert done or p.returncode == (130 if sig == signal.SIGINT else -signal.SIGKILL), (p.returncode, err)
        if p.returncode == 130:
            said = [line for line in err.splitlines() if "interrupted" in line]
            assert len(said) == 1, err
            claimed = re.search(r"(\d+) of 4 seeds finished and saved", said[0])
            assert claimed is None or int(claimed.group(1)) <= len(_finished(out))  # nothing claimed is lost
        assert _resumed(err) in (None, set(before)) and (before or _resumed(err) is None), err
        after = _finished(out)
        assert all(after.get(s) == mtimes for s, mtimes in before.items()), "a finished seed was computed again"
        assert _unreadable(out) == []
    assert any(rc == 130 for _, rc, _ in outcomes), outcomes  # (a Ctrl-C landed while it ran)
    before = _finished(out)
    final = subprocess.run(SOAK + ["--out", str(out)], capture_output=True, text=True, timeout=300)
    assert final.returncode == 0, final.stderr
    assert _resumed(final.stderr) == (set(before) if before else None), final.stderr
    assert all(_finished(out).get(s) == mtimes for s, mtimes in before.items())
    assert _unreadable(out) == [] and not list(out.rglob(".tmp-*"))
    assert _figures(json.loads(final.stdout)) == _figures(json.loads(reference))


def test_a_resumed_run_reports_the_figures_of_an_uninterrupted_one(tmp_path, capsys):
    """A seed read back from its files sums into the summary exactly as it did in the run that
    computed it (its figures are saved to the bit, not rounded for show)."""
    from agvsim.cli import main

    argv = ["drift", "--map", "corridor", "--observations", "geometric", "--distance", "20", "--workers", "1",
            "--no-progress", "--no-plots", "--json"]
    assert main(argv + ["--seeds", "3", "--out", str(tmp_path / "whole")]) == 0
    whole = json.loads(capsys.readouterr().out)
    assert main(argv + ["--seeds", "1", "--out", str(tmp_path / "parts")]) == 0  # seed 0, then 1 and 2
    capsys.readouterr()
    assert main(argv + ["--seeds", "3", "--out", str(tmp_path / "parts")]) == 0
    resumed = json.loads(capsys.readouterr().out)
    assert _figures(resumed) == _figures(whole)


def test_a_ctrl_c_while_the_command_line_is_built_is_one_line(monkeypatch, capsys):
    """A Ctrl-C in the first moments (the commands' parsers being built, or the arguments
    parsed) is the same one line and exit 130 as one during the work."""
    import agvsim.cli as cli

    def interrupted():
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "build_parser", interrupted)
    assert cli.main(["drift", "--seeds", "1"]) == 130
    assert capsys.readouterr().err == "agvsim: interrupted\n"


def test_a_ctrl_c_before_the_seeds_or_during_the_summary_says_what_is_saved(tmp_path, monkeypatch, capsys):
    """Before any seed: nothing written. After the last seed, while the summary is made: every
    seed saved, and the same command writes the summary without running any seed again."""
    import agvsim.analysis.evaluate as evaluate
    import agvsim.world as world
    from agvsim.cli import main

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    out = tmp_path / "run"
    argv = ["drift", "--map", "corridor", "--observations", "geometric", "--distance", "10", "--workers", "1",
            "--no-progress", "--no-plots", "--seeds", "2", "--out", str(out)]
    with monkeypatch.context() as m:
        m.setattr(world, "load_map", interrupted)
        assert main(argv) == 130
    err = capsys.readouterr().err
    assert err.splitlines()[-1] == "agvsim drift: interrupted; no seed had started, nothing was written"
    assert not out.exists()
    with monkeypatch.context() as m:
        m.setattr(evaluate, "summarize", interrupted)
        assert main(argv) == 130
    last = capsys.readouterr().err.splitlines()[-1]
    assert last.startswith("agvsim drift: interrupted; all 2 seeds finished and saved in ") and "summary" in last
    assert not (out / "drift.json").exists()
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "2 seeds of 2 already finished" in err and (out / "drift.json").exists()


def test_a_ctrl_c_a_library_reports_as_its_own_error_is_still_an_interrupt(monkeypatch, capsys):
    """matplotlib's compiled path code turns a KeyboardInterrupt raised inside it into
    ``ValueError: Invalid affine transformation matrix``: the command line says "interrupted" and
    exits 130, not "error" and 2; a ValueError with no Ctrl-C before it stays a user's mistake."""
    import agvsim.cli as cli

    def masked(args):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1.0)  # (the handler runs here)
        except KeyboardInterrupt:
            raise ValueError("Invalid affine transformation matrix") from None
        return 0

    def mistake(args):
        raise ValueError("--frames: expected a positive integer")

    handler = signal.signal(signal.SIGINT, signal.default_int_handler)  # (an xdist worker ignores it)
    try:
        for func, code, words in ((masked, 130, "interrupted"), (mistake, 2, "error: --frames")):
            class Parser:
                def parse_args(self, argv, func=func):
                    return argparse.Namespace(command="warmup", func=func)

            monkeypatch.setattr(cli, "build_parser", Parser)
            assert cli.main(["warmup"]) == code
            assert words in capsys.readouterr().err
            assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back
    finally:
        signal.signal(signal.SIGINT, handler)
