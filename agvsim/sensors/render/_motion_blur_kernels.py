"""Compiled motion blur of the raycast backend (:func:`blur_columns`), on the frame as the raycaster
draws it: column-major (column ``j`` at ``radiance_t[j]``, contiguous), exposed as it is blurred.

The model of :func:`agvsim.sensors.render.sensor.motion_blur` (which the pyrender backend runs
in NumPy and OpenCV): each pixel averages the scene along the path its scene point takes
across the image during the exposure (static scene, the camera's twist, the pixel's depth);
the path's horizontal extent is integrated exactly (row prefix sums), its vertical position
is taken at the path's midpoint (a level camera moving in the floor plane smears rows
sideways; the vertical drift is a small fraction of a pixel at AGV speeds), rows
``floor(ym)`` and ``floor(ym) + 1`` blended linearly. In float32:

* every image row's prefix sums are one pass over the columns, ``prefix[j + 1] = prefix[j] +
  radiance_t[j]`` (a column at a time, vectorised down it: the same float32 additions, in the
  same order, as a row's running sum);
* each output column's paths are computed down the column (vectorised); a level camera's wall
  column has one depth, so its pixels' paths start and end in the same columns: runs of pixels
  with the same offsets (and the same drift of the path's row from the pixel's) read contiguous
  memory of two columns of the radiance and two of the prefix sums (vectorised; gathers are no
  faster than scalar loads here, and a loop that gathers and stores does not vectorise);
* the blurred column is exposed by the sensor into a block of columns and stored in the 8-bit
  frame a block at a time, exactly as
  :func:`~agvsim.sensors.render._sensor_kernels.expose_columns` exposes a column-major frame (the
  same noise counter per column): the blurred radiance is never stored, and neither the
  radiance nor the depth is transposed (a row-major kernel needs both transposed first, and its
  output exposed in a pass of its own: 0.5 ms a frame of 512 x 480 more, measured).

The float32 prefix sums leave the result within about 1e-5 of the frame's maximum of the
float64 model (tested at 2e-5). Images are ``(W, H)`` float32 (the transposes of ``(H, W)``
frames: radiance, depth in m along the optical axis, 0 = far), C-contiguous.
"""
from __future__ import annotations

import numpy as np
from numba.cpython.unsafe.numbers import trailing_zeros

from agvsim.sensors.render._sensor_kernels import column_counter, expose_flat, store_columns
from agvsim.sensors.render.kernel_jit import frame_kernel, helper
from agvsim.sensors.render.ray_records import EXPOSE_BLOCK

__all__ = ["blur_columns", "transpose_into"]

_F = np.float32
_ONE, _ZERO = _F(1.0), _F(0.0)


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
def _prefix_columns(radiance_t, prefix):
    """``prefix[j, i]``: the sum of pixels ``0 .. j - 1`` of image row ``i`` (``prefix`` ``(W + 1, H)``
    float32), a column at a time (vectorised down the columns)."""
    w, h = radiance_t.shape
    p0 = prefix[0]
    for i in range(np.uint64(h)):
        p0[i] = _ZERO
    for j in range(np.uint64(w)):
        src = radiance_t[j]
        a = prefix[j]
        b = prefix[j + np.uint64(1)]
        for i in range(np.uint64(h)):
            b[i] = a[i] + src[i]


