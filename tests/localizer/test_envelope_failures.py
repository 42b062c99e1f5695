"""Frames of the envelope benchmark (independent renders: a printed target on a cluttered wall
through a real camera's optics and sensor) that the localizer once got wrong: lettering taken
for a target, and covariances too small through the sRGB curve."""
from __future__ import annotations

import math

import numpy as np
import pytest

from agvsim.bench.envelope_conditions import BY_NAME, CHI2_3D_3SIGMA, GATE_BETA, GATE_DISTANCE
from agvsim.bench.envelope_frames import make_frame
from localizer import detect_targets


def _matches(o, pose) -> bool:
    return abs(o.beta - pose.beta) < GATE_BETA and abs(o.distance / pose.distance - 1.0) < GATE_DISTANCE


def _errors(o, pose) -> tuple[np.ndarray, float]:
    """Errors in sd of the reported covariance (d, beta, alpha) and the 3-D Mahalanobis distance squared."""
    e = np.array([o.distance - pose.distance, o.beta - pose.beta, math.remainder(o.alpha - pose.alpha, 2 * math.pi)])
    c = np.asarray(o.covariance)
    return np.abs(e) / np.sqrt(np.diag(c)), float(e @ np.linalg.solve(c, e))


@pytest.mark.parametrize("condition, index", [("defocus", 108), ("motion_diag", 108), ("very_noisy", 108),
                                              ("flare", 108), ("saturated", 140)])
def test_lettering_beside_a_target_is_not_a_target(condition, index):
    # before: a U's right stroke and an L's (frame 108: the U's bowl and the L's foot turn out of
    # the side margins below the stack's last row) and a J's stem beside an O (frame 140, the J's
    # hat) were reported besides the true target
    frame = make_frame(BY_NAME[condition].settings, 0, index)
    obs = detect_targets(frame.image, frame.camera)
    assert len(obs) == 1
    assert _matches(obs[0], frame.scene.pose)


def test_a_stroke_beside_a_light_strip_is_not_a_target():
    # before: an I's stroke, a light strip across an H and the H's other stroke (bars of unequal
    # width: the exact fit's normalised residual 6.5) on a 1280 x 1024 frame without a target
    frame = make_frame(BY_NAME["hires_1280"].settings, 0, 21, with_target=False)
    assert detect_targets(frame.image, frame.camera) == []


#: gamma frames whose range was 4.4-5.4 sd off before the pixels were linearized
GAMMA_FRAMES = (79, 127, 169, 176, 283, 285)


def test_srgb_encoded_targets_are_measured_within_their_covariance():
    worst = []
    for index in GAMMA_FRAMES:
        frame = make_frame(BY_NAME["gamma"].settings, 0, index)
        found = [o for o in detect_targets(frame.image, frame.camera) if _matches(o, frame.scene.pose)]
        assert len(found) == 1
        z, m2 = _errors(found[0], frame.scene.pose)
        worst.append((z.max(), m2))
    assert max(z for z, _ in worst) <= 3.0
    assert max(m2 for _, m2 in worst) <= CHI2_3D_3SIGMA


def test_response_choices():
    frame = make_frame(BY_NAME["gamma"].settings, 0, GAMMA_FRAMES[0])
    pose = frame.scene.pose
    # refined on its pixels (photometric="all"), whose model assumes light-proportional grey levels
    auto = detect_targets(frame.image, frame.camera, photometric="all")
    srgb = detect_targets(frame.image, frame.camera, response="srgb", photometric="all")
    linear = detect_targets(frame.image, frame.camera, response="linear", photometric="all")
    assert len(auto) == len(srgb) == len(linear) == 1
    assert auto[0].distance == srgb[0].distance and auto[0].alpha == srgb[0].alpha
    assert _errors(linear[0], pose)[0][0] > 3.0  # the pixels as they are: the range 5 sd off
    # a linear frame is measured as it is: "auto" and "linear" agree to the bit
    base = make_frame(BY_NAME["baseline"].settings, 0, GAMMA_FRAMES[0])
    a = detect_targets(base.image, base.camera)
    b = detect_targets(base.image, base.camera, response="linear")
    assert [(o.distance, o.beta, o.alpha) for o in a] == [(o.distance, o.beta, o.alpha) for o in b]
    with pytest.raises(ValueError, match="response"):
        detect_targets(frame.image, frame.camera, response="gamma")


