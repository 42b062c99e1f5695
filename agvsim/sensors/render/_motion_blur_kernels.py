"""Compiled motion blur of the raycast backend (:func:`motion_blur`).

The model of :func:`agvsim.sensors.render.sensor.motion_blur` (which the pyrender backend runs
in NumPy and OpenCV): each pixel averages the scene along the path its scene point takes
across the image during the exposure (static scene, the camera's twist, the pixel's depth);
the path's horizontal extent is integrated exactly (row prefix sums), its vertical position
is taken at the path's midpoint (a level camera moving in the floor plane smears rows
sideways; the vertical drift is a small fraction of a pixel at AGV speeds). Per image row,
in float32: every pixel's path (vectorised), then runs of pixels whose paths start and end
at the same offsets read contiguous memory (vectorised; gathers are no faster than scalar
loads here, and a loop that gathers and stores does not vectorise). Row prefix sums are
kept for a ring of rows; their float32 rounding leaves the result within about 1e-5 of the
frame's maximum of the float64 model (tested at 2e-5).

Images are ``(H, W)`` float32 (radiance, depth in m along the optical axis, 0 = far),
C-contiguous.
"""
from __future__ import annotations

import numpy as np
from numba.cpython.unsafe.numbers import trailing_zeros

from agvsim.sensors.render.kernel_jit import frame_kernel, helper

__all__ = ["motion_blur", "transpose_into"]

_F = np.float32
_ONE, _ZERO = _F(1.0), _F(0.0)


@helper
def _ensure_row(radiance, scratch, r):
    """Image row ``r``'s prefix sums in its ring slot (computed if missing, evicting row ``r - K``)."""
    slot = r & (scratch.prefix.shape[0] - 1)
    if scratch.ring_row[slot] != r:
        q = scratch.prefix[slot]
        x = radiance[r]
        acc = _ZERO
        q[0] = acc
        for j in range(x.size):
            acc += x[j]
            q[j + 1] = acc
        scratch.ring_row[slot] = r


@helper
def _next_break(breaks64, j, w):
    """The first ``k > j`` where a run of equal offsets starts (``w`` at the row's end)."""
    k = j + 1
    word_index = k >> 3
    word = breaks64[word_index] >> np.uint64(8 * (k & 7))
    while word == np.uint64(0):
        word_index += 1
        word = breaks64[word_index]
        k = word_index * 8
    return min(k + (trailing_zeros(word) >> 3), w)


@helper
def _run(orow, weights, x0, x1, p0, p1, js, n, o0, o1):
    """Pixels ``js .. js + n - 1`` of one output row whose paths start in pixel ``j + o0`` and end in
    pixel ``j + o1`` of image rows ``x0`` and ``x1`` (prefix sums ``p0``, ``p1``): the first pixel's
    share, the whole pixels between (prefix sums), the last pixel's share, rows blended
    (``weights``: :attr:`~agvsim.sensors.render.ray_records.BlurScratch.weights`). A path within
    one pixel (``o1 == o0``) takes that pixel's value (the prefix term dropped exactly)."""
    g0 = weights[0]
    f1 = weights[1]
    w0 = weights[2]
    w1 = weights[3]
    same = _ONE if o1 == o0 else _ZERO
    span = _ONE - same
    for t in range(n):
        j = np.uint64(js + t)
        u = np.uint64(js + t + o0)
        v = np.uint64(js + t + o1)
        u1 = u + np.uint64(1)
        g = g0[j] - same
        s0 = g * x0[u] + f1[j] * x0[v] + (p0[v] - p0[u1]) * span
        s1 = g * x1[u] + f1[j] * x1[v] + (p1[v] - p1[u1]) * span
        orow[j] = s0 * w0[j] + s1 * w1[j]


