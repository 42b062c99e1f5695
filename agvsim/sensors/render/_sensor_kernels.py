"""Compiled sensor stages of the raycast backend: sensor noise and exposure.

The same models as :mod:`agvsim.sensors.render.sensor` (which the pyrender backend runs
in NumPy and OpenCV), written so that LLVM vectorises the per-pixel loops (8 lanes):

* :func:`expose`: gain, flare, shot + read noise, saturation, 8 bits. The noise is
  Gaussian by the Box-Muller transform of a counter-based generator: SplitMix64 of the
  frame's seed, output ``k + 1`` for pair ``k`` (its high 32 bits the radius, its low 32 the
  angle: :func:`pair_bits`), whose two normals go to pixels ``k`` and ``k + (n - n // 2)`` of
  the flattened frame. Every
  frame draws a fresh seed from the run's ``numpy.random.Generator``, so frames never share
  a noise pattern, and the same seed gives the same frame bit for bit.
* :func:`expose_columns`: the same of a column-major frame (the raycaster's) into a
  row-major 8-bit one, each column the normals of a one-column frame, the counter advanced
  past the columns before it.

Motion blur is :mod:`agvsim.sensors.render._motion_blur_kernels`.

Accuracy of the noise (:func:`normal_pair`): the uniform of the radius is the middle of one
of 2**32 equal cells (``u >= 2**-33``: radii up to 6.76 sigma; a normal passes that once in
7e10 draws, once in 3e5 frames of 512 x 480), with 24 significant bits, the angle 22 bits
per quarter turn; the logarithm, sine and
cosine are float32 polynomials. Against the exact transform of the same bits in float64
the draws differ by less than 1e-6 sigma (``tests/render/test_sensor_kernels.py``).

Images are ``(H, W)`` float32 radiance, C-contiguous (:func:`expose_columns`: ``(W, H)``).
"""
from __future__ import annotations

import math

import numpy as np
from numba.cpython.unsafe.numbers import leading_zeros

from agvsim.sensors.render.ray_records import EXPOSE_BLOCK
from agvsim.sensors.render.kernel_jit import frame_kernel, helper, kernel

__all__ = ["EXPOSE_BLOCK", "column_counter", "expose", "expose_columns", "expose_flat", "expose_scratch",
           "nearest_depth", "normal_pair", "pair_bits", "splitmix64", "standard_normals", "store_8x8", "store_columns"]

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


@helper
def splitmix64(x):
    """SplitMix64's output function of the counter state ``x`` (uint64)."""
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


_HI32 = np.uint64(0xFFFFFFFF00000000)
_HALF_CELL = np.uint64(1 << 31)


@helper
def pair_bits(bits):
    """``(bits_r, bits_a)`` of one pair from one 64-bit output: the high 32 bits as the radius's
    uniform (the middle of its cell: bit 31 set, never 0) and the low 32 as the angle's (bits
    32-63 of ``bits_a``)."""
    return (bits & _HI32) | _HALF_CELL, bits << np.uint64(32)


@helper
def _minus_two_log_u(bits):
    """``-2 ln u`` (float32) of the uniform ``u = bits / 2**64`` (``bits`` uint64, not 0)."""
    x = bits
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


@helper
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


@helper
def normal_pair(bits_r, bits_a):
    """Two independent standard normals (float32) from 128 random bits (uint64 each; Box-Muller)."""
    r = math.sqrt(_minus_two_log_u(bits_r))
    c, s = _direction(bits_a)
    return r * c, r * s


@frame_kernel
def standard_normals(seed, out):
    """Fill ``out`` (1-D float32) with the normals :func:`expose` adds to a frame of ``out.size``
    pixels with this ``seed`` (int < 2**63), in pixel order, unscaled."""
    n = out.size
    m = n // 2
    lo = out[:m]
    hi = out[n - m:]
    c = np.uint64(seed) + _GOLDEN
    for k in range(m):
        bits_r, bits_a = pair_bits(splitmix64(c))
        a, b = normal_pair(bits_r, bits_a)
        c += _GOLDEN
        lo[k] = a
        hi[k] = b
    if n % 2:
        bits_r, bits_a = pair_bits(splitmix64(c))
        out[m] = normal_pair(bits_r, bits_a)[0]


