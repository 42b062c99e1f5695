"""The raycaster's plain face rows: rows of a face span with no decal, filtered texture times irradiance.

Most of a frame's face pixels are such rows (a wall between its decals, above and below a
target). :func:`plain_rows` weights each row's two subsamples in each mip level's texel
column (built by :func:`agvsim.sensors.render._raycast_face.shade_face`) by the face's
irradiance, in one fixed-point loop; :func:`own_reflectance` and :func:`irr_at` sample the
same columns and irradiance at one row (the rows decals reach or the span covers in part).
"""
from __future__ import annotations

import math

import numpy as np

from agvsim.sensors.render.kernel_jit import span_helper

__all__ = ["FIXED_BITS", "irr_at", "own_reflectance", "plain_rows"]

#: fractional bits of the fixed-point texel coordinates of :func:`plain_rows`
FIXED_BITS = 32
_FIXED_ONE = float(1 << FIXED_BITS)
_FIXED_INV = np.float32(1.0 / _FIXED_ONE)  # (float32: the texel columns' interpolation is float32)
_U1 = np.uint64(1)
_UBITS = np.uint64(FIXED_BITS)
_UMASK = np.uint64((1 << FIXED_BITS) - 1)


@span_helper
def _fixed(x):
    """``x >= 0`` texels as a fixed-point integer (:data:`FIXED_BITS` fractional bits), unsigned."""
    return np.uint64(np.int64(x * _FIXED_ONE))


@span_helper
def _lerp_fixed(buf, o, p):
    """``buf[o:]`` interpolated linearly at the fixed-point coordinate ``p`` (unsigned: array
    indices without a test for negative ones)."""
    q = o + (p >> _UBITS)
    return buf[q] + (buf[q + _U1] - buf[q]) * (np.float32(np.int64(p & _UMASK)) * _FIXED_INV)


@span_helper
def _column_at(buf, o, t, n):
    """Linear interpolation of the ``n`` entries ``buf[o:o + n]`` at coordinate ``t`` (clamped)."""
    if t < 0.0:
        t = 0.0
    if t > n - 1.000001:
        t = n - 1.000001
    q = int(t)
    a = np.uint64(o + q)
    return buf[a] + (buf[a + _U1] - buf[a]) * (t - q)


@span_helper
def own_reflectance(buf, cols, ym):
    """The face's own reflectance at row coordinate ``ym``: its two subsample rows (``ym -+
    1/4``), trilinear between the span's two levels (``cols``:
    :class:`~agvsim.sensors.render.ray_records.TexelColumns` in ``buf``)."""
    ta = ym - 0.25
    tb = ym + 0.25
    own = (_column_at(buf, cols.b0, cols.t0a + cols.t0b * ta, cols.n0)
           + _column_at(buf, cols.b0, cols.t0a + cols.t0b * tb, cols.n0))
    if cols.n1 > 0:
        own = own + (_column_at(buf, cols.b1, cols.t1a + cols.t1b * ta, cols.n1)
                     + _column_at(buf, cols.b1, cols.t1a + cols.t1b * tb, cols.n1))
    return 0.5 * own


@span_helper
def irr_at(irr, lit, ym):
    """The span's irradiance at row coordinate ``ym`` (``lit``:
    :class:`~agvsim.sensors.render.ray_records.SpanLight` of ``irr``; linear between samples)."""
    qq = (ym - lit.y0) * lit.inv_step
    mm = min(int(qq), lit.n - 2)
    return irr[mm] + (irr[mm + 1] - irr[mm]) * (qq - mm)


@span_helper
def plain_rows(lo, hi, g, buf, cols, irr, lit, acc):
    """Rows ``lo .. hi`` of a face span that covers them whole, no decal among them, into ``acc``:
    ``g`` x the sum of the two subsamples of each level (``buf``, ``cols``:
    :class:`~agvsim.sensors.render.ray_records.TexelColumns`, the levels' texel columns,
    weighted, float32: interpolated in float32) times the irradiance (``irr``, ``lit``:
    :class:`~agvsim.sensors.render.ray_records.SpanLight`).

    The texel columns reach a row beyond the span's ends (built by
    :func:`agvsim.sensors.render._raycast_face.shade_face`), so the subsamples need no
    clamping. One loop: the subsamples' coordinates step by a constant per row, in fixed point
    (:data:`FIXED_BITS` fractional bits: 2e-10 texel, no float-to-int conversion per sample;
    unsigned, a negative step wrapping modulo 2^64), and the irradiance is stepped linearly
    within each of its segments. Without a second level (``cols.n1 == 0``: magnified, most
    walls) its subsamples (+0.0) are left out of the sum."""
    if hi < lo:
        return
    y0 = lit.y0
    step = lit.step
    n_l = lit.n
    two = cols.n1 > 0
    t0a, t0b, t1a, t1b = cols.t0a, cols.t0b, cols.t1a, cols.t1b
    m0 = min(max(int((lo - y0) / step), 0), n_l - 2)
    m1 = min(max(int((hi - y0) / step), 0), n_l - 2)
    d0 = 0.25 * t0b
    d1 = 0.25 * t1b
    # the subsamples' coordinates at row lo and their step per row
    pa = _fixed(t0a + t0b * lo - d0)
    pb = _fixed(t0a + t0b * lo + d0)
    pc = _fixed(t1a + t1b * lo - d1)
    pd = _fixed(t1a + t1b * lo + d1)
    s0 = np.uint64(np.int64(t0b * _FIXED_ONE))
    s1 = np.uint64(np.int64(t1b * _FIXED_ONE))
    o0 = np.uint64(cols.b0)
    o1 = np.uint64(cols.b1)
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