@helper
def _row_runs(radiance, scratch, orow, ensure):
    """:func:`motion_blur`'s runs of one row: pixels whose paths start and end at the same offsets
    and rows read contiguous memory (vectorised). With ``ensure`` each run computes the prefix
    rows it needs first (the caller has not: the row's paths reach more rows than the ring holds)."""
    w = orow.size
    mask = scratch.prefix.shape[0] - 1
    o0s, o1s, rows = scratch.offsets[0], scratch.offsets[1], scratch.offsets[2]
    breaks64 = scratch.breaks.view(np.uint64)
    js = np.int64(0)
    while js < w:
        je = _next_break(breaks64, js, w)
        r = np.int64(rows[js])
        if ensure:
            _ensure_row(radiance, scratch, r)
            _ensure_row(radiance, scratch, r + 1)
        _run(orow, scratch.weights, radiance[r], radiance[r + 1], scratch.prefix[r & mask],
             scratch.prefix[(r + 1) & mask], js, je - js, np.int64(o0s[js]), np.int64(o1s[js]))
        js = je


@helper
def _row_paths(radiance, depth, params, i, scratch):
    """Every pixel's path in row ``i`` (vectorised) into ``scratch.offsets`` and ``scratch.weights``
    (:class:`~agvsim.sensors.render.ray_records.BlurScratch`), and where the offsets change into
    ``scratch.breaks``; returns the first and last image row the paths start in."""
    h, w = radiance.shape
    fx, fy, cx, cy = params.fx, params.fy, params.cx, params.cy
    ra, rb = params.rot_a, params.rot_b
    # fx x and fy y / 2 (the ends' image offsets from (cx, cy) times z); pixel j covers x in [j, j + 1)
    ta0, ta1, ta2 = _F(fx * params.tr_a[0]), _F(0.5 * fy * params.tr_a[1]), _F(params.tr_a[2])
    tb0, tb1, tb2 = _F(fx * params.tr_b[0]), _F(0.5 * fy * params.tr_b[1]), _F(params.tr_b[2])
    cx5, cy32 = _F(cx + 0.5), _F(cy)
    eps, far = _F(1e-3), _F(1e3)
    kmax0, kmax, ymax = _F(w - 1e-3), _F(w), _F(h - 1.0)
    o0s, o1s, rows = scratch.offsets[0], scratch.offsets[1], scratch.offsets[2]
    g0s, f1s, w0s, w1s = scratch.weights[0], scratch.weights[1], scratch.weights[2], scratch.weights[3]
    breaks = scratch.breaks
    # the point of pixel (i, j) at depth z is z (x_n(j), y_n, 1) at mid-exposure; each row of
    # rot . (x_n(j), y_n, 1) is c0 + c1 j along the image row
    yn = (i - cy) / fy
    xa0 = _F(fx * (ra[0, 1] * yn + ra[0, 2]) - ra[0, 0] * cx)
    xa1 = _F(ra[0, 0])
    ya0 = _F(0.5 * fy * (ra[1, 1] * yn + ra[1, 2] - ra[1, 0] * cx / fx))
    ya1 = _F(0.5 * fy * ra[1, 0] / fx)
    za0 = _F(ra[2, 1] * yn + ra[2, 2] - ra[2, 0] * cx / fx)
    za1 = _F(ra[2, 0] / fx)
    xb0 = _F(fx * (rb[0, 1] * yn + rb[0, 2]) - rb[0, 0] * cx)
    xb1 = _F(rb[0, 0])
    yb0 = _F(0.5 * fy * (rb[1, 1] * yn + rb[1, 2] - rb[1, 0] * cx / fx))
    yb1 = _F(0.5 * fy * rb[1, 0] / fx)
    zb0 = _F(rb[2, 1] * yn + rb[2, 2] - rb[2, 0] * cx / fx)
    zb1 = _F(rb[2, 0] / fx)
    drow = depth[i]
    jf = _ZERO
    rmin = np.int32(h)
    rmax = np.int32(0)
    for j in range(w):  # each pixel's path (vectorised)
        z = drow[j]
        z = z if z > _ZERO else far
        pxa = z * (xa0 + xa1 * jf) + ta0
        pya = z * (ya0 + ya1 * jf) + ta1
        pza = max(z * (za0 + za1 * jf) + ta2, eps)
        pxb = z * (xb0 + xb1 * jf) + tb0
        pyb = z * (yb0 + yb1 * jf) + tb1
        pzb = max(z * (zb0 + zb1 * jf) + tb2, eps)
        q = _ONE / (pza * pzb)
        qa = pzb * q
        qb = pza * q
        ax = cx5 + pxa * qa
        bx = cx5 + pxb * qb
        k0 = min(max(min(ax, bx), _ZERO), kmax0)
        k1 = min(max(max(ax, bx), k0 + eps), kmax)
        ym = min(max(cy32 + pya * qa + pyb * qb, _ZERO), ymax)
        r0 = min(np.int32(ym), np.int32(h - 2))
        a0 = np.int32(k0)
        a1 = min(np.int32(k1), np.int32(w - 1))
        ji = np.int32(j)
        o0s[j] = a0 - ji
        o1s[j] = a1 - ji
        rows[j] = r0
        rmin = min(rmin, r0)
        rmax = max(rmax, r0)
        fr = ym - _F(r0)
        inv = _ONE / (k1 - k0)
        g0s[j] = (_F(a0) + _ONE) - k0
        f1s[j] = k1 - _F(a1)
        w0s[j] = (_ONE - fr) * inv
        w1s[j] = fr * inv
        jf += _ONE
    breaks[0] = 1
    for j in range(1, w):
        breaks[j] = (o0s[j] != o0s[j - 1]) | (o1s[j] != o1s[j - 1]) | (rows[j] != rows[j - 1])
    return rmin, rmax