def test_srgb_inverse_table():
    from localizer.detect import SRGB_TO_LINEAR

    assert SRGB_TO_LINEAR[0] == 0 and SRGB_TO_LINEAR[255] == 255
    assert np.all(np.diff(SRGB_TO_LINEAR.astype(int)) >= 0)
    assert SRGB_TO_LINEAR[128] == 55  # sRGB mid-grey is 21.6 % of full scale


def test_a_blurred_targets_orientation_is_not_the_pixel_models_alone():
    # blur3 frame 181 (84 rows, 2.08 m, alpha 11.4 deg): the edges said 11.56 deg (sd 1.5), the
    # photometric refinement 8.35 (its own sd 0.06): 3.07 deg off, over the 3-deg floor. Now their mean (9.95)
    # when it is refined (photometric="all"; "auto" keeps the edges' answer of a sd under 2 deg)
    frame = make_frame(BY_NAME["blur3"].settings, 0, 181)
    pose = frame.scene.pose
    found = [o for o in detect_targets(frame.image, frame.camera, photometric="all") if _matches(o, pose)]
    assert len(found) == 1
    assert abs(math.degrees(found[0].alpha - pose.alpha)) < 2.0
    assert _errors(found[0], pose)[0].max() <= 3.0
    # the range is the refinement's (the edges' is 3.8 mm off, the refinement's 1.4 mm)
    off = detect_targets(frame.image, frame.camera, photometric="off")
    assert abs(found[0].distance - pose.distance) < abs(off[0].distance - pose.distance)


