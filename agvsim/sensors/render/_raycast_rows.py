"""The raycaster's plain face rows: rows of a face span with no decal, filtered texture times irradiance.

Most of a frame's face pixels are such rows (a wall between its decals, above and below a
target). :func:`plain_rows` weights each row's two subsamples in each mip level's texel
column (built by :func:`agvsim.sensors.render._raycast_face.shade_face`) by the face's
irradiance; with AVX-512 the subsamples come 16 at a time from
:func:`agvsim.sensors.render._simd.pair_sums8` (:func:`permuted_level`), elsewhere from one
fixed-point loop. The two paths agree to float32 rounding (tested).
"""
from __future__ import annotations

import math

import numpy as np

from agvsim.sensors.render._simd import PERMUTE_MAX_STEP, PERMUTE_ROWS, pair_sums8
from localizer._jit import fast_inline as inline

__all__ = ["FIXED_BITS", "permuted_level", "plain_rows"]

#: fractional bits of the fixed-point texel coordinates of :func:`plain_rows`
FIXED_BITS = 32
_FIXED_ONE = float(1 << FIXED_BITS)
_FIXED_INV = np.float32(1.0 / _FIXED_ONE)  # (float32: the texel columns' interpolation is float32)
_U1 = np.uint64(1)
_UBITS = np.uint64(FIXED_BITS)
_UMASK = np.uint64((1 << FIXED_BITS) - 1)


@inline
def _fixed(x):
    """``x >= 0`` texels as a fixed-point integer (:data:`FIXED_BITS` fractional bits), unsigned."""
    return np.uint64(np.int64(x * _FIXED_ONE))


@inline
def _lerp_fixed(buf, o, p):
    """``buf[o:]`` interpolated linearly at the fixed-point coordinate ``p`` (unsigned: array
    indices without a test for negative ones)."""
    q = o + (p >> _UBITS)
    return buf[q] + (buf[q + _U1] - buf[q]) * (np.float32(np.int64(p & _UMASK)) * _FIXED_INV)


@inline
def permuted_level(buf, bo, ta, tb, lo, n, val, at):
    """``val[at + k]`` (``k = 0 .. n - 1``): the sum of the two subsamples of row ``lo + k`` in the
    texel column ``buf[bo:]`` (coordinate ``ta + tb y`` of image row ``y``: the subsamples at
    ``y -+ 1/4``), 8 rows at a time by :func:`~agvsim.sensors.render._simd.pair_sums8` (``|tb| / 2
    <= PERMUTE_MAX_STEP``), the last ``n % 8`` one sample at a time (float32 interpolation of
    float64 coordinates, as :func:`pair_sums8`'s)."""
    first = ta + tb * (lo - 0.25)  # the rows' subsamples: one sequence, half a row's step apart
    half = 0.5 * tb
    nb = n // PERMUTE_ROWS
    for b in range(nb):
        start = first + (2 * PERMUTE_ROWS * b) * half
        base = int(min(start, start + (2 * PERMUTE_ROWS - 1) * half))  # (>= 0: truncation is the floor)
        pair_sums8(buf, bo + base, start - base, half, val, at + PERMUTE_ROWS * b)
    for k in range(PERMUTE_ROWS * nb, n):
        v = np.float32(0.0)
        for t in range(2):
            x = first + (2 * k + t) * half
            q = int(x)
            f = np.float32(x - q)
            v += buf[bo + q] + (buf[bo + q + 1] - buf[bo + q]) * f
        val[at + k] = v