@frame_kernel
def motion_blur(radiance, depth, params, out, scratch):
    """Average each pixel along its scene point's image path between the exposure's ends.

    The path of pixel ``(i, j)`` runs from ``x0`` to ``x1`` (the point's image x at the two ends,
    clipped to the image, at least 1e-3 px apart) at row ``ym`` (the mean of the ends' rows): the
    output is the mean of the row, piecewise constant over its pixels, over ``x0 .. x1``, rows
    ``floor(ym)`` and ``floor(ym) + 1`` blended linearly.

    Args:
        radiance, depth: ``(H, W)`` float32 (depth m along the axis, 0 = far), ``H >= 2``.
        params: :class:`~agvsim.sensors.render.ray_records.MotionBlurParams`.
        out: ``(H, W)`` float32, written (not ``radiance``).
        scratch: :class:`~agvsim.sensors.render.ray_records.BlurScratch` for ``(H, W)``.
    """
    h, w = radiance.shape
    scratch.breaks[w:] = 1
    scratch.ring_row[:] = -1
    for i in range(h):
        rmin, rmax = _row_paths(radiance, depth, params, i, scratch)
        fits = rmax + 1 - rmin < scratch.prefix.shape[0]
        if fits:
            # every row this row's paths reach fits the ring at once (always, but for vertical smears
            # of about the ring's size)
            for r in range(rmin, rmax + 2):
                _ensure_row(radiance, scratch, r)
        _row_runs(radiance, scratch, out[i], not fits)


@frame_kernel
def transpose_into(src, dst):
    """``dst[...] = src.T``: a column-major frame (``src``, ``(W, H)`` float32, C-contiguous: the
    raycaster's) to the row-major one motion blur reads (``dst``, ``(H, W)`` float32,
    C-contiguous), in 8 x 8 blocks (LLVM turns each into register shuffles: 0.1 ms for 512 x 480,
    NumPy's strided copy 0.17 ms)."""
    w, h = src.shape
    wb = w - w % 8
    hb = h - h % 8
    for j0 in range(0, wb, 8):
        uj = np.uint64(j0)
        for i0 in range(0, hb, 8):
            ui = np.uint64(i0)
            for r in range(np.uint64(8)):
                for q in range(np.uint64(8)):
                    dst[ui + r, uj + q] = src[uj + q, ui + r]
    for j in range(wb, w):  # the columns and rows past the last whole block
        for i in range(h):
            dst[i, j] = src[j, i]
    for j in range(wb):
        for i in range(hb, h):
            dst[i, j] = src[j, i]
