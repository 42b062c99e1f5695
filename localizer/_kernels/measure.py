"""The per-target path of ``detect_targets`` for an undistorted camera, fused in one call.

Subpixel edges (:func:`localizer._kernels.subpixel.subpixel`), the target test
(:func:`localizer._kernels.target_test.makes_target`) and the exact pose fit
(:func:`localizer._kernels.exact_pose.fit`) of one verified stack: Python between
these steps cost as much as the steps.

Its callees are compiled into it, and numba's cache keys on this file alone: after a change
to a callee, the cached ``measure`` in ``__pycache__`` is the old code until removed.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit
from localizer._kernels.exact_pose import fit
from localizer._kernels.records import EXACT_RESULT, FitStatus, Intrinsics, TargetConstants
from localizer._kernels.subpixel import blur_floor, edge_rows, rows_blur, subpixel
from localizer._kernels.target_test import makes_target


@jit
def measure(image, stack_rows, bounds, ends, positive, camera, target, settings):
    """The subpixel edges, the target test and the exact pose of one verified stack of ``image``.

    Args:
        image: ``(H, W)`` uint8 frame, C-contiguous.
        stack_rows: ``(n,)`` int64 rows of the verified stack.
        bounds: ``(4,)`` float64 median run boundaries of the stack (columns).
        ends: ``(2, 2)`` int64 rough bar ends (rows): ``[[top1, bottom1], [top2, bottom2]]``.
        positive: target polarity (black bars on white).
        camera: ``(1,)`` :data:`~localizer._kernels.records.INTRINSICS` record (px).
        target: ``(1,)`` :data:`~localizer._kernels.records.TARGET_CONSTANTS` record (m).
        settings: ``(1,)`` :data:`~localizer._kernels.records.EXACT_SETTINGS` record.

    Returns a new ``(1,)`` :data:`~localizer._kernels.records.EXACT_RESULT` record: ``found``
    False when the edges do not make a target or no fit converged (the pose is then zeros
    and the covariance the identity); the edges (px) in either case. The one compiled
    measurement: :func:`localizer.measure.exact_pose.exact_measure` and the fused frame call
    (:func:`localizer._kernels.frame.detect_frame`) call it with the same argument types.
    """
    out = np.zeros(1, EXACT_RESULT)
    c, t = camera[0], target[0]
    measure_into(out[0], image, stack_rows, bounds, ends, positive, Intrinsics(c.fx, c.fy, c.cx, c.cy),
                 TargetConstants(t.bar_width, t.bar_height, t.margin), settings[0])
    return out


@jit
def measure_lut(image, lut, box, stack_rows, bounds, ends, positive, camera, target, settings):
    """:func:`measure` of the window ``box = (r0, r1, c0, c1)`` (rows ``r0:r1``, columns
    ``c0:c1``) of ``image`` with every grey level passed through ``lut`` ``(256,)`` uint8 (the
    sRGB inverse of :data:`localizer.detect.SRGB_TO_LINEAR`): the window's own camera (principal
    point moved by ``(c0, r0)``) and the stack ``stack_rows``, ``bounds``, ``ends`` (frame
    pixels) moved likewise, in one call (in Python the window, its camera and its stack cost
    more than the measurement). Returns ``(result, window)``: the
    :data:`~localizer._kernels.records.EXACT_RESULT` record, in the window's pixels, and the
    ``(r1 - r0, c1 - c0)`` uint8 window it was measured on."""
    r0, r1, c0, c1 = box[0], box[1], box[2], box[3]
    win = np.empty((r1 - r0, c1 - c0), np.uint8)
    for i in range(r1 - r0):
        src = image[r0 + i]
        dst = win[i]
        for j in range(c1 - c0):
            dst[j] = lut[src[c0 + j]]
    ew = np.empty((2, 2), np.int64)
    ew[0, 0], ew[0, 1], ew[1, 0], ew[1, 1] = ends[0, 0] - r0, ends[0, 1] - r0, ends[1, 0] - r0, ends[1, 1] - r0
    c = camera[0]
    out = np.zeros(1, EXACT_RESULT)
    t = target[0]
    measure_into(out[0], win, stack_rows - r0, bounds - c0, ew, positive, Intrinsics(c.fx, c.fy, c.cx - c0, c.cy - r0),
                 TargetConstants(t.bar_width, t.bar_height, t.margin), settings[0])
    return out, win


@jit
def linear_box(h, w, t0, b0, t1, b1, x0, x3):
    """``(r0, r1, c0, c1)``: the neighbourhood (rows ``r0:r1``, columns ``c0:c1`` of an ``(h, w)``
    frame) of a verified stack whose bars run from rows ``t0``-``b0`` and ``t1``-``b1`` (its rough
    ends) over columns ``x0``-``x3`` (its outer median run boundaries) that is linearized: the
    bars, their margins (a quarter of a bar) and the blur's reach."""
    pad_r = (max(b0, b1) - min(t0, t1) + 1) // 2 + 12
    pad_c = int(x3 - x0) // 2 + 12
    return (max(0, min(t0, t1) - pad_r), min(h, max(b0, b1) + pad_r + 1), max(0, int(x0) - pad_c),
            min(w, int(x3) + pad_c + 1))


@jit
def measure_into(r, image, stack_rows, bounds, e, positive, cam, tc, st):
    """:func:`measure`'s body, written into ``r`` (an :data:`~localizer._kernels.records.EXACT_RESULT`
    record of zeros): ``e`` ``(2, 2)`` int64 rough bar ends (rows), ``cam`` an
    :class:`~localizer._kernels.records.Intrinsics`, ``tc`` a
    :class:`~localizer._kernels.records.TargetConstants`, ``st`` an
    :data:`~localizer._kernels.records.EXACT_SETTINGS` record."""
    rows = edge_rows(image, stack_rows, bounds)
    m, _, _, _ = subpixel(image, rows, bounds, e, positive)
    blur = rows_blur(image, rows, bounds)
    floor = blur_floor(blur, bounds, st.sigma_floor)
    edges, top, bot = m.edges, m.top, m.bottom
    r.edge0, r.edge1, r.edge2, r.edge3 = edges[0], edges[1], edges[2], edges[3]
    r.bar_cx1, r.bar_cx2 = m.bar_cx[0], m.bar_cx[1]
    r.top1, r.top2, r.bottom1, r.bottom2 = top[0], top[1], bot[0], bot[1]
    r.blur = blur
    for k in range(3):
        r.cov[k, k] = 1.0
    if not makes_target(edges[0], edges[1], edges[2], edges[3], bot[0] - top[0], bot[1] - top[1],
                        st.width_tolerance, st.width_slack, st.min_rows):
        return
    f = fit(m, cam, tc, positive, floor, st.iterations)
    if f.status != FitStatus.FITTED:
        return
    p = f.p
    r.found = True
    r.distance = math.hypot(p[0], p[1])
    r.beta = math.atan2(p[0], p[1])
    r.alpha = p[2]
    r.z = p[1]
    r.x = p[0]
    r.height = p[3]
    r.edge_bias = p[4]
    r.alpha1 = f.alpha1
    r.alpha2 = f.alpha2
    r.n_solutions = f.n_solutions
    r.chi2 = f.chi2
    for i in range(3):
        for j in range(3):
            r.cov[i, j] = f.cov[i, j]
