"""The common path of ``detect_targets`` over one frame, in one compiled call.

For the ``exact`` method on an undistorted camera: the search
(:func:`localizer._kernels.search.recognize`), then for each verified stack the subpixel edges
and the exact pose (:func:`localizer._kernels.measure.measure`), on the sRGB-linearized
window where the camera's response says so, and the checks of
:func:`localizer.detect.detect_targets` that need no more than the pose. Only the
photometric refinement, where a target falls short, is left to Python
(:data:`~localizer._kernels.records.FrameStatus` ``REFINE``). A cold call of the detector (a
camera frame after other work) spent about as long in the Python between these steps as in
the steps.

Its callees are compiled into it, and numba's cache keys on this file alone: after a change
to a callee, the cached ``detect_frame`` in ``__pycache__`` is the old code until removed
(``make clean-kernels``).
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit
from localizer._kernels.measure import linear_box, measure, measure_lut
from localizer._kernels.records import (EXACT_RESULT, EXACT_SETTINGS, INTRINSICS, TARGET_CONSTANTS, FrameStatus, FusedColumn,
                                        FusedTarget)
from localizer._kernels.search import recognize


#: the columns of the result table (:class:`~localizer._kernels.records.FusedTarget`)
N_FIELDS = len(FusedTarget._fields)


@jit
def detect_frame(image, search_image, search, settings, lut):
    """The search of ``search_image`` and the measurement of every verified stack on ``image``.

    Args:
        image: ``(H, W)`` uint8 grey frame, C-contiguous.
        search_image: ``(H, W)`` uint8, the frame the search runs on: ``image`` itself, or its
            sharpened copy (:func:`localizer.image.sharpen.unsharp`; the stacks' positions, bar ends and
            grey levels are then those of the copy, the edges and the pose those of ``image``).
        search: ``(1,)`` :data:`~localizer._kernels.records.SEARCH_SETTINGS` record.
        settings: ``(1,)`` :data:`~localizer._kernels.records.MEASURE_SETTINGS` record.
        lut: ``(256,)`` uint8, the sRGB inverse (:data:`localizer.detect.SRGB_TO_LINEAR`).

    Returns ``(search_result, table)``: the :class:`~localizer._kernels.records.SearchResult`,
    and per verified stack, in the search's order, a row of the ``(V, F)`` float64 table of
    :class:`~localizer._kernels.records.FusedTarget` fields (columns
    :class:`~localizer._kernels.records.FusedColumn`).

    Per stack, as :func:`localizer.detect._exact` in Python: a target whose bright side reaches
    250 or dark side 5 is clipped (its per-edge floor ``clipped_floor``; never linearized by
    ``auto_response``, never held to the shift test); ``srgb`` measures the linearized window
    (:func:`~localizer._kernels.measure.linear_box`) alone, ``auto_response`` measures it too when
    the edges' common shift towards the dark side exceeds ``0.5 encoded_shift`` px and
    ``encoded_shift`` times the blur sd (at least 0.5 px), and takes it when it makes a target.
    A pose whose shift exceeds ``max_shift_share`` times the blur sd is rejected (bars and gap
    of unequal widths); one the photometric settings would refine is ``REFINE``; else it is
    ``ACCEPTED`` when in front of the camera, ``|alpha| < max_alpha``, its normalised residual
    below ``max_fit_rms`` and its covariance finite.
    """
    sr = recognize(search_image, search)
    cand = sr.candidates
    nv = 0
    for i in range(cand.size):
        if cand[i].verified:
            nv += 1
    table = np.zeros((nv, N_FIELDS))
    if nv == 0:
        return sr, table
    s = settings[0]
    # (the measurement's arguments as records, the types its Python callers pass: one compiled measure)
    cam = np.zeros(1, INTRINSICS)
    cam[0].fx, cam[0].fy, cam[0].cx, cam[0].cy = s.fx, s.fy, s.cx, s.cy
    tc = np.zeros(1, TARGET_CONSTANTS)
    tc[0].bar_width, tc[0].bar_height, tc[0].margin = s.bar_width, s.bar_height, s.margin
    es = np.zeros(2, EXACT_SETTINGS)  # (not clipped, clipped)
    for k in range(2):
        es[k].sigma_floor = s.clipped_floor if k else s.sigma_floor
        es[k].iterations = s.iterations
        es[k].width_tolerance = s.width_tolerance
        es[k].width_slack = s.width_slack
        es[k].min_rows = s.min_rows
    h, w = image.shape
    e = np.empty((2, 2), np.int64)
    bounds = np.empty(4)  # (a plain array: the measurement's types those of its Python callers)
    results = np.zeros(2, EXACT_RESULT)  # a stack's measurement on the frame's pixels, on the linearized window
    j = 0
    for i in range(cand.size):
        cd = cand[i]
        if not cd.verified:
            continue
        saturated = cd.bright >= 250.0
        clipped = saturated or cd.dark <= 5.0
        st = es[1:2] if clipped else es[0:1]
        stack_rows = sr.rows[cd.start:cd.stop]
        for k in range(4):
            bounds[k] = cd.median_x[k]
        e[0, 0], e[0, 1], e[1, 0], e[1, 1] = cd.top1, cd.bottom1, cd.top2, cd.bottom2
        box = linear_box(h, w, cd.top1, cd.bottom1, cd.top2, cd.bottom2, bounds[0], bounds[3])
        linear = False
        if s.srgb:
            results[1] = measure_lut(image, lut, box, stack_rows, bounds, e, cd.positive, cam, tc, st)[0][0]
            linear = True
        else:
            results[0] = measure(image, stack_rows, bounds, e, cd.positive, cam, tc, st)[0]
            r = results[0]
            if (s.auto_response and r.found and not clipped and r.edge_bias > 0.5 * s.encoded_shift
                    and r.edge_bias > s.encoded_shift * at_least(r.blur, 0.5)):
                results[1] = measure_lut(image, lut, box, stack_rows, bounds, e, cd.positive, cam, tc, st)[0][0]
                linear = results[1].found  # the encoded edges made a target, the linear ones do not: keep them
        r = results[1] if linear else results[0]
        status = decide(r, s, saturated, clipped)
        row = table[j]
        row[FusedColumn.STATUS] = status.value
        row[FusedColumn.WIDE] = status == FrameStatus.REFINE and saturated and uncertain(r, s)
        row[FusedColumn.LINEAR] = linear
        row[FusedColumn.CANDIDATE] = i
        row[FusedColumn.ROW0] = stack_rows[0]
        row[FusedColumn.ROW1] = stack_rows[stack_rows.size - 1]
        row[FusedColumn.X0] = sr.x[cd.start, 0]
        row[FusedColumn.POSITIVE] = cd.positive
        row[FusedColumn.DARK] = cd.dark
        row[FusedColumn.BRIGHT] = cd.bright
        r0, r1, c0, c1 = box
        row[FusedColumn.R0], row[FusedColumn.R1], row[FusedColumn.C0], row[FusedColumn.C1] = r0, r1, c0, c1
        if not linear:  # (the window's pixels moved back to the frame's)
            r0, c0 = 0, 0
        row[FusedColumn.EDGE0], row[FusedColumn.EDGE1] = r.edge0 + c0, r.edge1 + c0
        row[FusedColumn.EDGE2], row[FusedColumn.EDGE3] = r.edge2 + c0, r.edge3 + c0
        row[FusedColumn.BAR_CX1], row[FusedColumn.BAR_CX2] = r.bar_cx1 + c0, r.bar_cx2 + c0
        row[FusedColumn.TOP1], row[FusedColumn.TOP2] = r.top1 + r0, r.top2 + r0
        row[FusedColumn.BOTTOM1], row[FusedColumn.BOTTOM2] = r.bottom1 + r0, r.bottom2 + r0
        row[FusedColumn.DISTANCE], row[FusedColumn.BETA], row[FusedColumn.ALPHA] = r.distance, r.beta, r.alpha
        row[FusedColumn.Z], row[FusedColumn.X], row[FusedColumn.HEIGHT] = r.z, r.x, r.height
        row[FusedColumn.EDGE_BIAS], row[FusedColumn.ALPHA1], row[FusedColumn.ALPHA2] = r.edge_bias, r.alpha1, r.alpha2
        row[FusedColumn.N_SOLUTIONS], row[FusedColumn.CHI2], row[FusedColumn.BLUR] = r.n_solutions, r.chi2, r.blur
        for a in range(3):
            for b in range(3):
                row[FusedColumn.COV00 + 3 * a + b] = r.cov[a, b]
        j += 1
    return sr, table


@jit
def at_least(x, low):
    """Python's ``max(x, low)``: ``x`` unless ``low`` is greater (so NaN stays NaN)."""
    return low if low > x else x