@helper
def expose_flat(x, o, params, c):
    """:func:`expose` of the pixels ``x`` (1-D float32) into ``o`` (1-D uint8), the noise's counter
    at ``c`` (uint64: pair ``k``'s bits are SplitMix64 of ``c + k GOLDEN``, split by :func:`pair_bits`)."""
    n = x.size
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
    for k in range(m):
        bits_r, bits_a = pair_bits(splitmix64(c))
        rho = _minus_two_log_u(bits_r)
        ca, cb = _direction(bits_a)
        c += _GOLDEN
        g = xa[k]
        v = ca * math.sqrt(rho * max(g * va + vb, read2)) + (g * sc + fl5)
        oa[k] = np.uint8(min(np.int32(max(v, _ZERO)), top))
        g = xb[k]
        v = cb * math.sqrt(rho * max(g * va + vb, read2)) + (g * sc + fl5)
        ob[k] = np.uint8(min(np.int32(max(v, _ZERO)), top))
    if n % 2:
        bits_r, bits_a = pair_bits(splitmix64(c))
        rho = _minus_two_log_u(bits_r)
        ca = _direction(bits_a)[0]
        g = x[m]
        v = ca * math.sqrt(rho * max(g * va + vb, read2)) + (g * sc + fl5)
        o[m] = np.uint8(min(np.int32(max(v, _ZERO)), top))


@frame_kernel
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
    expose_flat(radiance.reshape(n), out.reshape(n), params, np.uint64(params.seed) + _GOLDEN)


_U8 = np.uint64(8)
_LO8 = np.uint64(0x00FF00FF00FF00FF)
_LO16 = np.uint64(0x0000FFFF0000FFFF)
_LO32 = np.uint64(0x00000000FFFFFFFF)


@helper
def _swap(a, b, mask, shift):
    """One stage of a byte-matrix transpose: the units of ``shift`` bits of the words ``a`` and ``b``
    (uint64) interleaved: ``a``'s even units with ``b``'s even ones, ``a``'s odd with ``b``'s odd."""
    return (a & mask) | ((b & mask) << shift), ((a >> shift) & mask) | (b & ~mask)


@helper
def store_8x8(src, ib, stride, dst, d0, d_stride):
    """Words ``src[ib + q stride]`` (``q`` = 0..7; byte ``r`` of word ``q``: row ``r``, column ``q``)
    transposed into ``dst[d0 + r d_stride]`` (byte ``q`` of word ``r``), in three stages of swaps."""
    a0, a1 = _swap(src[ib], src[ib + stride], _LO8, _U8)
    a2, a3 = _swap(src[ib + 2 * stride], src[ib + 3 * stride], _LO8, _U8)
    a4, a5 = _swap(src[ib + 4 * stride], src[ib + 5 * stride], _LO8, _U8)
    a6, a7 = _swap(src[ib + 6 * stride], src[ib + 7 * stride], _LO8, _U8)
    b0, b2 = _swap(a0, a2, _LO16, np.uint64(16))
    b1, b3 = _swap(a1, a3, _LO16, np.uint64(16))
    b4, b6 = _swap(a4, a6, _LO16, np.uint64(16))
    b5, b7 = _swap(a5, a7, _LO16, np.uint64(16))
    r0, r4 = _swap(b0, b4, _LO32, np.uint64(32))
    r1, r5 = _swap(b1, b5, _LO32, np.uint64(32))
    r2, r6 = _swap(b2, b6, _LO32, np.uint64(32))
    r3, r7 = _swap(b3, b7, _LO32, np.uint64(32))
    dst[d0] = r0
    dst[d0 + d_stride] = r1
    dst[d0 + 2 * d_stride] = r2
    dst[d0 + 3 * d_stride] = r3
    dst[d0 + 4 * d_stride] = r4
    dst[d0 + 5 * d_stride] = r5
    dst[d0 + 6 * d_stride] = r6
    dst[d0 + 7 * d_stride] = r7