def test_two_strokes_of_lettering_are_not_a_target_on_a_coarser_level():
    # before: on the 960 x 600 level of a sharp 1920 x 1200 frame two strokes of lettering (21, 29
    # and 20 px: bars narrower than their gap by more than a blur explains; the exact fit's common
    # edge shift 1.1 blur sd, localizer.detect.MAX_SHIFT_SHARE) were reported beside the target
    from localizer.image.pyramid import level_image

    frame = make_frame(BY_NAME["hires_1920"].settings, 0, 25)
    cam = frame.camera.scaled(frame.camera.width // 2, frame.camera.height // 2)
    obs = detect_targets(level_image(frame.image, 2), cam, pyramid=False)
    assert len(obs) == 1 and _matches(obs[0], frame.scene.pose)


@pytest.mark.parametrize("condition, index", [("blur3_1280", 26), ("blur3_1280", 31), ("blur3_1280", 39),
                                              ("blur3_2448", 26)])
def test_blurred_high_resolution_targets_are_found_and_measured(condition, index):
    # the thesis camera's 3 px of blur on 1280 x 1024 (7.5 px) and 2448 x 2048 (14 px) sensors.
    # Before: the range from the frame's own pixels 6.0 % (frame 26), 3.7 % (39) off; frame 31 (75
    # rows) missed on the coarse level (its segments' spread taken over the blurred bar ends); frame
    # 26 (bars 2.4 blur sd wide) 3.2 / 7.6 alpha sd off (blur floor of an underestimated blur)
    frame = make_frame(BY_NAME[condition].settings, 0, index)
    found = [o for o in detect_targets(frame.image, frame.camera) if _matches(o, frame.scene.pose)]
    assert len(found) == 1
    z, m2 = _errors(found[0], frame.scene.pose)
    assert abs(found[0].distance / frame.scene.pose.distance - 1.0) < 0.02
    assert z.max() <= 3.0 and m2 <= CHI2_3D_3SIGMA


def test_the_compiled_linearized_window_is_the_python_one():
    # exact_measure_lut makes the sRGB-linearized window, its camera and stack in the compiled call:
    # the very numbers of the window cut, linearized (cv2.LUT) and measured from Python
    import dataclasses

    import cv2

    from localizer.detect import SRGB_TO_LINEAR
    from localizer.measure.exact_pose import ExactSettings, exact_measure, exact_measure_lut
    from localizer.model.params import DetectionStats, DetectorParams
    from localizer.search.recognize import find_stacks
    from localizer.model.target import TargetSpec

    frame = make_frame(BY_NAME["gamma"].settings, 0, 3)
    img, cam, tg = frame.image, frame.camera, TargetSpec()
    p = DetectorParams().resolved(*img.shape)
    v = find_stacks(img, cam, tg, p, DetectionStats())[1][0]
    r0, r1, c0, c1 = box = (int(v.rows[0]) - 20, int(v.rows[-1]) + 21, int(v.bounds[0]) - 15, int(v.bounds[3]) + 16)
    args = ExactSettings(0.05, 8, p.width_tolerance, p.width_slack, p.min_rows)
    *compiled, window = exact_measure_lut(img, SRGB_TO_LINEAR, box, cam, tg, v, args)
    by_hand = cv2.LUT(img[r0:r1, c0:c1], SRGB_TO_LINEAR)
    lv = dataclasses.replace(v, rows=v.rows - r0, x=v.x - c0, ends=tuple((a - r0, b - r0) for a, b in v.ends),
                             median_x=v.median_x - c0)
    python = exact_measure(by_hand, cam.cropped(c0, r0, c1, r1), tg, lv, args)
    assert np.array_equal(window, by_hand)
    assert compiled[:4] == list(python[:4]) and compiled[4] is not None
    assert compiled[4].covariance.tolist() == python[4].covariance.tolist()
    assert (compiled[4].distance, compiled[4].alpha, compiled[4].blur) == (python[4].distance, python[4].alpha,
                                                                           python[4].blur)


@pytest.mark.parametrize("condition, seed, index", [("blur1", 1, 284), ("blur2", 2, 139), ("hires_1920", 3, 38),
                                                    ("blur1", 5, 19), ("webcam", 5, 19), ("defocus", 5, 19)])
def test_two_strokes_of_open_orientation_that_fit_badly_are_not_a_target(condition, seed, index):
    # before: the "II" of a label (seeds 1, 3, 5) and a "0" beside a label's edge (seed 2) were
    # reported beside the true target: steep poses (54-77 deg) of open sign (alpha sd 35-70 deg)
    # that the strokes' edges fit with residuals of 0.99-4.06 (localizer.detect.AMBIGUOUS_ALPHA_SD)
    from localizer import DetectionStats

    frame = make_frame(BY_NAME[condition].settings, seed, index)
    st = DetectionStats()
    obs = detect_targets(frame.image, frame.camera, stats=st)
    assert len(obs) == 1 and _matches(obs[0], frame.scene.pose)
    assert st.rejected.get("ambiguous_fit", 0) >= 1


@pytest.mark.parametrize("seed, index", [(2, 4), (5, 29), (6, 9)])
def test_a_small_blurred_target_is_confirmed_on_its_crop(seed, index):
    # blur3_1280 (7.5 px): steep targets (51-60 deg) 3.7-4.3 m away, 67-83 rows. Before: the crop
    # that confirms a target of the coarse level was scanned at the frame's line spacing, three or
    # four lines across the bars in another phase than the level's, and none passed: not reported
    # (localizer.image.pyramid.CROP_LINES)
    frame = make_frame(BY_NAME["blur3_1280"].settings, seed, index)
    found = [o for o in detect_targets(frame.image, frame.camera) if _matches(o, frame.scene.pose)]
    assert len(found) == 1
    z, m2 = _errors(found[0], frame.scene.pose)
    assert abs(found[0].distance / frame.scene.pose.distance - 1.0) < 0.02
    assert z.max() <= 3.0 and m2 <= CHI2_3D_3SIGMA


def test_a_target_the_crop_confirms_is_measured_there_not_on_the_search_level(monkeypatch):
    # blur3_2448 seed 2 frame 4 (14 px, 60 deg, 4.3 m): at the frame's line spacing its crop finds
    # nothing, and its measurement on the search level (no pixel-level refinement) is reported
    import localizer.image.pyramid as pyramid

    frame = make_frame(BY_NAME["blur3_2448"].settings, 2, 4)
    error = lambda: [abs(o.distance / frame.scene.pose.distance - 1.0)  # noqa: E731
                     for o in detect_targets(frame.image, frame.camera) if _matches(o, frame.scene.pose)]
    assert len(error()) == 1 and error()[0] < 0.02
    monkeypatch.setattr(pyramid, "CROP_LINES", 1)  # lines as far apart as the frame's (11 level rows)
    assert len(error()) == 1 and error()[0] > 0.02
