"""The envelope benchmark's independent frame pipeline (``agvsim bench envelope``)."""
from __future__ import annotations

import argparse
import dataclasses
import math

import cv2
import numpy as np
import pytest

from agvsim.bench import envelope
from agvsim.bench.envelope_conditions import NAMES, parse_conditions
from agvsim.bench.envelope_frames import (Radiance, bar_rows, camera_for, expose_frame, make_frame, render_radiance,
                                          render_scene, sample_scene, scene_rng)
from agvsim.bench.envelope_sensor import FrameSettings, psf_kernel, srgb_encode, vignetting
from agvsim.bench.peers import peer_detectors, silent_c_stderr
from agvsim.bench.envelope_frames import MARKER_SIDE
from localizer import Camera, TargetPose, TargetSpec, detect_targets

#: no noise: the frame is a function of the scene and the optics alone
CLEAN = FrameSettings(full_well=0.0, read_noise=0.0)


def _scene(pose: TargetPose, polarity: str = "positive", camera: Camera | None = None) -> Radiance:
    """A frame's scene with ``pose``, no clutter and even light, rendered."""
    camera = camera or camera_for(512, 480)
    rng = scene_rng(7, 0, True)
    scene = dataclasses.replace(sample_scene(rng, camera), pose=pose, polarity=polarity, clutter=(),
                                light=(0.0, 0.0, 0.0))
    return Radiance(camera, scene, render_radiance(scene, camera, TargetSpec(), rng), (7, 0, 1))


def test_frames_are_seeded_and_reproducible():
    a = make_frame(FrameSettings(), 3, 1)
    b = make_frame(FrameSettings(), 3, 1)
    assert a.image.dtype == np.uint8 and a.image.shape == (480, 512)
    assert np.array_equal(a.image, b.image)
    assert a.scene == b.scene
    assert not np.array_equal(a.image, make_frame(FrameSettings(), 4, 1).image)
    assert not np.array_equal(a.image, make_frame(FrameSettings(), 3, 2).image)
    # every condition of a size sees the same scene; the sensor's draws differ with the settings
    r = render_scene(512, 480, 3, 1)
    assert np.array_equal(expose_frame(FrameSettings(), r).image, a.image)
    assert expose_frame(FrameSettings(blur=2.0), r).scene == a.scene


@pytest.mark.parametrize("alpha, polarity", [(0.0, "positive"), (0.5, "negative"), (-0.9, "positive")])
def test_bar_edges_land_where_the_pinhole_projection_says(alpha, polarity):
    pose = TargetPose(2.2, 0.06, alpha, 0.05)
    r = _scene(pose, polarity)
    img = expose_frame(CLEAN, r).image.astype(float)
    cam, b = r.camera, TargetSpec().bar_width
    y = cam.project(pose.points(0.0, 0.0))[1]
    profile = img[int(y) - 15:int(y) + 15].mean(axis=0)  # the column profile across the bars' middle
    edges = cam.project(pose.points(np.array([-1.5, -0.5, 0.5, 1.5]) * b, np.zeros(4)))[:, 0]
    mids = cam.project(pose.points(np.array([-1.75, -1.0, 0.0, 1.0, 1.75]) * b, np.zeros(5)))[:, 0]
    centres = np.rint(mids).astype(int)  # margin, bar, gap, bar, margin
    ink = [profile[centres[1]], profile[centres[3]]]
    paper = [profile[centres[0]], profile[centres[2]], profile[centres[4]]]
    assert abs(np.mean(ink) - np.mean(paper)) > 100
    for k, e in enumerate(edges):
        a, z = centres[k], centres[k + 1]  # the pixels between the two plateaus
        lo, hi = profile[a], profile[z]
        s = ((profile[a:z + 1] - lo) / (hi - lo)).sum()  # the area under the normalised step
        measured = z + 0.5 - s  # a step from lo to hi at x = e leaves (z + 0.5 - e) of area
        assert abs(measured - e) < 0.1, (k, measured, e)