def expose_scratch(height: int) -> np.ndarray:
    """The ``cols`` scratch of :func:`expose_columns` for frames ``height`` rows high."""
    return np.empty((EXPOSE_BLOCK, -(-height // 8) * 8), np.uint8)


@frame_kernel
def expose_columns(radiance_t, params, out, cols):
    """:func:`expose` of a column-major frame into a row-major 8-bit frame.

    Args:
        radiance_t: ``(W, H)`` float32, C-contiguous: column ``j`` of the frame at ``radiance_t[j]``
            (as :meth:`agvsim.sensors.render.raycast.RaycastBackend.draw_level` draws it).
        params: :class:`~agvsim.sensors.render.ray_records.SensorParams`.
        out: ``(H, W)`` uint8, C-contiguous, written.
        cols: ``(EXPOSE_BLOCK, >= H)`` uint8 scratch, C-contiguous, rows a multiple of 8 bytes long
            (:func:`expose_scratch`).

    Column ``j`` gets what :func:`expose` gives a frame of that one column (``H`` pixels: pair
    ``k`` to rows ``k`` and ``k + H - H // 2``), with the noise's counter advanced past the
    ``H - H // 2`` pairs of each column before it: every pixel of the frame has its own draws.
    Blocks of :data:`EXPOSE_BLOCK` columns are exposed down their columns (vectorised) into
    ``cols``, then stored 8 rows at a time when ``W`` is a multiple of 8: an 8 x 8 block of bytes
    transposed in 64-bit words (:func:`store_8x8`), one store per row of the block.
    """
    w, h = radiance_t.shape
    for j0 in range(0, w, EXPOSE_BLOCK):
        nb = min(EXPOSE_BLOCK, w - j0)
        for q in range(nb):
            expose_flat(radiance_t[j0 + q], cols[q, :h], params, column_counter(params, h, j0 + q))
        store_columns(cols, j0, nb, out)


@helper
def column_counter(params, h, j):
    """The noise's counter (uint64) at column ``j`` of a column-major frame ``h`` rows high
    (:func:`expose_columns`): past the ``h - h // 2`` pairs of each column before it."""
    return np.uint64(params.seed) + _GOLDEN + _GOLDEN * np.uint64(h - h // 2) * np.uint64(j)


@helper
def store_columns(cols, j0, nb, out):
    """Columns ``j0 .. j0 + nb - 1`` of the row-major 8-bit frame ``out`` ``(H, W)`` (C-contiguous)
    from their exposed bytes ``cols[q, :H]`` (:func:`expose_columns`'s ``cols``): 8 rows at a time,
    an 8 x 8 block of bytes transposed in 64-bit words (:func:`store_8x8`), when ``W`` is a
    multiple of :data:`EXPOSE_BLOCK` (``j0`` then one too), else byte by byte."""
    h, w = out.shape
    if w % EXPOSE_BLOCK == 0:
        words = out.reshape(h * w).view(np.uint64)
        uw8 = np.uint64(w // EXPOSE_BLOCK)
        uhb = np.uint64(cols.shape[1] // 8)  # words per row of cols
        col_words = cols.reshape(cols.size).view(np.uint64)
        uj = np.uint64(j0 // EXPOSE_BLOCK)
        hb = h // 8  # whole blocks of 8 rows
        for ib in range(np.uint64(hb)):
            store_8x8(col_words, ib, uhb, words, ib * _U8 * uw8 + uj, uw8)
        for i in range(hb * 8, h):  # the rows past the last block of 8
            v = np.uint64(cols[0, i])
            for q in range(1, EXPOSE_BLOCK):  # little-endian: column j0 + q at byte q
                v |= np.uint64(cols[q, i]) << np.uint64(8 * q)
            words[np.uint64(i) * uw8 + uj] = v
    else:
        for i in range(h):
            for q in range(nb):
                out[i, j0 + q] = cols[q, i]


@kernel
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
