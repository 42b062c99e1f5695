"""``detect_targets``: the whole pipeline of thesis Fig. 4.6 on one frame."""
from __future__ import annotations

import functools
import math
import time

import numpy as np

from localizer._kernels.measure import linear_box
from localizer._kernels.records import FrameStatus
from localizer._kernels.subpixel import edge_rows, rows_blur
from localizer._kernels.target_test import makes_target
from localizer.model.camera import Camera
from localizer.measure.exact_pose import ExactSettings, exact_measure, exact_measure_lut, exact_pose
from localizer.measure.fused import EdgeChecks, FrameTargets, detect_frame, frame_plan
from localizer.interrupts import deferred_interrupt
from localizer.numeric import check_choice
from localizer.model.observation import TargetObservation, observation_of, pose_fields
from localizer.model.params import METHODS, DetectionStats, DetectorParams
from localizer.image.pyramid import LEVEL_ROWS, detect_pyramid
from localizer.measure.pose import PoseEstimate
from localizer.search.recognize import candidate_stack, find_stacks
from localizer.image.sharpen import GAINS, unsharp_copies
from localizer.measure.subpixel_edges import subpixel_edges
from localizer.model.target import TargetSpec
from localizer.measure.target_finish import MAX_ALPHA, MAX_FIT_RMS, SRGB_TO_LINEAR, finish, window_parts
from localizer.thesis.edges import thesis_edges
from localizer.thesis.pose import thesis_pose

#: px, the per-edge error floor of a clipped target (at least): the clipped pixels hide up to
#: ~0.58 px of where a sharp edge lies, a uniform error of sd 0.58 / sqrt(12) ~ 0.17 px per edge
#: beyond the common shift
CLIPPED_FLOOR = 0.17
#: :class:`FrameStatus` codes as plain ints (compared with a fused call's table, floats)
REJECTED, REFINE = int(FrameStatus.REJECTED), int(FrameStatus.REFINE)
#: ``response="auto"``: a target's pixels are taken as sRGB-encoded (and linearized, :func:`_exact`)
#: when the exact fit's common shift of every edge towards its dark side exceeds this share of the
#: edges' blur sd (px, at least 0.5). On the envelope benchmark's frames the share is 0.22-0.41
#: through the sRGB curve and at most 0.12 with a linear response (blur, noise, flare, JPEG, Bayer)
ENCODED_SHIFT = 0.16
#: an unclipped target's common edge shift ``delta`` (the exact fit's, towards the dark side,
#: px) is at most this share of its blur sd (px, at least 0.5): a monotone response moves a
#: blurred edge's gradient peak by a fraction of its blur (the sRGB curve 0.22-0.41, a linear
#: one at most 0.12 on the envelope benchmark's targets, 512 x 480 to 2448 x 2048, blur 0.6-3.8
#: px), whereas bars narrower (or wider) than their gap by more than the blur are not a target:
#: two strokes of lettering 21, 29 and 20 px wide (a sharp 1920 x 1200 frame) fit with a shift
#: of 1.1 sd. Clipped targets (whose clipped pixels hide up to ~0.6 px of each edge) are not held to it
MAX_SHIFT_SHARE = 0.75
#: the largest normalised residual of the exact fit (on the frame's own pixels) of a target that only
#: the search of the sharpened copy found (:func:`localizer.image.sharpen.unsharp`): sharpening makes some
#: lettering pass the search's tests (an H whose crossbar a light stripe hides, strokes in noise;
#: residuals 1.32 and 4.8) that the frame's edges do not fit, where the blurred targets it is for
#: fit within their noise (blur3, the blurriest condition of the envelope benchmark, seeds 0-2: 99 %
#: of 893 targets below 0.90, the largest 1.13; the 19 found only on the copy over seeds 0-4 at most 0.75)
SHARPENED_MAX_RMS = 1.0
#: a pose whose orientation the target's edges leave open (alpha sd above
#: :data:`AMBIGUOUS_ALPHA_SD`, rad: the mirror pose not ruled out) is reported only if those edges fit
#: it within :data:`AMBIGUOUS_MAX_RMS` (normalised residual), and a pose steeper than
#: :data:`AMBIGUOUS_STEEP` (rad) within that times ``cos(alpha) / cos(AMBIGUOUS_STEEP)``. Two strokes
#: of lettering ("II" in a label, a "0" beside a label's edge) pass every test of the search and fit a
#: target of unknown sign (alpha sd 35-84 deg) whose bars are as narrow for their height as the
#: strokes: steep (54-77 deg); residuals 0.99-4.62 over the envelope benchmark's seeds 0-6 and every
#: condition (19 such finds), the ones below 1.2 all at 77 deg. True targets of open orientation:
#: the envelope's 79 (|alpha| <= 60 deg, most of them blur3) fit within 0.34; far, dim or clipped
#: test targets (9-20 m, |alpha| <= 46 deg) within 1.19; the steepest, 63 deg, within 0.25.
AMBIGUOUS_ALPHA_SD = math.radians(30.0)
AMBIGUOUS_MAX_RMS = 1.2
AMBIGUOUS_STEEP = math.radians(60.0)
#: the fields of :class:`DetectorParams` whose default (None) depends on the frame's size
RESOLVED_FIELDS = ("coarse_step", "threshold_window", "min_rows")


