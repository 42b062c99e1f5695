"""Compiled sensor stages of the raycast backend: sensor noise and exposure, motion blur.

The same models as :mod:`agvsim.sensors.render.sensor` (which the pyrender backend runs
in NumPy and OpenCV), written so that LLVM vectorises the per-pixel loops (8 lanes):

* :func:`expose`: gain, flare, shot + read noise, saturation, 8 bits. The noise is
  Gaussian by the Box-Muller transform of a counter-based generator: SplitMix64 of the
  frame's seed, output ``2k + 1`` giving the radius and ``2k + 2`` the angle of pair ``k``,
  whose two normals go to pixels ``k`` and ``k + (n - n // 2)`` of the flattened frame. Every
  frame draws a fresh seed from the run's ``numpy.random.Generator``, so frames never share
  a noise pattern, and the same seed gives the same frame bit for bit.
* :func:`motion_blur`: each pixel averages the scene along the path its scene point
  takes across the image during the exposure (static scene, the camera's twist, the
  pixel's depth), as :func:`agvsim.sensors.render.sensor.motion_blur`; the path's
  horizontal extent is integrated exactly (row prefix sums), its vertical position is
  taken at the path's midpoint (a level camera moving in the floor plane smears rows
  sideways; the vertical drift is a small fraction of a pixel at AGV speeds). Per image row,
  in float32: every pixel's path (vectorised), then runs of pixels whose paths start and end
  at the same offsets read contiguous memory (vectorised; gathers are no faster than scalar
  loads here, and a loop that gathers and stores does not vectorise). Row prefix sums are
  kept for a ring of rows; their float32 rounding leaves the result within about 1e-5 of the
  frame's maximum of the float64 model (tested at 2e-5).

Accuracy of the noise (:func:`normal_pair`): the uniform of the radius keeps 24 significant
bits over the whole 64-bit range (``u >= 2**-64``: radii up to 9.4 sigma, so the tails are
Gaussian to beyond 9 sigma), the angle 22 bits per quarter turn; the logarithm, sine and
cosine are float32 polynomials. Against the exact transform of the same bits in float64
the draws differ by less than 1e-6 sigma (``tests/render/test_sensor_kernels.py``).

Images are ``(H, W)`` float32 (radiance, depth in m along the optical axis, 0 = far),
C-contiguous.
"""
from __future__ import annotations

import math

import numpy as np
from numba.cpython.unsafe.numbers import leading_zeros, trailing_zeros

from localizer._jit import borrowed
from localizer._jit import fast_inline as inline
from localizer._jit import fast_jit as jit

__all__ = ["expose", "motion_blur", "nearest_depth", "normal_pair", "splitmix64", "standard_normals"]

_F = np.float32
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_ONE, _HALF, _ZERO = _F(1.0), _F(0.5), _F(0.0)
# the radius: u = m 2**-(e + 1), m in [1, 2) from 24 bits after the e leading zeros; ln m by
# atanh: ln t = 2 s (1 + s^2 / 3 + s^4 / 5 + ...), s = (t - 1) / (t + 1), t = m or m / 2 (|s| < 0.172)
_K23, _K24, _KSPLIT = _F(2.0 ** 23), _F(2.0 ** 24), _F(math.sqrt(2.0) * 2.0 ** 23)
_TWO_LN2, _MINUS4 = _F(2.0 * math.log(2.0)), _F(-4.0)
_L3, _L5, _L7, _L9 = (_F(1.0 / k) for k in (3, 5, 7, 9))
# the angle: x uniform in (-pi/4, pi/4) from 22 bits; Cephes' sinf / cosf polynomials on that range
_ANG_A = _F(2.0 ** -22 * math.pi / 2.0)
_ANG_B = _F((0.5 * 2.0 ** -22 - 0.5) * math.pi / 2.0)
_S3, _S5, _S7 = _F(-1.6666654611e-1), _F(8.3321608736e-3), _F(-1.9515295891e-4)
_C4, _C6, _C8 = _F(4.166664568298827e-2), _F(-1.388731625493765e-3), _F(2.443315711809948e-5)
_BIT62 = np.uint64(1 << 62)


@inline
def splitmix64(x):
    """SplitMix64's output function of the counter state ``x`` (uint64)."""
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


