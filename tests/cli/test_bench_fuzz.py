"""``agvsim bench fuzz``: the JSON report, the frame kinds, and that a detection is counted as false."""
from __future__ import annotations

import json
import os
import signal

import numpy as np
import pytest

from agvsim.bench import fuzz
from agvsim.cli import main


def test_the_cli_json_has_the_fields_and_meets_the_floors(capsys):
    assert main(["bench", "fuzz", "--frames", "200", "--seed", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("frames", "frames_requested", "seed", "interrupted", "kinds", "warmup_s", "timing", "crashes",
                "crash_cases", "false_detections", "false_cases", "by_kind", "floors", "machine"):
        assert key in out, key
    assert out["frames"] == 200 and not out["interrupted"]
    assert out["crashes"] == 0 and out["false_detections"] == 0
    assert out["floors"]["crashes"]["met"] and out["floors"]["false_detections"]["met"]
    for m in fuzz.METHODS:
        t = out["timing"][m]
        assert 0 < t["median_ms"] <= t["p99_ms"] <= t["max_ms"]
    assert sum(k["frames"] for k in out["by_kind"].values()) == 200
    assert all(out["by_kind"][k]["frames"] > 0 for k in fuzz.KINDS)


@pytest.mark.parametrize("kind", fuzz.KINDS)
def test_each_generator_makes_target_free_frames_of_its_kind(kind):
    from localizer import Camera, detect_targets

    cam = Camera.thesis(16.0)
    frames = [fuzz.make_frame(kind, s) for s in range(6)]
    for f in frames:
        assert f.shape == cam.shape == (480, 512) and f.dtype == np.uint8
        for m in fuzz.METHODS:
            assert detect_targets(f, cam, method=m) == []
    assert np.array_equal(fuzz.make_frame(kind, 3), frames[3])  # the seed reproduces the frame
    if kind == "flat_saturated":
        assert any(len(np.unique(f)) <= 3 for f in frames)
    else:
        assert not all(np.array_equal(frames[0], f) for f in frames[1:])  # the seed varies the frame


def test_equal_bars_are_rows_of_equal_bars():
    f = fuzz.make_frame("equal_bars", 11)
    cols = np.flatnonzero((f != f[0, 0]).any(axis=0))  # the bars' columns
    assert cols.size > 0
    runs = np.split(cols, np.flatnonzero(np.diff(cols) > 1) + 1)
    assert len({len(r) for r in runs}) == 1  # every bar the same width


def test_a_detection_is_counted_false_and_the_floor_is_not_met(monkeypatch):
    import localizer

    real = localizer.detect_targets
    calls = {"n": 0}

    def fake(image, camera, *a, **kw):
        calls["n"] += 1
        obs = real(image, camera, *a, **kw)
        return obs + ["fake observation"] if calls["n"] == 2 * len(fuzz.KINDS) + 7 else obs

    monkeypatch.setattr(localizer, "detect_targets", fake)
    r = fuzz.measure(12, seed=0, progress=False)
    assert r["false_detections"] == 1 and sum(r["false_detections_by_method"].values()) == 1
    assert len(r["false_cases"]) == 1 and r["false_cases"][0]["kind"] in fuzz.KINDS
    assert r["floors"]["false_detections"]["met"] is False and r["floors"]["crashes"]["met"]
    table = fuzz.format_table({**r, "machine": {}})
    assert "floor: false detections <= 0: NOT met (1)" in table
    assert "floor: crashes <= 0: met (0)" in table
    case = r["false_cases"][0]
    assert fuzz.make_frame(case["kind"], case["frame_seed"]).shape == (480, 512)


def test_a_crash_is_counted_with_its_kind_and_seed(monkeypatch):
    import localizer

    def boom(image, camera, *a, **kw):
        raise ZeroDivisionError("fake")

    monkeypatch.setattr(localizer, "detect_targets", boom)
    r = fuzz.measure(3, seed=2, progress=False)
    assert r["crashes"] == 6 and len(r["crash_cases"]) == 5
    assert r["crash_cases"][0] == {"method": "exact", "kind": fuzz.KINDS[0], "frame_seed": fuzz.frame_seed(2, 0),
                                   "index": 0, "error": "ZeroDivisionError", "message": "fake"}
    assert "floor: crashes <= 0: NOT met (6)" in fuzz.format_table(r)


def test_ctrl_c_reports_the_frames_done(monkeypatch):
    import localizer

    real = localizer.detect_targets
    calls = {"n": 0}

    def interrupt(image, camera, *a, **kw):
        calls["n"] += 1
        if calls["n"] == 2 * len(fuzz.KINDS) + 2 * 5 + 1:  # after the warm-up and 5 frames
            raise KeyboardInterrupt
        return real(image, camera, *a, **kw)

    monkeypatch.setattr(localizer, "detect_targets", interrupt)
    r = fuzz.measure(50, seed=0, progress=False)
    assert r["interrupted"] and r["frames"] == 5 and r["crashes"] == 0
    assert "5 of 50" in fuzz.format_table(r) and "INTERRUPTED" in fuzz.format_table(r)


@pytest.mark.skipif(not hasattr(signal, "pthread_sigmask"), reason="SIGINT held back by the thread's signal mask")
def test_a_ctrl_c_while_a_frame_is_measured_stops_the_run_after_that_frame(monkeypatch, python_sigint):
    # the signal, not an exception: held back until the frame is counted, so that no KeyboardInterrupt
    # is raised inside a compiled call (where numba crashes, or raises a SystemError that would be
    # counted as the detector's crash)
    import localizer

    real = localizer.detect_targets
    calls = {"n": 0}

    def signalled(image, camera, *a, **kw):
        calls["n"] += 1
        if calls["n"] == 2 * len(fuzz.KINDS) + 2 * 5 + 1:  # frame 5's first method
            os.kill(os.getpid(), signal.SIGINT)
            sum(range(1000))  # (Python code after the signal: a KeyboardInterrupt would be raised here)
        return real(image, camera, *a, **kw)

    monkeypatch.setattr(localizer, "detect_targets", signalled)
    r = fuzz.measure(50, seed=0, progress=False)
    assert r["interrupted"] and r["frames"] == 6 and r["crashes"] == 0