def as_gray(image, camera: Camera) -> np.ndarray:
    """Validate a frame and return it as a C-contiguous 2-D uint8 array.

    Raises ``ValueError`` naming what was expected: a non-empty uint8 array of
    shape ``(camera.height, camera.width)`` or ``(..., 3|4)`` channels (BGR/BGRA).
    """
    if (type(image) is np.ndarray and image.dtype == np.uint8 and image.ndim == 2 and image.size
            and image.shape == camera.shape and image.flags.c_contiguous):
        return image  # the common case, at once
    if not isinstance(image, np.ndarray):
        raise ValueError(f"expected a numpy uint8 image array, got {type(image).__name__}")
    if image.size == 0:
        raise ValueError(f"expected a non-empty uint8 image of shape {camera.shape}, got shape {image.shape}")
    if image.dtype != np.uint8:
        extra = ""
        if np.issubdtype(image.dtype, np.floating) and not np.isfinite(image).all():
            extra = " with non-finite values"
        raise ValueError(f"expected a uint8 image (grey levels 0..255), got dtype {image.dtype}{extra}")
    if image.ndim == 3 and image.shape[2] in (3, 4):
        import cv2

        image = cv2.cvtColor(image, cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY)
    elif image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim != 2:
        raise ValueError(f"expected a 2-D grey or 3-channel image, got shape {image.shape}")
    if image.shape != camera.shape:
        raise ValueError(f"image shape {image.shape} does not match the camera's (height, width) = {camera.shape}")
    return np.ascontiguousarray(image)


@functools.lru_cache(maxsize=64)
def _resolved_params(items: tuple, shape: tuple | None) -> DetectorParams:
    """Validated, resolution-resolved parameters (cached: building them costs ~0.1 ms); ``shape``
    None when ``items`` name every resolution-dependent field (a level of a large frame: its crops,
    of a new size in every frame, then share one entry)."""
    p = DetectorParams.from_kwargs(**dict(items))
    return p if shape is None else p.resolved(shape[0], shape[1])


def detect_targets(image, camera: Camera, target: TargetSpec = TargetSpec(), method: str = "exact", *,
                   stats: DetectionStats | None = None, **params) -> list[TargetObservation]:
    """Find every two-bar target in ``image`` and recover the camera pose to each.

    Args:
        image: ``(camera.height, camera.width)`` uint8 grey image (3-channel BGR is converted).
        camera: intrinsics; must match the image size.
        target: target geometry (m).
        method: ``"thesis"`` -- the thesis pipeline (half-pixel edges, eqs 4.3-4.13; a
            target is reported only if the exact model also fits it, which rejects lettering
            the thesis's verification accepts); ``"exact"`` -- subpixel edges and a
            perspective-exact least-squares pose. Both share the recognizer
            (:mod:`localizer.search.recognize`).
        stats: optional :class:`DetectionStats` filled in for this frame.
        **params: any field of :class:`DetectorParams` (thesis defaults).
    Returns:
        A list of :class:`TargetObservation`, top to bottom, left to right.

    Ctrl-C: a SIGINT received during the call raises KeyboardInterrupt when the call ends
    (:func:`localizer.interrupts.deferred_interrupt`: raised while a compiled kernel hands back
    its results, it would crash the interpreter).
    """
    t0 = time.perf_counter()
    if method not in METHODS:
        check_choice("detect_targets method", method, METHODS)
    if not isinstance(camera, Camera):
        raise ValueError(f"camera must be a localizer.Camera, got {type(camera).__name__}")
    if not isinstance(target, TargetSpec):
        raise ValueError(f"target must be a localizer.TargetSpec, got {type(target).__name__}")
    img = as_gray(image, camera)
    try:
        if not params:  # (the defaults)
            p = _resolved_params((), img.shape)
        else:
            shape = img.shape if any(params.get(n) is None for n in RESOLVED_FIELDS) else None
            p = _resolved_params(tuple(sorted(params.items())), shape)
    except TypeError:  # an unhashable parameter value: let the dataclass report it
        p = DetectorParams.from_kwargs(**params).resolved(img.shape[0], img.shape[1])
    with deferred_interrupt():
        return _detect(img, camera, p, target, method, stats, t0)