@inline
def _minus_two_log_u(bits):
    """``-2 ln u`` (float32) of the uniform ``u = bits / 2**64`` (``bits`` uint64, 0 read as 1)."""
    x = bits | np.uint64(1)
    e = leading_zeros(x)
    mm = _F(np.int64((x << e) >> np.uint64(40)))  # m * 2**23, 24 bits, in [2**23, 2**24)
    big = mm > _KSPLIT
    kk = _K24 if big else _K23
    s = (mm - kk) / (mm + kk)
    s2 = s * s
    p = _L9 * s2 + _L7
    p = p * s2 + _L5
    p = p * s2 + _L3
    p = p * s2 + _ONE
    return (_MINUS4 * s) * p + (_F(e) + (_ZERO if big else _ONE)) * _TWO_LN2


@inline
def _direction(bits):
    """``(cos a, sin a)`` (float32) of an angle ``a`` uniform on the circle, from ``bits`` (uint64):
    bit 63 flips the cosine, bit 62 swaps the two (the four quarter turns), bits 39..60 the angle
    within a quarter turn."""
    x = _F(np.int64((bits << np.uint64(2)) >> np.uint64(42))) * _ANG_A + _ANG_B
    x2 = x * x
    sn = _S7 * x2 + _S5
    sn = sn * x2 + _S3
    sn = (sn * x2) * x + x
    cs = _C8 * x2 + _C6
    cs = cs * x2 + _C4
    cs = cs * (x2 * x2) + (_ONE - _HALF * x2)
    cs = -cs if np.int64(bits) < 0 else cs
    swap = (bits & _BIT62) != np.uint64(0)
    return (sn if swap else cs), (cs if swap else sn)


@inline
def normal_pair(bits_r, bits_a):
    """Two independent standard normals (float32) from 128 random bits (uint64 each; Box-Muller)."""
    r = math.sqrt(_minus_two_log_u(bits_r))
    c, s = _direction(bits_a)
    return r * c, r * s


@jit
def standard_normals(seed, out):
    """Fill ``out`` (1-D float32) with the normals :func:`expose` adds to a frame of ``out.size``
    pixels with this ``seed`` (int < 2**63), in pixel order, unscaled."""
    n = out.size
    m = n // 2
    lo = out[:m]
    hi = out[n - m:]
    c = np.uint64(seed) + _GOLDEN
    step = _GOLDEN + _GOLDEN
    for k in range(m):
        a, b = normal_pair(splitmix64(c), splitmix64(c + _GOLDEN))
        c += step
        lo[k] = a
        hi[k] = b
    if n % 2:
        out[m] = normal_pair(splitmix64(c), splitmix64(c + _GOLDEN))[0]


@jit
def expose(radiance, params, out):
    """Radiance -> 8-bit grey (:func:`agvsim.sensors.render.sensor.expose`'s model): ``g = scale
    radiance + flare``, plus ``z sqrt(max(g, 0) / electrons_per_grey + read_noise**2) noise_scale``
    with ``z`` standard normal (module docstring), rounded half up, clipped to 0..255.

    Args:
        radiance: ``(H, W)`` float32 linear radiance, C-contiguous.
        params: :class:`~agvsim.sensors.render.ray_records.SensorParams`.
        out: ``(H, W)`` uint8, C-contiguous, written.
    """
    n = radiance.size
    x = radiance.reshape(n)
    o = out.reshape(n)
    scale = params.scale
    sc = _F(scale)
    top = np.int32(255)
    if params.noise_scale <= 0.0:
        fl5 = _F(params.flare + 0.5)
        for p in range(n):
            o[p] = np.uint8(min(np.int32(max(x[p] * sc + fl5, _ZERO)), top))
        return
    # variance in grey levels^2 (times noise_scale^2): va radiance + vb, at least read2
    ns2 = params.noise_scale * params.noise_scale
    inv_e = ns2 / params.electrons_per_grey
    read2 = _F(params.read_noise * params.read_noise * ns2)
    va = _F(scale * inv_e)
    vb = _F(params.flare * inv_e) + read2
    fl5 = _F(params.flare + 0.5)
    m = n // 2
    xa = x[:m]
    xb = x[n - m:]
    oa = o[:m]
    ob = o[n - m:]
    c = np.uint64(params.seed) + _GOLDEN
    step = _GOLDEN + _GOLDEN
    for k in range(m):
        rho = _minus_two_log_u(splitmix64(c))
        ca, cb = _direction(splitmix64(c + _GOLDEN))
        c += step
        g = xa[k]
        v = ca * math.sqrt(rho * max(g * va + vb, read2)) + (g * sc + fl5)
        oa[k] = np.uint8(min(np.int32(max(v, _ZERO)), top))
        g = xb[k]
        v = cb * math.sqrt(rho * max(g * va + vb, read2)) + (g * sc + fl5)
        ob[k] = np.uint8(min(np.int32(max(v, _ZERO)), top))
    if n % 2:
        rho = _minus_two_log_u(splitmix64(c))
        ca = _direction(splitmix64(c + _GOLDEN))[0]
        g = x[m]
        v = ca * math.sqrt(rho * max(g * va + vb, read2)) + (g * sc + fl5)
        o[m] = np.uint8(min(np.int32(max(v, _ZERO)), top))