def test_gamma_encodes_with_the_srgb_curve():
    r = _scene(TargetPose(3.0, 0.0, 0.3, 0.0))
    lin = expose_frame(CLEAN, r).image.astype(float)
    srgb = expose_frame(dataclasses.replace(CLEAN, encoding="srgb"), r).image.astype(float)
    want = 255.0 * srgb_encode((lin / 255.0).astype(np.float32))
    assert np.abs(srgb - want).max() <= 2.5  # the linear frame's own rounding, stretched by the curve
    assert srgb.mean() > lin.mean() + 20  # mid-greys are lifted
    assert srgb_encode(np.array([0.0, 1.0], np.float32)) == pytest.approx([0.0, 1.0], abs=1e-6)
    assert abs(float(srgb_encode(np.array([0.5], np.float32))[0]) - 0.7354) < 1e-3


def test_vignetting_falls_to_the_corner_share():
    cam = camera_for(512, 480)
    v = vignetting(cam.shape, cam.fx, cam.fy, cam.cx, cam.cy, 0.4)
    corners = [v[0, 0], v[0, -1], v[-1, 0], v[-1, -1]]
    assert min(corners) == pytest.approx(0.4, abs=0.01) and v.max() == pytest.approx(1.0, abs=1e-3)
    r = _scene(TargetPose(3.0, 0.0, 0.0, 0.0))
    plain = expose_frame(CLEAN, r).image.astype(float)
    dark = expose_frame(dataclasses.replace(CLEAN, vignette=0.4), r).image.astype(float)
    flare = 255.0 * CLEAN.flare
    ratio = (dark[-4:, -4:].mean() - flare) / (plain[-4:, -4:].mean() - flare)
    assert ratio == pytest.approx(v[-4:, -4:].mean(), abs=0.03)
    assert abs(dark[240, 256] - plain[240, 256]) <= 1


def test_jpeg_compresses_with_loss_but_keeps_the_picture():
    r = _scene(TargetPose(2.5, 0.05, 0.2, 0.0))
    raw = expose_frame(CLEAN, r).image.astype(float)
    jpg = expose_frame(dataclasses.replace(CLEAN, jpeg_quality=70), r).image.astype(float)
    err = jpg - raw
    assert np.abs(err).max() > 2  # ringing at the edges
    assert 10 * math.log10(255.0 ** 2 / np.mean(err ** 2)) > 30  # but a faithful picture


def test_bayer_demosaicing_keeps_grey_levels_and_blurs_edges():
    red = np.zeros((8, 8), np.uint8)
    red[0::2, 0::2] = 200  # RGGB: red at (0, 0); OpenCV calls this layout BayerBG
    assert tuple(cv2.cvtColor(red, cv2.COLOR_BayerBG2BGR)[3, 3]) == (0, 0, 200)
    r = _scene(TargetPose(2.5, 0.05, 0.2, 0.0))
    grey = expose_frame(CLEAN, r).image.astype(float)
    bayer = expose_frame(dataclasses.replace(CLEAN, bayer=True), r).image.astype(float)
    assert not np.array_equal(grey, bayer)
    flat = np.abs(cv2.Laplacian(grey, cv2.CV_64F)) < 0.5  # away from edges: the white balance holds the level
    assert np.abs(bayer - grey)[flat].mean() < 1.5
    assert np.abs(bayer - grey).max() > 5  # at edges the interpolation shows


def test_psf_kernels_are_normalised_and_of_their_size():
    for kind, size in (("gaussian", 1.5), ("disc", 2.0), ("streak", 4.0)):
        k = psf_kernel(kind, size, math.radians(30.0))
        assert k.sum() == pytest.approx(1.0, abs=1e-5)
    disc = psf_kernel("disc", 3.0)
    assert (disc / disc.max()).sum() == pytest.approx(math.pi * 9, rel=0.02)  # its area, px^2
    streak = psf_kernel("streak", 6.0)  # horizontal: one row (and its bilinear neighbour)
    ys, xs = np.nonzero(streak > 1e-3)
    assert xs.max() - xs.min() >= 5 and ys.max() - ys.min() <= 1
    assert psf_kernel("gaussian", 0.0) is None


def test_hires_cameras_share_the_field_of_view():
    small, big = camera_for(512, 480), camera_for(2448, 2048)
    assert math.atan(0.5 * small.width / small.fx) == pytest.approx(math.atan(0.5 * big.width / big.fx))
    assert FrameSettings(width=2448, height=2048).blur_px == pytest.approx(0.5 * 2448 / 512)
    pose = TargetPose(3.0, 0.0, 0.0, 0.0)
    assert bar_rows(pose, big) / bar_rows(pose, small) == pytest.approx(big.fy / small.fy)


