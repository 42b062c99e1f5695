"""`agvsim render` writes the frame and the truth JSON (its documented fields); `agvsim bench render --json`
prints one JSON object; the demo's camera strip renders, detects and tiles."""
from __future__ import annotations

import json
import math
import subprocess
import sys

import cv2
import numpy as np
import pytest

pytestmark = pytest.mark.render


def _agvsim(*args, timeout=180):
    return subprocess.run([sys.executable, "-m", "agvsim", *args], capture_output=True, text=True, timeout=timeout)


@pytest.mark.slow
def test_render_cli_writes_frame_and_truth(tmp_path):
    frame, truth = tmp_path / "frame.png", tmp_path / "truth.json"
    out = _agvsim("render", "--map", "plant_floor", "--pose", "47", "4", "-1.2", "--lens", "16",
                  "--lighting", "bright", "--seed", "3", "--out", str(frame), "--truth", str(truth))
    assert out.returncode == 0, out.stderr
    img = cv2.imread(str(frame), cv2.IMREAD_UNCHANGED)
    assert img.shape == (480, 512) and img.dtype == np.uint8
    data = json.loads(truth.read_text())
    assert data["camera"]["fx"] == pytest.approx(16.0 / 8.8 * 512)
    assert data["camera"]["cx"] == 256.0 and data["camera"]["width"] == 512
    ids = {t["id"] for t in data["targets"]}
    from agvsim.world import load_map

    assert "T05" in ids and ids == {t.id for t in load_map("plant_floor").targets}  # one entry per map target
    t05 = next(t for t in data["targets"] if t["id"] == "T05")
    assert t05["visible"] is True
    assert set(t05) >= {"id", "visible", "distance", "alpha", "beta", "polarity", "bbox", "corners"}
    assert len(t05["bbox"]) == 4 and np.array(t05["corners"]).shape == (4, 2)
    assert 3.0 < t05["distance"] < 6.0 and abs(t05["alpha"]) < math.radians(70)
    assert np.count_nonzero(img == 255) > 0.2 * img.size  # bright lighting saturates
    # --json: exactly one object on stdout
    out = _agvsim("render", "--pose", "47", "4", "-1.2", "--out", str(frame), "--json", "--no-noise")
    assert out.returncode == 0, out.stderr
    assert [t["id"] for t in json.loads(out.stdout)["visible"]] == ["T05"]
    # bad input: a clear error, exit status 2
    out = _agvsim("render", "--pose", "47", "4", "nan", "--out", str(frame))
    assert out.returncode == 2 and "finite" in out.stderr


@pytest.mark.slow
def test_bench_render_json():
    out = _agvsim("bench", "render", "--frames", "2", "--json", timeout=300)
    assert out.returncode == 0, out.stderr
    res = json.loads(out.stdout)
    assert res["platform"] in ("egl", "osmesa")
    assert res["render_ms"]["supersample_2"] > 0 and res["startup_s"]["gl_context"] > 0
    ray = res["raycast"]
    assert ray["passes"] == 5 and 0 < ray["best_of_passes_ms"]["render"] <= ray["render_ms"] * 1.5
    assert ray["floor"]["met"] == (ray["render_ms"] <= ray["floor"]["render_median_ms_max"] == 1.5)
    blur = ray["floors"]["render() + motion blur median"]
    assert blur["met"] == (ray["render_motion_blur_ms"] <= 2.0)
    ratio = ray["floors"]["speed-up over pyrender's default"]
    assert ratio["met"] == (res["render_ms"]["supersample_2"] / ray["render_ms"] >= 40.0)


def test_camera_strip(tmp_path, gl_context):
    from agvsim.sensors.render.mount import CameraMount
    from agvsim.sensors.render.renderer import CameraRenderer
    from agvsim.sensors.render.strip import route_poses, save_camera_strip
    from agvsim.world import load_map

    m = load_map("plant_floor")
    mount = CameraMount.side_looking("right")
    poses = route_poses(m, 3, mount=mount)
    r = CameraRenderer(m, mount=mount, context=gl_context, backend="pyrender")
    res = save_camera_strip(m, poses, tmp_path / "strip.png", renderer=r, rng=np.random.default_rng(0), columns=3)
    img = cv2.imread(res["path"])
    assert img.shape[1] == 768 and img.shape[0] > 240  # the legend on top, captions below the tiles
    found = [f for fr in res["frames"] for f in fr["found"]]
    assert len(found) >= 2
    for f in found:
        assert f["target"] is not None and abs(f["distance_error"]) < 0.05