@jit
def uncertain(r, s):
    """Whether the edge-based pose ``r`` (an EXACT_RESULT record) falls short of what the
    refinement is for: orientation variance above ``s.refine_alpha_var`` or range sd above
    ``s.refine_range_sd`` of the range."""
    t = s.refine_range_sd * r.distance
    return abs(r.cov[2, 2]) > s.refine_alpha_var or abs(r.cov[0, 0]) > t * t


@jit
def decide(r, s, saturated, clipped):
    """The :class:`~localizer._kernels.records.FrameStatus` of the measurement ``r`` (its
    blur and shift, ``s`` the :data:`~localizer._kernels.records.MEASURE_SETTINGS` row)."""
    if not r.found:
        return FrameStatus.REJECTED
    if not clipped and abs(r.edge_bias) > s.max_shift_share * at_least(r.blur, 0.5):
        return FrameStatus.REJECTED  # bars and gap of unequal widths: not a target
    if r.z > 0 and math.isfinite(r.distance):
        if s.refine_all or (s.refine_clipped and saturated) or (s.refine_auto and uncertain(r, s)):
            return FrameStatus.REFINE
    if not (r.z > 0 and math.isfinite(r.distance) and abs(r.alpha) < s.max_alpha
            and math.sqrt(r.chi2 / 3.0) < s.max_fit_rms):
        return FrameStatus.REJECTED
    for i in range(3):
        for k in range(3):
            if not math.isfinite(r.cov[i, k]):
                return FrameStatus.REJECTED
    return FrameStatus.ACCEPTED