def _detect(img: np.ndarray, camera: Camera, p: DetectorParams, target: TargetSpec, method: str,
            st: DetectionStats | None, t0: float | None = None) -> list[TargetObservation]:
    """:func:`detect_targets` of a checked frame ``img`` (C-contiguous uint8 of ``camera``'s
    shape) with resolved parameters ``p``; ``st`` None: no bookkeeping (a cold call's Python is a
    good share of its time); ``t0`` the call's start (``time.perf_counter``), default now."""
    if t0 is None:
        t0 = time.perf_counter()
    if p.pyramid and img.shape[0] >= 2 * LEVEL_ROWS and not p.debug_dir:
        # a large frame: searched on a coarse level, each target measured where its blur is 1-2 px
        accepted, seconds = (st.accepted, st.seconds) if st is not None else (0, 0.0)
        out = detect_pyramid(functools.partial(_detect, target=target, method=method, st=st), img, camera, p)
        out = _drop_shared_bars(out, st)
        if st is not None:
            st.accepted = accepted + len(out)
            st.seconds = seconds + time.perf_counter() - t0
        return out
    out = _search_measure(img, img, camera, p, target, method, st)
    if not out and method == "exact" and p.sharpen_sigma > 0 and p.sharpen_amount > 0 and not p.debug_dir:
        # nothing found: the narrow runs of a steep, strongly blurred target are lost to the search,
        # which looks again on a sharpened copy (localizer.image.sharpen); edges and pose from the frame
        # (at the gains of localizer.image.sharpen.GAINS in turn, until one finds a target)
        for copy in unsharp_copies(img, p.sharpen_sigma, tuple(g * p.sharpen_amount for g in GAINS)):
            for o in _search_measure(img, copy, camera, p, target, method, st):
                if o.fit_rms <= SHARPENED_MAX_RMS:
                    out.append(o)
                elif st is not None:
                    st.reject("sharpened_fit")
            if out:
                break
    if st is not None:
        st.accepted += len(out)
        st.seconds += time.perf_counter() - t0
    return out


def _search_measure(img: np.ndarray, search_img: np.ndarray, camera: Camera, p: DetectorParams, target: TargetSpec,
                    method: str, st: DetectionStats | None) -> list[TargetObservation]:
    """One search of ``search_img`` (``img`` or its sharpened copy, same shape) and the measurement
    on ``img`` of every stack it verifies: the observations kept (``st``'s counts added, not its
    ``accepted`` and ``seconds``); the debug images of ``p.debug_dir`` written."""
    found = None
    if method == "exact" and not camera.has_distortion and not p.debug_dir:
        try:  # the common path, in one compiled call
            plan = frame_plan(p, camera.intrinsics, target.constants,
                              EdgeChecks(ENCODED_SHIFT, MAX_SHIFT_SHARE, MAX_ALPHA, MAX_FIT_RMS, CLIPPED_FLOOR))
            found = detect_frame(img, plan, SRGB_TO_LINEAR, st, None if search_img is img else search_img)
        except (np.linalg.LinAlgError, ValueError, ZeroDivisionError, FloatingPointError):
            found = None  # a degenerate measurement: step by step, each target on its own
    if found is not None:
        return _drop_shared_bars(_unambiguous(_fused(img, camera, target, p, found, st), st), st)
    out: list[TargetObservation] = []
    stacks, verified = find_stacks(search_img, camera, target, p, st, keep_candidates=bool(p.debug_dir))
    for v in verified:
        try:
            obs = _measure(img, camera, target, v, method, p)
        except (np.linalg.LinAlgError, ValueError, ZeroDivisionError, FloatingPointError):
            obs = None
        if obs is None:
            if st is not None:
                st.reject("pose")
            continue
        out.append(obs)
    out = _drop_shared_bars(_unambiguous(out, st) if method == "exact" else out, st)
    if p.debug_dir:
        from localizer.tools.annotation import write_debug_images

        write_debug_images(p.debug_dir, img, camera, p, stacks, verified, out)
    return out


