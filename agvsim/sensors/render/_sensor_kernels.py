"""Compiled sensor stages of the raycast backend: sensor noise and exposure, motion blur.

The same models as :mod:`agvsim.sensors.render.sensor` (which the pyrender backend runs
in NumPy and OpenCV), written per pixel so that a frame costs a fraction of a millisecond:

* :func:`expose_t`: gain, flare, shot + read noise, saturation, 8 bits. The noise is
  Gaussian (Marsaglia and Tsang's ziggurat) from a counter-based generator (SplitMix64
  of the frame's seed and the pixel's index): every frame draws a fresh seed from the
  run's ``numpy.random.Generator``, so frames never share a noise pattern and the same
  seed gives the same frame bit for bit.
* :func:`motion_blur_t`: each pixel averages the scene along the path its scene point
  takes across the image during the exposure (static scene, the camera's twist, the
  pixel's depth), as :func:`agvsim.sensors.render.sensor.motion_blur`; the path's
  horizontal extent is integrated exactly (row prefix sums), its vertical position is
  taken at the path's midpoint (a level camera moving in the floor plane smears rows
  sideways; the vertical drift is a small fraction of a pixel at AGV speeds).

Images are *transposed* ``(W, H)`` float32 (column-major), as the raycaster draws them.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import fast_inline as inline
from localizer._jit import fast_jit as jit

__all__ = ["ZIGGURAT", "expose_t", "motion_blur_t", "standard_normal_from"]


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
def expose_t(radiance_t, params, out):
    """Radiance -> 8-bit grey (:func:`agvsim.sensors.render.sensor.expose`'s model).

    Args:
        radiance_t: ``(W, H)`` float32 linear radiance, transposed.
        params: :class:`~agvsim.sensors.render.ray_records.SensorParams`.
        out: ``(H, W)`` uint8, written.
    """
    w, h = radiance_t.shape
    scale = params.scale
    flare = params.flare
    inv_e = 1.0 / params.electrons_per_grey
    read2 = params.read_noise * params.read_noise
    ns = params.noise_scale
    seed = np.uint64(params.seed)
    for j in range(w):
        for i in range(h):
            g = radiance_t[j, i] * scale + flare
            if ns > 0.0:
                state = seed ^ (np.uint64(i * w + j) * _M2)
                z, state = standard_normal_from(state)
                g += z * math.sqrt(max(g, 0.0) * inv_e + read2) * ns
            v = math.floor(g + 0.5)
            out[i, j] = np.uint8(0 if v < 0.0 else (255 if v > 255.0 else v))


@jit
def motion_blur_t(radiance_t, depth_t, fx, fy, cx, cy, rot_a, tr_a, rot_b, tr_b, out_t, prefix):
    """Average each pixel along its scene point's image path between the exposure's ends.

    Args:
        radiance_t, depth_t: ``(W, H)`` float32 (depth m along the axis, 0 = far), transposed.
        rot_a, tr_a, rot_b, tr_b: ``(3, 3)``, ``(3,)``: camera(t) -> camera(0) motion at the
            start and end of the exposure (camera frame, m).
        out_t: ``(W, H)`` float32, written. prefix: ``(H, W + 1)`` float64 scratch.
    """
    w, h = radiance_t.shape
    # prefix[i, j] = sum of row i's pixels 0 .. j - 1 (pixel j covers x = j - 0.5 .. j + 0.5)
    for i in range(h):
        prefix[i, 0] = 0.0
    for j in range(w):
        for i in range(h):
            prefix[i, j + 1] = prefix[i, j] + radiance_t[j, i]
    for j in range(w):
        xn = (j - cx) / fx
        for i in range(h):
            z = depth_t[j, i]
            if z <= 0.0:
                z = 1.0e3
            yn = (i - cy) / fy
            X = xn * z
            Y = yn * z
            px = rot_a[0, 0] * X + rot_a[0, 1] * Y + rot_a[0, 2] * z + tr_a[0]
            py = rot_a[1, 0] * X + rot_a[1, 1] * Y + rot_a[1, 2] * z + tr_a[1]
            pz = max(rot_a[2, 0] * X + rot_a[2, 1] * Y + rot_a[2, 2] * z + tr_a[2], 1e-3)
            ax = cx + fx * px / pz
            ay = cy + fy * py / pz
            px = rot_b[0, 0] * X + rot_b[0, 1] * Y + rot_b[0, 2] * z + tr_b[0]
            py = rot_b[1, 0] * X + rot_b[1, 1] * Y + rot_b[1, 2] * z + tr_b[1]
            pz = max(rot_b[2, 0] * X + rot_b[2, 1] * Y + rot_b[2, 2] * z + tr_b[2], 1e-3)
            bx = cx + fx * px / pz
            by = cy + fy * py / pz
            x0 = min(max(min(ax, bx), -0.5), w - 0.5)
            x1 = min(max(max(ax, bx), -0.5), w - 0.5)
            ym = min(max(0.5 * (ay + by), 0.0), h - 1.0)
            r0 = int(ym)
            r1 = min(r0 + 1, h - 1)
            fr = ym - r0
            if x1 - x0 < 1e-3:
                xm = min(max(0.5 * (x0 + x1), 0.0), w - 1.0)
                c0 = int(xm)
                c1 = min(c0 + 1, w - 1)
                fc = xm - c0
                v0 = radiance_t[c0, r0] * (1.0 - fc) + radiance_t[c1, r0] * fc
                v1 = radiance_t[c0, r1] * (1.0 - fc) + radiance_t[c1, r1] * fc
            else:
                # the integral of a row from x0 to x1 (piecewise constant pixels)
                k0 = x0 + 0.5
                k1 = x1 + 0.5
                a0 = min(int(k0), w - 1)
                a1 = min(int(k1), w - 1)
                f0 = k0 - a0
                f1 = k1 - a1
                inv = 1.0 / (x1 - x0)
                s0 = (prefix[r0, a1] + f1 * (prefix[r0, a1 + 1] - prefix[r0, a1])
                      - prefix[r0, a0] - f0 * (prefix[r0, a0 + 1] - prefix[r0, a0]))
                s1 = (prefix[r1, a1] + f1 * (prefix[r1, a1 + 1] - prefix[r1, a1])
                      - prefix[r1, a0] - f0 * (prefix[r1, a0 + 1] - prefix[r1, a0]))
                v0 = s0 * inv
                v1 = s1 * inv
            out_t[j, i] = v0 * (1.0 - fr) + v1 * fr