@jit
def nearest_depth(depth):
    """The smallest positive finite depth of ``depth`` (m, C-contiguous float32 of any shape; 1e3 if
    none). Positive floats order as their bit patterns do: an integer minimum, which vectorises."""
    bits = depth.reshape(depth.size).view(np.int32)
    inf_bits = np.int32(0x7F800000)
    best = inf_bits
    for p in range(bits.size):
        b = bits[p]
        best = min(best, b if b > np.int32(0) else inf_bits)
    if best >= inf_bits:
        return 1e3
    value = np.empty(1, np.int32)
    value[0] = best
    return float(value.view(np.float32)[0])


# ------------------------------------------------------------------ motion blur
@inline
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


@inline
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


@inline
def _run(orow, g0, f1, w0, w1, x0, x1, p0, p1, js, n, o0, o1):
    """Pixels ``js .. js + n - 1`` of one output row whose paths start in pixel ``j + o0`` and end in
    pixel ``j + o1`` of image rows ``x0`` and ``x1`` (prefix sums ``p0``, ``p1``): the first pixel's
    share, the whole pixels between (prefix sums), the last pixel's share, rows blended. A path
    within one pixel (``o1 == o0``) takes that pixel's value (the prefix term dropped exactly)."""
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


@jit
def _row_runs_ensured(radiance, scratch, orow):
    """:func:`motion_blur`'s runs of one row, each computing the prefix rows it needs first (a
    function of its own: that check in the common loop makes it a third slower)."""
    radiance = borrowed(radiance)
    scratch = borrowed(scratch)
    orow = borrowed(orow)
    w = orow.size
    mask = scratch.prefix.shape[0] - 1
    o0s, o1s, rows = scratch.offsets[0], scratch.offsets[1], scratch.offsets[2]
    g0s, f1s, w0s, w1s = scratch.weights[0], scratch.weights[1], scratch.weights[2], scratch.weights[3]
    breaks64 = scratch.breaks.view(np.uint64)
    js = 0
    while js < w:
        je = _next_break(breaks64, js, w)
        r = np.int64(rows[js])
        _ensure_row(radiance, scratch, r)
        _ensure_row(radiance, scratch, r + 1)
        _run(orow, g0s, f1s, w0s, w1s, radiance[r], radiance[r + 1], scratch.prefix[r & mask],
             scratch.prefix[(r + 1) & mask], js, je - js, np.int64(o0s[js]), np.int64(o1s[js]))
        js = je


@jit
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

    The arguments are used :func:`~localizer._jit.borrowed` (the caller holds them): the rows
    and prefix rows handed to each run cost no reference counts.
    """
    radiance = borrowed(radiance)
    depth = borrowed(depth)
    params = borrowed(params)
    out = borrowed(out)
    scratch = borrowed(scratch)
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
    breaks64 = breaks.view(np.uint64)
    breaks[w:] = 1
    mask = scratch.prefix.shape[0] - 1
    scratch.ring_row[:] = -1
    for i in range(h):
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
        orow = out[i]
        if rmax + 1 - rmin < scratch.prefix.shape[0]:
            # every row this row's paths reach fits the ring at once (always, but for vertical smears
            # of about the ring's size): runs of pixels with the same offsets and rows read
            # contiguous memory (vectorised)
            for r in range(rmin, rmax + 2):
                _ensure_row(radiance, scratch, r)
            js = 0
            while js < w:
                je = _next_break(breaks64, js, w)
                r = np.int64(rows[js])
                _run(orow, g0s, f1s, w0s, w1s, radiance[r], radiance[r + 1], scratch.prefix[r & mask],
                     scratch.prefix[(r + 1) & mask], js, je - js, np.int64(o0s[js]), np.int64(o1s[js]))
                js = je
        else:
            _row_runs_ensured(radiance, scratch, orow)
