"""Compiled sensor stages of the raycast backend: sensor noise and exposure, motion blur.

The same models as :mod:`agvsim.sensors.render.sensor` (which the pyrender backend runs
in NumPy and OpenCV), written per pixel so that a frame costs a fraction of a millisecond:

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
  sideways; the vertical drift is a small fraction of a pixel at AGV speeds).

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
from numba.cpython.unsafe.numbers import leading_zeros

from localizer._jit import fast_inline as inline
from localizer._jit import fast_jit as jit

__all__ = ["expose", "motion_blur", "normal_pair", "splitmix64", "standard_normals"]

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
def motion_blur(radiance, depth, fx, fy, cx, cy, rot_a, tr_a, rot_b, tr_b, out, prefix, path):
    """Average each pixel along its scene point's image path between the exposure's ends.

    Args:
        radiance, depth: ``(H, W)`` float32 (depth m along the axis, 0 = far).
        rot_a, tr_a, rot_b, tr_b: ``(3, 3)``, ``(3,)``: camera(t) -> camera(0) motion at the
            start and end of the exposure (camera frame, m).
        out: ``(H, W)`` float32, written. prefix: ``(H, W + 1)`` float64 and path: ``(3, H, W)``
            float32 scratch.
    """
    h, w = radiance.shape
    # prefix[i, j] = sum of row i's pixels 0 .. j - 1 (pixel j covers x = j - 0.5 .. j + 0.5)
    for i in range(h):
        acc = 0.0
        prefix[i, 0] = 0.0
        for j in range(w):
            acc += radiance[i, j]
            prefix[i, j + 1] = acc
    a00, a01, a02 = rot_a[0, 0], rot_a[0, 1], rot_a[0, 2]
    a10, a11, a12 = rot_a[1, 0], rot_a[1, 1], rot_a[1, 2]
    a20, a21, a22 = rot_a[2, 0], rot_a[2, 1], rot_a[2, 2]
    b00, b01, b02 = rot_b[0, 0], rot_b[0, 1], rot_b[0, 2]
    b10, b11, b12 = rot_b[1, 0], rot_b[1, 1], rot_b[1, 2]
    b20, b21, b22 = rot_b[2, 0], rot_b[2, 1], rot_b[2, 2]
    ta0, ta1, ta2 = tr_a[0], tr_a[1], tr_a[2]
    tb0, tb1, tb2 = tr_b[0], tr_b[1], tr_b[2]
    inv_fx = 1.0 / fx
    inv_fy = 1.0 / fy
    # pass 1 (vectorised): each pixel's path, x from x0 to x1 at row ym
    for i in range(h):
        yn = (i - cy) * inv_fy
        for j in range(w):
            z = depth[i, j]
            z = z if z > 0.0 else 1.0e3
            X = (j - cx) * inv_fx * z
            Y = yn * z
            pxa = a00 * X + a01 * Y + a02 * z + ta0
            pya = a10 * X + a11 * Y + a12 * z + ta1
            qa = 1.0 / max(a20 * X + a21 * Y + a22 * z + ta2, 1e-3)
            pxb = b00 * X + b01 * Y + b02 * z + tb0
            pyb = b10 * X + b11 * Y + b12 * z + tb1
            qb = 1.0 / max(b20 * X + b21 * Y + b22 * z + tb2, 1e-3)
            ax = cx + fx * pxa * qa
            bx = cx + fx * pxb * qb
            lo = min(max(min(ax, bx), -0.5), w - 0.5 - 1e-3)
            hi = min(max(max(ax, bx), lo + 1e-3), w - 0.5)
            path[0, i, j] = lo + 0.5
            path[1, i, j] = hi + 0.5
            path[2, i, j] = min(max(cy + 0.5 * fy * (pya * qa + pyb * qb), 0.0), h - 1.0)
    # pass 2: the row integrals (piecewise constant pixels) between x0 and x1, rows blended at ym
    for i in range(h):
        for j in range(w):
            k0 = path[0, i, j]
            k1 = path[1, i, j]
            ym = path[2, i, j]
            r0 = min(int(ym), h - 2)
            fr = ym - r0
            a0 = min(int(k0), w - 1)
            a1 = min(int(k1), w - 1)
            f0 = k0 - a0
            f1 = k1 - a1
            s0 = (prefix[r0, a1] + f1 * (prefix[r0, a1 + 1] - prefix[r0, a1])
                  - prefix[r0, a0] - f0 * (prefix[r0, a0 + 1] - prefix[r0, a0]))
            s1 = (prefix[r0 + 1, a1] + f1 * (prefix[r0 + 1, a1 + 1] - prefix[r0 + 1, a1])
                  - prefix[r0 + 1, a0] - f0 * (prefix[r0 + 1, a0 + 1] - prefix[r0 + 1, a0]))
            out[i, j] = (s0 + (s1 - s0) * fr) / (k1 - k0)