@helper
def _column_paths(depth_t, params, j, scratch):
    """Every pixel's path in column ``j`` (vectorised down it) into ``scratch.offsets`` and
    ``scratch.weights`` (:class:`~agvsim.sensors.render.ray_records.BlurScratch`), and where
    the offsets change into ``scratch.breaks``."""
    w, h = depth_t.shape
    fx, fy, cx, cy = params.fx, params.fy, params.cx, params.cy
    ra, rb = params.rot_a, params.rot_b
    # fx x and fy y / 2 (the ends' image offsets from (cx, cy) times z); pixel j covers x in [j, j + 1)
    ta0, ta1, ta2 = _F(fx * params.tr_a[0]), _F(0.5 * fy * params.tr_a[1]), _F(params.tr_a[2])
    tb0, tb1, tb2 = _F(fx * params.tr_b[0]), _F(0.5 * fy * params.tr_b[1]), _F(params.tr_b[2])
    cx5, cy32 = _F(cx + 0.5), _F(cy)
    eps, far = _F(1e-3), _F(1e3)
    kmax0, kmax, ymax = _F(w - 1e-3), _F(w), _F(h - 1.0)
    o0s, o1s, drift = scratch.offsets[0], scratch.offsets[1], scratch.offsets[2]
    g0s, f1s, w0s, w1s = scratch.weights[0], scratch.weights[1], scratch.weights[2], scratch.weights[3]
    # the point of pixel (i, j) at depth z is z (x_n, y_n(i), 1) at mid-exposure; each row of
    # rot . (x_n, y_n(i), 1) is c0 + c1 i down the column
    xn = (j - cx) / fx
    c = -cy / fy
    xa0 = _F(fx * (ra[0, 0] * xn + ra[0, 2] + ra[0, 1] * c))
    xa1 = _F(fx * ra[0, 1] / fy)
    ya0 = _F(0.5 * fy * (ra[1, 0] * xn + ra[1, 2] + ra[1, 1] * c))
    ya1 = _F(0.5 * ra[1, 1])
    za0 = _F(ra[2, 0] * xn + ra[2, 2] + ra[2, 1] * c)
    za1 = _F(ra[2, 1] / fy)
    xb0 = _F(fx * (rb[0, 0] * xn + rb[0, 2] + rb[0, 1] * c))
    xb1 = _F(fx * rb[0, 1] / fy)
    yb0 = _F(0.5 * fy * (rb[1, 0] * xn + rb[1, 2] + rb[1, 1] * c))
    yb1 = _F(0.5 * rb[1, 1])
    zb0 = _F(rb[2, 0] * xn + rb[2, 2] + rb[2, 1] * c)
    zb1 = _F(rb[2, 1] / fy)
    dcol = depth_t[j]
    ji = np.int32(j)
    fi = _ZERO
    for i in range(h):  # each pixel's path (vectorised)
        z = dcol[i]
        z = z if z > _ZERO else far
        pxa = z * (xa0 + xa1 * fi) + ta0
        pya = z * (ya0 + ya1 * fi) + ta1
        pza = max(z * (za0 + za1 * fi) + ta2, eps)
        pxb = z * (xb0 + xb1 * fi) + tb0
        pyb = z * (yb0 + yb1 * fi) + tb1
        pzb = max(z * (zb0 + zb1 * fi) + tb2, eps)
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
        o0s[i] = a0 - ji
        o1s[i] = a1 - ji
        drift[i] = r0 - np.int32(i)
        fr = ym - _F(r0)
        inv = _ONE / (k1 - k0)
        g0s[i] = (_F(a0) + _ONE) - k0
        f1s[i] = k1 - _F(a1)
        w0s[i] = (_ONE - fr) * inv
        w1s[i] = fr * inv
        fi += _ONE
    breaks = scratch.breaks
    breaks[0] = 1
    for i in range(1, h):
        breaks[i] = (o0s[i] != o0s[i - 1]) | (o1s[i] != o1s[i - 1]) | (drift[i] != drift[i - 1])