@inline
def plain_rows(lo, hi, g, buf, b0, t0a, t0b, b1, t1a, t1b, two, irr, y0, step, n_l, acc, val, permute):
    """Rows ``lo .. hi`` of a face span that covers them whole, no decal among them: ``g`` x the
    sum of the two subsamples of each level (``buf[b0:]``, ``buf[b1:]``: the levels' texel
    columns, weighted, float32: interpolated in float32) times the irradiance (``irr[:n_l]``).

    The texel columns reach a row beyond the span's ends (built by
    :func:`agvsim.sensors.render._raycast_face.shade_face`), so the subsamples need no
    clamping. With ``permute`` (the face kernel passes :data:`agvsim.sensors.render._simd.PERMUTE`:
    AVX-512) the subsamples are read 16 at a time from windows of the columns
    (:func:`permuted_level`, into ``val``, ``(2 (H + 8),)`` float32 scratch), then each row is
    weighted by the irradiance (vectorised). Elsewhere one loop does both: the subsamples'
    coordinates step by a constant per row, in fixed point (:data:`FIXED_BITS` fractional bits: 2e-10 texel, no float-to-int
    conversion per sample; unsigned, a negative step wrapping modulo 2^64). Either way the
    irradiance is stepped linearly within each of its segments (``step`` rows from ``y0``).
    ``two``: False when the second level has weight 0 (magnified: most walls); its subsamples
    (+0.0) would not change the sum."""
    if hi < lo:
        return
    m0 = min(max(int((lo - y0) / step), 0), n_l - 2)
    m1 = min(max(int((hi - y0) / step), 0), n_l - 2)
    if permute and abs(0.5 * t0b) <= PERMUTE_MAX_STEP and (not two or abs(0.5 * t1b) <= PERMUTE_MAX_STEP):
        n = hi + 1 - lo
        second = val.size // 2
        permuted_level(buf, b0, t0a, t0b, lo, n, val, 0)
        if two:
            permuted_level(buf, b1, t1a, t1b, lo, n, val, second)
        ulo = np.uint64(lo)
        for m in range(m0, m1 + 1):
            a = max(lo, int(math.ceil(y0 + m * step))) if m > m0 else lo
            b = min(hi, int(math.ceil(y0 + (m + 1) * step)) - 1) if m < m1 else hi
            slope = g * (irr[m + 1] - irr[m]) / step
            e = g * irr[m] + (a - (y0 + m * step)) * slope
            if two:
                for i in range(np.uint64(a), np.uint64(b + 1)):
                    acc[i] += (val[i - ulo] + val[second + i - ulo]) * e
                    e += slope
            else:
                for i in range(np.uint64(a), np.uint64(b + 1)):
                    acc[i] += val[i - ulo] * e
                    e += slope
        return
    d0 = 0.25 * t0b
    d1 = 0.25 * t1b
    # the subsamples' coordinates at row lo and their step per row
    pa = _fixed(t0a + t0b * lo - d0)
    pb = _fixed(t0a + t0b * lo + d0)
    pc = _fixed(t1a + t1b * lo - d1)
    pd = _fixed(t1a + t1b * lo + d1)
    s0 = np.uint64(np.int64(t0b * _FIXED_ONE))
    s1 = np.uint64(np.int64(t1b * _FIXED_ONE))
    o0 = np.uint64(b0)
    o1 = np.uint64(b1)
    for m in range(m0, m1 + 1):
        a = max(lo, int(math.ceil(y0 + m * step))) if m > m0 else lo
        b = min(hi, int(math.ceil(y0 + (m + 1) * step)) - 1) if m < m1 else hi
        slope = g * (irr[m + 1] - irr[m]) / step
        e = g * irr[m] + (a - (y0 + m * step)) * slope
        if two:
            for i in range(np.uint64(a), np.uint64(b + 1)):
                acc[i] += (_lerp_fixed(buf, o0, pa) + _lerp_fixed(buf, o0, pb) + _lerp_fixed(buf, o1, pc)
                           + _lerp_fixed(buf, o1, pd)) * e
                e += slope
                pa += s0
                pb += s0
                pc += s1
                pd += s1
        else:
            for i in range(np.uint64(a), np.uint64(b + 1)):
                acc[i] += (_lerp_fixed(buf, o0, pa) + _lerp_fixed(buf, o0, pb)) * e
                e += slope
                pa += s0
                pb += s0