def _unambiguous(found: list[TargetObservation], st: DetectionStats | None) -> list[TargetObservation]:
    """``found`` without the poses of open orientation that fit badly (:data:`AMBIGUOUS_ALPHA_SD`)."""
    keep = []
    for o in found:
        limit = AMBIGUOUS_MAX_RMS * min(1.0, math.cos(o.alpha) / math.cos(AMBIGUOUS_STEEP))
        if o.covariance[2][2] > AMBIGUOUS_ALPHA_SD ** 2 and o.fit_rms > limit:
            if st is not None:
                st.reject("ambiguous_fit")
            continue
        keep.append(o)
    return keep


def _drop_shared_bars(found: list[TargetObservation], st: DetectionStats | None) -> list[TargetObservation]:
    """``found`` without every observation whose bars overlap another's (counted as
    ``st.rejected["shared_bars"]``).

    A target's bars belong to one target only: two printed targets never overlap in the
    image (their active areas, bar 1 to bar 2 over the rows of the stack, are apart by at
    least two margins). When two candidates overlap, at least one is false, and which one
    cannot be told from its fit: in a row of equal bars every neighbouring pair fits a
    target equally well (and a true target with an equal bar at the pitch next to it is no
    longer distinguishable from such a row). So both are dropped rather than the better fit
    kept: a lost frame costs the filter one update, a false target a wrong one."""
    n = len(found)
    if n < 2:
        return found
    box = []
    for o in found:
        m = o.measurements
        box.append((m.rows[0], m.rows[1], min(m.edges_x), max(m.edges_x)))
    bad = [False] * n
    for i in range(n):
        r0, r1, x0, x1 = box[i]
        for j in range(i + 1, n):
            s0, s1, y0, y1 = box[j]
            if r0 <= s1 and s0 <= r1 and x0 < y1 and y0 < x1:
                bad[i] = bad[j] = True
    if not any(bad):
        return found
    for b in bad:
        if b and st is not None:
            st.reject("shared_bars")
    return [o for o, b in zip(found, bad) if not b]


def _exact(img: np.ndarray, camera: Camera, target: TargetSpec, v, p: DetectorParams, refine: bool = True):
    """Subpixel edges and the exact pose of the verified stack ``v`` (refined on the pixels as
    ``p.photometric`` says, when ``refine``). Returns ``(edges, bar_cx, top, bottom, pose)``:
    tuples of 4, 2, 2 and 2 pixel coordinates and the pose, None when the edges do not make
    a target (:func:`localizer._kernels.target_test.makes_target`) or the model does not fit them.

    The camera's response (``p.response``). The edges and the pixel-level refinement assume grey
    levels proportional to light. Through the sRGB curve of most USB, phone and web cameras
    (grey ~ light^(1/2.4)) a blurred edge's dark side is stretched and its bright side squeezed:
    every edge's gradient moves towards its dark side, by about a third of the blur sd on a
    printed target. The fit's common shift ``delta`` takes up the common part, not the rest (the
    tops and bottoms, and narrow runs, are measured through other windows; the refinement's
    linear blur model is wrong): on sRGB frames the range was then up to 5 sd off. So the
    target's neighbourhood is linearized through the sRGB inverse (:data:`SRGB_TO_LINEAR`) and
    measured again: with ``"srgb"`` always, with ``"auto"`` when ``delta`` says the edges are
    encoded (:data:`ENCODED_SHIFT`; never on clipped targets, whose clipping shifts their
    edges too), with ``"linear"`` never."""
    saturated = v.bright >= 250.0
    clipped = saturated or (v.dark <= 5.0)
    floor = p.edge_sigma_floor if not clipped else max(p.edge_sigma_floor, CLIPPED_FLOOR)
    view = None  # a linearized measurement: (window, box, its camera and stack or None)
    if p.response == "srgb":
        found, *view = _linear_edges_pose(img, camera, target, v, floor, p)
    else:
        edges, cxs, top, bot, est = _edges_pose(img, camera, target, v, floor, p)
        if (p.response == "auto" and est is not None and not clipped and est.edge_bias > 0.5 * ENCODED_SHIFT
                and est.edge_bias > ENCODED_SHIFT * max(_blur_sd(img, v, est), 0.5)):
            found, *view = _linear_edges_pose(img, camera, target, v, floor, p)
            if found[4] is None:  # the encoded edges made a target, the linear ones do not: keep them
                view = None
    pending = None  # the frame's camera, stack and window box, for the window's camera and stack when needed
    if view is not None:
        window, box, parts = view
        r0, c0 = box[0], box[2]
        edges, cxs = tuple(x + c0 for x in found[0]), tuple(x + c0 for x in found[1])
        top, bot, est = tuple(y + r0 for y in found[2]), tuple(y + r0 for y in found[3]), found[4]
        img = window
        if parts is not None:
            camera, v = parts
        else:
            pending = (camera, v, box)
    if est is None:
        return edges, cxs, top, bot, None
    blur = _blur_sd(img, v, est)  # (a pending window's est carries its blur: exact_measure_lut)
    if not clipped and abs(est.edge_bias) > MAX_SHIFT_SHARE * max(blur, 0.5):
        return edges, cxs, top, bot, None  # bars and gap of unequal widths: not a target
    return edges, cxs, top, bot, finish(img, camera, target, v, p, est, blur, saturated, pending, refine)