@helper
def _run(out, weights, xu, xv, pu1, pv, i0, n, d, same):
    """Pixels ``i0 .. i0 + n - 1`` of one output column whose paths start in column ``u`` and end in
    column ``v`` (radiance ``xu``, ``xv``; prefix sums ``pu1 = prefix[u + 1]``, ``pv = prefix[v]``),
    rows ``i + d`` and ``i + d + 1`` blended: the first pixel's share, the whole pixels between
    (prefix sums), the last pixel's share. A path within one pixel (``same``: ``u == v``) takes that
    pixel's value (the prefix term dropped exactly)."""
    g0 = weights[0]
    f1 = weights[1]
    w0 = weights[2]
    w1 = weights[3]
    sm = _ONE if same else _ZERO
    span = _ONE - sm
    for t in range(n):
        i = np.uint64(i0 + t)
        r = np.uint64(i0 + t + d)
        r1 = r + np.uint64(1)
        g = g0[i] - sm
        s0 = g * xu[r] + f1[i] * xv[r] + (pv[r] - pu1[r]) * span
        s1 = g * xu[r1] + f1[i] * xv[r1] + (pv[r1] - pu1[r1]) * span
        out[i] = s0 * w0[i] + s1 * w1[i]


@helper
def _column_runs(radiance_t, scratch, j, out):
    """Column ``j`` blurred into ``out`` (``(H,)`` float32): its runs of pixels whose paths start and
    end in the same columns, at the same drift of rows (contiguous memory, vectorised)."""
    h = out.size
    o0s, o1s, drift = scratch.offsets[0], scratch.offsets[1], scratch.offsets[2]
    breaks64 = scratch.breaks.view(np.uint64)
    prefix = scratch.prefix
    i0 = np.int64(0)
    while i0 < h:
        ie = _next_break(breaks64, i0, h)
        u = j + np.int64(o0s[i0])
        v = j + np.int64(o1s[i0])
        _run(out, scratch.weights, radiance_t[u], radiance_t[v], prefix[u + 1], prefix[v], i0, ie - i0,
             np.int64(drift[i0]), u == v)
        i0 = ie


@frame_kernel
def blur_columns(radiance_t, depth_t, params, out_t, scratch, sensor, image):
    """Average each pixel of a column-major frame along its scene point's image path between the
    exposure's ends (module docstring).

    The path of pixel ``(i, j)`` runs from ``x0`` to ``x1`` (the point's image x at the two ends,
    clipped to the image, at least 1e-3 px apart) at row ``ym`` (the mean of the ends' rows): the
    blurred pixel is the mean of the row, piecewise constant over its pixels, over ``x0 .. x1``,
    rows ``floor(ym)`` and ``floor(ym) + 1`` blended linearly.

    Args:
        radiance_t, depth_t: ``(W, H)`` float32, C-contiguous: column ``j`` of the ``(H, W)`` frame
            at ``[j]`` (radiance; depth m along the axis, 0 = far), ``H >= 2``.
        params: :class:`~agvsim.sensors.render.ray_records.MotionBlurParams`.
        out_t: ``(W, H)`` float32, C-contiguous, out (not ``radiance_t``): the blurred radiance,
            column-major, when ``image`` is ``(0, 0)``; else not written.
        scratch: :class:`~agvsim.sensors.render.ray_records.BlurScratch` for ``(H, W)``.
        sensor, image: ``image`` ``(H, W)`` uint8, C-contiguous, out: the blurred frame exposed by
            the sensor (:class:`~agvsim.sensors.render.ray_records.SensorParams` ``sensor``) as
            :func:`~agvsim.sensors.render._sensor_kernels.expose_columns` exposes the blurred
            radiance (bit for bit); or ``(0, 0)``: the radiance is stored in ``out_t``.
    """
    w, h = radiance_t.shape
    exposed = image.shape[0] > 0
    _prefix_columns(radiance_t, scratch.prefix)
    scratch.breaks[h:] = 1
    cols = scratch.exposed
    for j in range(w):
        col = scratch.column if exposed else out_t[j]
        _column_paths(depth_t, params, j, scratch)
        _column_runs(radiance_t, scratch, np.int64(j), col)
        if exposed:
            q = j % EXPOSE_BLOCK
            expose_flat(col, cols[q, :h], sensor, column_counter(sensor, h, j))
            if q == EXPOSE_BLOCK - 1 or j == w - 1:
                store_columns(cols, j - q, q + 1, image)


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
