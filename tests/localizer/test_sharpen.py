"""The second search on a sharpened copy (localizer.image.sharpen, detect._detect): where the search of a
frame finds nothing, an unsharp-masked copy is searched, and what it finds is measured on the
frame's own pixels and kept only if those edges fit a target."""
from __future__ import annotations

import math

import numpy as np
import pytest

import localizer.detect
import localizer.image.sharpen
from agvsim.bench.envelope_conditions import BY_NAME
from agvsim.bench.envelope_frames import make_frame
from localizer import DetectionStats, DetectorParams, detect_targets
from localizer.image.sharpen import unsharp

#: envelope frames (seed, index) whose steep, blurred target (blur sd 3 px at 512 x 480, |alpha|
#: 48-60 deg, 3.7-4.6 m) the search of the frame itself loses
STEEP_BLURRED = ((2, 169), (2, 207), (2, 287), (4, 146), (4, 183))


def test_unsharp_keeps_flat_areas_and_steepens_a_blurred_edge():
    flat = np.full((40, 60), 117, np.uint8)
    assert np.array_equal(unsharp(flat, 3.0, 1.0), flat)
    x = np.arange(60.0)
    step = np.tile(np.clip(np.rint(60 + 120 / (1 + np.exp(-(x - 30) / 2.0))), 0, 255).astype(np.uint8), (40, 1))
    out = unsharp(step, 3.0, 1.0)
    assert out.dtype == np.uint8 and out.shape == step.shape and out.flags.c_contiguous
    assert np.array_equal(unsharp(step, 3.0, 0.0), step)
    rise = lambda im: np.abs(np.diff(im[20].astype(int))).max()  # noqa: E731
    assert rise(out) >= 1.2 * rise(step)
    assert out[20, :8].tolist() == step[20, :8].tolist()  # far from the edge: unchanged


@pytest.mark.parametrize("seed, index", STEEP_BLURRED)
def test_steep_blurred_targets_are_found_on_the_sharpened_copy_and_measured_on_the_frame(monkeypatch, seed, index):
    f = make_frame(BY_NAME["blur3"].settings, seed, index)
    truth = f.scene.pose
    calls = []
    fused = localizer.detect.detect_frame

    def spy(image, plan, lut, stats, search_image=None):
        calls.append((image is f.image, search_image is not None))
        return fused(image, plan, lut, stats, search_image)

    monkeypatch.setattr(localizer.detect, "detect_frame", spy)
    found = detect_targets(f.image, f.camera)
    assert calls == [(True, False), (True, True)]  # the frame searched, then its copy; both measured on the frame
    assert len(found) == 1
    o = found[0]
    e = np.array([o.distance - truth.distance, o.beta - truth.beta, math.remainder(o.alpha - truth.alpha, 2 * math.pi)])
    assert abs(e[0]) < 0.02 * truth.distance and abs(e[2]) < math.radians(3.0)
    assert float(e @ np.linalg.solve(o.covariance, e)) < 14.2  # within the covariance (chi-square 3, p = 0.003)
    assert detect_targets(f.image, f.camera, sharpen_sigma=0.0) == []  # the second search found it


def test_a_find_of_the_copy_that_the_frames_edges_do_not_fit_is_dropped():
    # a target-free 1920 x 1200 frame: lettering (an H whose crossbar a light stripe hides) passes the
    # search of the sharpened coarse level, and its edges on the level fit no target (residual 1.3)
    f = make_frame(BY_NAME["hires_1920"].settings, 0, 21, with_target=False)
    st = DetectionStats()
    assert detect_targets(f.image, f.camera, stats=st) == []
    # (its pose is also of open orientation: the gate of detect.AMBIGUOUS_ALPHA_SD sees it first)
    assert st.rejected.get("sharpened_fit", 0) + st.rejected.get("ambiguous_fit", 0) == 1
    assert detect_targets(f.image, f.camera, sharpen_sigma=0.0) == []


def test_a_frame_with_a_target_is_not_searched_twice(monkeypatch):
    f = make_frame(BY_NAME["baseline"].settings, 0, 0)
    monkeypatch.setattr(localizer.detect, "unsharp_copies", lambda *a: pytest.fail("searched twice"))
    assert len(detect_targets(f.image, f.camera)) == 1


@pytest.mark.parametrize("field, value", [("sharpen_sigma", -1.0), ("sharpen_amount", float("nan")),
                                          ("sharpen_sigma", "3")])
def test_bad_sharpen_settings_are_refused_by_name(field, value):
    with pytest.raises(ValueError, match=f"DetectorParams.{field}"):
        DetectorParams(**{field: value})


@pytest.mark.parametrize("condition, seed, index", [("blur2", 1, 286), ("blur3_1280", 5, 29)])
def test_the_copy_at_twice_the_gain_is_searched_where_the_first_finds_nothing(monkeypatch, condition, seed, index):
    # targets that neither the frame's search nor that of the copy at gain 1 finds, and the copy at
    # gain 2 does (localizer.image.sharpen.GAINS)
    import localizer.image.sharpen

    f = make_frame(BY_NAME[condition].settings, seed, index)
    truth = f.scene.pose
    found = detect_targets(f.image, f.camera)
    assert len(found) == 1 and abs(found[0].distance / truth.distance - 1.0) < 0.02
    monkeypatch.setattr(localizer.detect, "GAINS", localizer.image.sharpen.GAINS[:1])
    assert detect_targets(f.image, f.camera) == []


def test_unsharp_copies_blur_once_and_match_unsharp():
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (48, 64), dtype=np.uint8)
    copies = list(localizer.image.sharpen.unsharp_copies(img, 2.0, (1.0, 2.0)))
    assert [np.array_equal(c, unsharp(img, 2.0, a)) for c, a in zip(copies, (1.0, 2.0))] == [True, True]