def test_a_tiny_run_reports_every_key():
    args = argparse.Namespace(frames=2, hires_frames=1, conditions="baseline,jpeg70", seed=0, method="exact",
                              save_frames=None, peers=False, repeats=1)
    result = envelope.run(args)
    assert [c["name"] for c in result["conditions"]] == ["baseline", "jpeg70"]
    for c in result["conditions"]:
        for key in ("frames", "found", "detection_pct", "false_detections", "d_error_pct_mean", "d_error_pct_max",
                    "beta_error_deg_mean", "alpha_error_deg_mean", "alpha_error_deg_max", "within_3sigma_pct",
                    "ms_median", "ms_p99", "floors"):
            assert key in c
        assert c["frames"] == 2
        assert set(c["within_3sigma_pct"]) == {"d", "beta", "alpha", "mahalanobis_3d"}
    assert result["target_free"]["512x480"]["frames"] == 2
    assert {"detection_pct", "d_error_pct_max", "within_3sigma_pct", "ms_median"} <= set(result["floors"])
    text = envelope.format_table({"machine": {}, **result})
    assert "baseline" in text and "floor:" in text


def test_peer_markers_hang_beside_the_target_and_change_nothing_else():
    plain, marked = render_scene(512, 480, 0, 0), render_scene(512, 480, 0, 0, markers=True)
    assert dataclasses.replace(marked.scene, markers=()) == plain.scene
    assert [m[0] for m in marked.scene.markers] == ["aruco", "apriltag"]
    changed = np.argwhere(plain.radiance != marked.radiance)
    # the markers are printed on the wall beside the target, clear of its print
    corners = marked.camera.project(marked.scene.pose.points(np.array([-0.15, 0.15]), np.array([-0.1125, 0.1125])))
    x_print = sorted(corners[:, 0])
    assert changed.size and (changed[:, 1].max() < x_print[0] or changed[:, 1].min() > x_print[-1])
    frame = expose_frame(FrameSettings(), marked)
    found = {k: len(fn(frame.image)) for k, fn in peer_detectors(frame.camera, MARKER_SIDE).items()}
    assert found["aruco"] == 1
    assert len(detect_targets(frame.image, frame.camera)) == 1


def test_contenders_are_timed_in_turn():
    calls = []
    out = envelope.in_turn({"a": lambda im: calls.append("a") or 1, "b": lambda im: calls.append("b") or [2]},
                           np.zeros((2, 2), np.uint8), 3)
    assert calls == ["a", "b"] * 3
    assert out["a"][0] == 1 and out["b"][0] == [2] and out["a"][1] >= 0.0


def test_a_run_with_peers_reports_their_times_and_the_ratio_floor():
    args = argparse.Namespace(frames=2, hires_frames=1, conditions="baseline", seed=0, method="exact",
                              save_frames=None, peers=True, repeats=2)
    result = envelope.run(args)
    c = result["conditions"][0]
    assert c["found"] == 2 and c["false_detections"] == 0  # the markers are not targets
    assert c["peers"]["aruco"]["found"] == 2
    ratio = min(p["times_slower"] for p in c["peers"].values())
    assert c["floors"]["peer_ratio"]["value"] == pytest.approx(ratio)
    assert result["floors"]["peer_ratio"]["met"] == (ratio >= 3.0)
    text = envelope.format_table({"machine": {}, **result, "seconds": 1.0})
    assert "peers on the same frames" in text and "aruco" in text


def test_a_peers_c_level_stderr_is_silenced_and_restored(capfd):
    import os
    import sys

    with silent_c_stderr():
        os.write(2, b"Error, more than one new minima found.\n")  # as AprilTag's C code writes it
    os.write(2, b"after\n")
    print("python stderr", file=sys.stderr)
    assert capfd.readouterr().err == "after\npython stderr\n"


def test_conditions_parse_from_the_one_list():
    assert [c.name for c in parse_conditions("jpeg70, baseline")] == ["baseline", "jpeg70"]
    assert len(parse_conditions("all")) == len(NAMES)
    with pytest.raises(ValueError, match="--conditions.*did you mean 'blur2'"):
        parse_conditions("blurr2")