def _edges_pose(img: np.ndarray, camera: Camera, target: TargetSpec, v, floor: float, p: DetectorParams):
    """``(edges, bar_cx, top, bottom, pose)`` of the verified stack ``v`` from its edges alone
    (:func:`_exact` without the refinement and the last checks; ``floor`` the per-edge error floor, px)."""
    if camera.has_distortion:
        m = subpixel_edges(img, camera, v)
        edges, cxs, top, bot = (tuple(a.tolist()) for a in (m.edges_x, m.bar_cx, m.top_y, m.bottom_y))
        est = exact_pose(m, camera, target, v.positive, floor) if _makes_target(edges, top, bot, p) else None
        return edges, cxs, top, bot, est
    # one compiled call
    return exact_measure(img, camera, target, v, _exact_settings(floor, p))


def _linear_edges_pose(img: np.ndarray, camera: Camera, target: TargetSpec, v, floor: float, p: DetectorParams):
    """:func:`_edges_pose` of the verified stack ``v`` on its neighbourhood (:func:`_linear_box`)
    linearized through the sRGB inverse (:data:`SRGB_TO_LINEAR`). Returns ``(found, window, box,
    parts)``: ``found`` as :func:`_edges_pose`'s in the window's pixels, the uint8 window, its box
    ``(r0, r1, c0, c1)`` in the frame, and the window's camera and stack (:func:`_window_parts`)
    when they were made (a distorted camera's edges are measured in Python), else None (an
    undistorted camera's: the window made and measured in one compiled call,
    :func:`localizer.measure.exact_pose.exact_measure_lut`)."""
    box = _linear_box(img, v)
    if camera.has_distortion:
        import cv2

        window = cv2.LUT(img[box[0]:box[1], box[2]:box[3]], SRGB_TO_LINEAR)
        cam, lv = window_parts(camera, v, box)
        return _edges_pose(window, cam, target, lv, floor, p), window, box, (cam, lv)
    *found, window = exact_measure_lut(img, SRGB_TO_LINEAR, box, camera, target, v, _exact_settings(floor, p))
    return tuple(found), window, box, None


def _exact_settings(floor: float, p: DetectorParams) -> ExactSettings:
    """The compiled measurement's settings: per-edge error floor ``floor`` (px), 8 Gauss-Newton
    iterations, the target test's tolerances of ``p``."""
    return ExactSettings(floor, 8, p.width_tolerance, p.width_slack, p.min_rows)


def _linear_box(img: np.ndarray, v) -> tuple[int, int, int, int]:
    """``(r0, r1, c0, c1)``: the neighbourhood of the verified stack ``v`` (rows ``r0:r1``, columns
    ``c0:c1`` of ``img``) that is linearized (:func:`localizer._kernels.measure.linear_box`)."""
    (t0, b0), (t1, b1) = v.ends
    xb = v.bounds
    return linear_box(img.shape[0], img.shape[1], int(t0), int(b0), int(t1), int(b1), float(xb[0]), float(xb[3]))


