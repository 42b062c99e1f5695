"""Every benchmark states each floor with its verdict ("met" / "NOT met"), in the table and in
the JSON, and says what is missing instead of reporting a zero."""
from __future__ import annotations

import math

import pytest

from agvsim.bench.floors import floor_line, verdict

MACHINE = {"cpu_model": "test", "cpu_count": 2, "python": "3"}


def test_verdict_and_line():
    assert verdict(3.0, "<=", 2.0, "ms") == {"value": 3.0, "op": "<=", "limit": 2.0, "unit": "ms", "met": False}
    assert verdict(600, ">=", 500.0)["met"] and not verdict(None, ">=", 1.0)["met"]
    assert not verdict(math.nan, "<=", 1.0)["met"]
    assert floor_line("frame", verdict(1.5, "<=", 2.0, "ms"), ".2f") == "floor: frame <= 2 ms: met (1.50 ms)"
    assert floor_line("x", verdict(None, "<=", 2.0)) == "floor: x <= 2: NOT met (no value)"
    with pytest.raises(ValueError, match="floor op"):
        verdict(1.0, "<", 2.0)


def test_bench_sim_floor_line():
    from agvsim.bench.sim import format_table

    res = {"map": "m", "odometry": "typical", "physics_rate_hz": 100.0, "simulated_seconds": 10.0,
           "physics_steps_per_second": 40000.0, "real_time_factor": 400.0, "machine": MACHINE,
           "peer": {"physics_steps_per_second": 50000.0, "real_time_factor": 500.0},
           "floor_real_time_factor": 500.0, "floor": verdict(400.0, ">=", 500.0, "x")}
    assert "floor: real-time factor >= 500 x: NOT met (400 x)" in format_table(res)


def _localizer_result(**extra):
    return {"machine": MACHINE,
            "speed": {"frames": 4, "found": {"exact": 4, "aruco": 4}, "localizer_exact_ms": 1.0, "aruco_ms": 2.0,
                      "first_call_exact_s": 0.1, "first_call_thesis_s": 0.1},
            "resolution": [], "targets": [],
            "accuracy": {"samples": 2, "exact": {"detection_rate": 1.0,
                                                  "by_lighting": {"dim": {"d_error_pct_max": 1.5}}}},
            "false_positives": {"exact": 0, "thesis": 1, "frames": 9},
            "blank_frames": {"black_ms": 0.2, "white_ms": 6.0, "floor_ms": 5.0}, **extra}


def test_bench_localizer_floors_and_a_missing_apriltag():
    from agvsim.bench.localizer import APRILTAG_INSTALL, format_table

    table = format_table(_localizer_result(missing_peers={"apriltag": APRILTAG_INSTALL}))
    assert "floor: black frame (nothing to find), ms per call <= 5 ms: met (0.200 ms)" in table
    assert "floor: white frame (nothing to find), ms per call <= 5 ms: NOT met (6.000 ms)" in table
    assert "apriltag" in table and "pip install pupil-apriltags" in table
    assert "{" not in table  # no raw Python dicts
    assert "false detections on 9 target-free frames: exact 0, thesis 1" in table


def test_bench_render_floor_line_and_json_record():
    from agvsim.bench import render

    ray = {"passes": 5, "level_frame_ms": 1.0, "render_ms": 2.5, "render_motion_blur_ms": 3.0,
           "best_of_passes_ms": {"level_frame": 0.9, "render": 1.9, "render_motion_blur": 2.8},
           "floor": {**verdict(2.5, "<=", render.FRAME_FLOOR_MS, "ms"), "render_median_ms_max": 1.5,
                     "met_best_of_passes": False},
           "floors": {"render() + motion blur median": verdict(3.0, "<=", render.BLUR_FLOOR_MS, "ms"),
                      "speed-up over pyrender's default": verdict(20.0, ">=", render.PYRENDER_RATIO_FLOOR, "x")},
           "speed_up_vs_pyrender_default": 20.0, "startup_s": {"renderer_object": 0.1, "first_frame_total": 0.2}}
    res = {"map": "m", "width": 512, "height": 480, "lens_mm": 16.0, "frames": 3, "platform": "egl",
           "machine": MACHINE, "startup_s": {"renderer_object": 0.1, "gl_context": 0.1, "scene_upload_and_shaders": 0.1},
           "gl_only_ms": {"flat_1x": 1.0, "flat_2x": 2.0, "lit_pbr_1x": 3.0},
           "render_ms": {"supersample_1": 1.0, "supersample_2": 2.0, "supersample_2_motion_blur": 3.0}, "raycast": ray}
    table = render.format_table(res)
    assert "floor: raycast render() median <= 1.5 ms: NOT met (2.50 ms; best of passes 1.90 ms: NOT met)" in table
    assert "floor: render() + motion blur median <= 2 ms: NOT met (3.00 ms)" in table
    assert "floor: speed-up over pyrender's default >= 40 x: NOT met (20 x)" in table
    assert "issue" not in table


def test_integrity_table_pluralises_and_names_no_issue():
    from agvsim.bench.integrity_report import format_table
    from agvsim.commands.bench import BENCHMARKS

    assert "1 worker," in format_table({"machine": {}, "workers": 1, "wall_s": 1.0, "summary": {}})
    assert not any("issue" in text for text in BENCHMARKS.values())
