"""Compiled sensor stages of the raycast backend: sensor noise and exposure, motion blur.

The same models as :mod:`agvsim.sensors.render.sensor` (which the pyrender backend runs
in NumPy and OpenCV), written per pixel so that a frame costs a fraction of a millisecond:

* :func:`expose`: gain, flare, shot + read noise, saturation, 8 bits. The noise is
  Gaussian (Marsaglia and Tsang's ziggurat) from a counter-based generator (SplitMix64
  of the frame's seed and the pixel's index): every frame draws a fresh seed from the
  run's ``numpy.random.Generator``, so frames never share a noise pattern and the same
  seed gives the same frame bit for bit.
* :func:`motion_blur`: each pixel averages the scene along the path its scene point
  takes across the image during the exposure (static scene, the camera's twist, the
  pixel's depth), as :func:`agvsim.sensors.render.sensor.motion_blur`; the path's
  horizontal extent is integrated exactly (row prefix sums), its vertical position is
  taken at the path's midpoint (a level camera moving in the floor plane smears rows
  sideways; the vertical drift is a small fraction of a pixel at AGV speeds).

Images are ``(H, W)`` float32 (radiance, depth in m along the optical axis, 0 = far).
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import fast_inline as inline
from localizer._jit import fast_jit as jit

__all__ = ["ZIGGURAT", "expose", "motion_blur", "standard_normal_from"]


def _ziggurat_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Marsaglia and Tsang's 128-layer ziggurat for the standard normal (``kn``, ``wn``, ``fn``)."""
    m1 = 2147483648.0
    dn = tn = 3.442619855899
    vn = 9.91256303526217e-3
    kn = np.zeros(128, np.int64)
    wn = np.zeros(128)
    fn = np.zeros(128)
    q = vn / math.exp(-0.5 * dn * dn)
    kn[0] = int((dn / q) * m1)
    kn[1] = 0
    wn[0] = q / m1
    wn[127] = dn / m1
    fn[0] = 1.0
    fn[127] = math.exp(-0.5 * dn * dn)
    for i in range(126, 0, -1):
        dn = math.sqrt(-2.0 * math.log(vn / dn + math.exp(-0.5 * dn * dn)))
        kn[i + 1] = int((dn / tn) * m1)
        tn = dn
        fn[i] = math.exp(-0.5 * dn * dn)
        wn[i] = dn / m1
    return kn, wn, fn


#: ``(kn, wn, fn)`` of the ziggurat (module docstring)
ZIGGURAT = _ziggurat_tables()
_KN, _WN, _FN = ZIGGURAT
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_ZIG_R = 3.442619855899


@inline
def _mix(x):
    """SplitMix64's output function."""
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


@inline
def _uniform(x):
    """A double in (0, 1) from 64 random bits."""
    return ((x >> np.uint64(11)) + 0.5) * (1.0 / 9007199254740992.0)


@inline
def standard_normal_from(state):
    """One standard normal draw from the stream at ``state`` (uint64): ``(value, next state)``."""
    state = state + _GOLDEN
    bits = _mix(state)
    hz = np.int64(np.int32(bits & np.uint64(0xFFFFFFFF)))
    iz = hz & 127
    if abs(hz) < _KN[iz]:
        return hz * _WN[iz], state
    while True:
        x = hz * _WN[iz]
        if iz == 0:
            while True:
                state = state + _GOLDEN
                xx = -math.log(_uniform(_mix(state))) / _ZIG_R
                state = state + _GOLDEN
                yy = -math.log(_uniform(_mix(state)))
                if yy + yy >= xx * xx:
                    break
            return (_ZIG_R + xx if hz > 0 else -_ZIG_R - xx), state
        state = state + _GOLDEN
        if _FN[iz] + _uniform(_mix(state)) * (_FN[iz - 1] - _FN[iz]) < math.exp(-0.5 * x * x):
            return x, state
        state = state + _GOLDEN
        bits = _mix(state)
        hz = np.int64(np.int32(bits & np.uint64(0xFFFFFFFF)))
        iz = hz & 127
        if abs(hz) < _KN[iz]:
            return hz * _WN[iz], state


@jit
def expose(radiance, params, out):
    """Radiance -> 8-bit grey (:func:`agvsim.sensors.render.sensor.expose`'s model).

    Args:
        radiance: ``(H, W)`` float32 linear radiance.
        params: :class:`~agvsim.sensors.render.ray_records.SensorParams`.
        out: ``(H, W)`` uint8, written.
    """
    h, w = radiance.shape
    scale = params.scale
    flare = params.flare
    inv_e = 1.0 / params.electrons_per_grey
    read2 = params.read_noise * params.read_noise
    ns = params.noise_scale
    seed = np.uint64(params.seed)
    for i in range(h):
        for j in range(w):
            g = radiance[i, j] * scale + flare
            if ns > 0.0:
                state = seed ^ (np.uint64(i * w + j) * _M2)
                z, state = standard_normal_from(state)
                g += z * math.sqrt(max(g, 0.0) * inv_e + read2) * ns
            v = math.floor(g + 0.5)
            out[i, j] = np.uint8(0 if v < 0.0 else (255 if v > 255.0 else v))


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