def _makes_target(edges: tuple, top: tuple, bottom: tuple, p: DetectorParams) -> bool:
    """:func:`localizer._kernels.target_test.makes_target` with the parameters ``p``."""
    return makes_target(*edges, bottom[0] - top[0], bottom[1] - top[1], float(p.width_tolerance),
                        float(p.width_slack), float(p.min_rows))


def _blur_sd(img: np.ndarray, v, est=None) -> float:
    """The blur sd (px) of the verified stack ``v``'s row-mean profile on the rows its vertical
    edges are measured on (:func:`localizer._kernels.subpixel.rows_blur`): ``est.blur`` when its
    pose ``est`` (measured on ``img``) carries it (:func:`localizer.measure.exact_pose.exact_measure`)."""
    if est is not None and not math.isnan(est.blur):
        return est.blur
    bounds = np.asarray(v.bounds, np.float64)
    return float(rows_blur(img, edge_rows(img, v.rows, bounds), bounds))


def _measure(img: np.ndarray, camera: Camera, target: TargetSpec, v, method: str,
             p: DetectorParams) -> TargetObservation | None:
    if method == "thesis":
        m = thesis_edges(img, camera, v, int(p.edge_window))
        edges, cxs, top, bot = (tuple(a.tolist()) for a in (m.edges_x, m.bar_cx, m.top_y, m.bottom_y))
        if not _makes_target(edges, top, bot, p):
            return None
        est = thesis_pose(m, camera, target)
        # the thesis's verification lets some lettering through (strokes of an "m" or "n");
        # a target is reported only if the perspective-exact model fits its subpixel edges too
        if _exact(img, camera, target, v, p, refine=False)[4] is None:
            return None
    else:
        edges, cxs, top, bot, est = _exact(img, camera, target, v, p)
        if est is None:
            return None
    return observation_of(edges, cxs, top, bot, (int(v.rows[0]), int(v.rows[-1])), v.dark, v.bright, v.polarity,
                          method, pose_fields(est))


def _fused(img: np.ndarray, camera: Camera, target: TargetSpec, p: DetectorParams, f: FrameTargets,
           st: DetectionStats | None) -> list[TargetObservation]:
    """The observations of the fused call's verified stacks (:func:`localizer.measure.fused.detect_frame`),
    top to bottom, left to right: each ``ACCEPTED`` one, and each ``REFINE`` one refined and
    checked by :func:`localizer.measure.target_finish.finish` (as :func:`_exact` would); ``REJECTED`` ones
    counted as ``st.rejected["pose"]``."""
    found = enumerate(f.targets)
    if len(f.targets) > 1:  # (the search's order: top to bottom, left to right, as find_stacks)
        found = sorted(found, key=lambda jt: (jt[1].row0, jt[1].x0))
    out = []
    for j, t in found:
        status = t.status
        if status == REJECTED:
            if st is not None:
                st.reject("pose")
            continue
        cov = f.covariances[j]
        pose = (t.distance, t.beta, t.alpha, t.z, t.x, t.height, cov, (t.alpha1, t.alpha2), t.n_solutions > 1,
                t.edge_bias, math.sqrt(t.chi2 / 3.0))
        if status == REFINE:
            v = candidate_stack(f.rows, f.x, f.candidates[int(t.candidate)].tolist())
            pixels, pending = img, None
            if t.linear:
                import cv2

                box = (int(t.r0), int(t.r1), int(t.c0), int(t.c1))
                pixels, pending = cv2.LUT(img[box[0]:box[1], box[2]:box[3]], SRGB_TO_LINEAR), (camera, v, box)
            est = PoseEstimate(*pose, t.blur)
            try:
                est = finish(pixels, camera, target, v, p, est, t.blur, t.bright >= 250.0, pending)
            except (np.linalg.LinAlgError, ValueError, ZeroDivisionError, FloatingPointError):
                est = None
            if est is None:
                if st is not None:
                    st.reject("pose")
                continue
            pose = pose_fields(est)
        out.append(observation_of((t.edge0, t.edge1, t.edge2, t.edge3), (t.bar_cx1, t.bar_cx2), (t.top1, t.top2),
                                  (t.bottom1, t.bottom2), (int(t.row0), int(t.row1)), t.dark, t.bright,
                                  "positive" if t.positive else "negative", "exact", pose))
    return out


