"""The thesis's pose (§4.1-4.2): eqs 4.3, 4.4, 4.5 and 4.12-4.15 on the half-pixel edges.

Units: pixels in, metres and radians out. Conventions: :mod:`localizer.model.geometry`.
Image quantities are converted with the camera's focal lengths instead of the
thesis's millimetre factors (§4.7): ``x_m / f = (x - cx) / fx``,
``h_m / f = h / fy``.
"""
from __future__ import annotations

import math

import numpy as np

from localizer.model.camera import Camera
from localizer.measure.edges import EdgeMeasurements
from localizer.measure.pose import PoseEstimate
from localizer.model.target import TargetSpec


def thesis_alpha(ratio: float, beta_p: float, sign: int) -> tuple[float, tuple[float, float], bool]:
    """Solve eq 4.12 for alpha with the §4.2.2 rule.

    Args:
        ratio: ``(H/W) * (dx/dy)``, the measured width/height ratio over the true one.
        beta_p: beta' (rad), the bearing of the image mid-point m (eq 4.4).
        sign: +1 if the right bar is taller (right edge nearer, alpha > 0), -1 if
            the left bar is taller, 0 if undecided
            (:func:`localizer.thesis.edges.height_sign`: the subpixel heights averaged
            over each bar's columns, else the half-pixel heights at the bar centres).
    Returns:
        ``(alpha, (alpha1, alpha2), ambiguous)``. ``alpha1 = beta' + phi`` (4.14),
        ``alpha2 = beta' - phi`` (4.15), ``phi = acos(ratio * cos beta')`` (argument
        clipped to [-1, 1]). The root whose sign agrees with ``sign`` is taken; if
        both agree (the interval ``0..2 beta'`` of §4.2.2) the one of larger
        magnitude, which reproduces the thesis's over-estimates at small angles
        (Tables 5.3-5.4: 0 -> 4.4, 5 -> 13, 0 -> 6.8, 10 -> 14.5 degrees); if none
        agrees, the one nearer zero. When the sign is undecided (``sign`` 0: the bar
        heights equal) the target is assumed turned towards the
        camera: the sign of beta' is used (the root nearer zero if beta' is 0 too).
    """
    phi = math.acos(min(1.0, max(-1.0, ratio * math.cos(beta_p))))
    a1, a2 = beta_p + phi, beta_p - phi
    if sign == 0:
        if beta_p != 0.0:
            return (a1 if beta_p > 0 else a2), (a1, a2), True
        return (a1 if abs(a1) <= abs(a2) else a2), (a1, a2), True
    ok = [a for a in (a1, a2) if a * sign >= 0]
    if len(ok) == 2:
        return (a1 if abs(a1) >= abs(a2) else a2), (a1, a2), True
    if len(ok) == 1:
        return ok[0], (a1, a2), False
    return (a1 if abs(a1) <= abs(a2) else a2), (a1, a2), False


def _thesis_core(edges_x: np.ndarray, h1: float, h2: float, camera: Camera, target: TargetSpec, sign: int):
    w = edges_x[3] - edges_x[0]  # target width in the image (px), §4.7
    h = 0.5 * (h1 + h2)  # centre height (px)
    xc = 0.25 * (edges_x[0] + edges_x[1] + edges_x[2] + edges_x[3])  # mean of the bar centre lines
    z = target.bar_height * camera.fy / h  # eq 4.3 / 4.11
    tb = (xc - camera.cx) / camera.fx  # eq 4.4
    beta_p = math.atan(tb)
    d = z * math.sqrt(1.0 + tb * tb)  # eq 4.5
    ratio = target.active_height / target.active_width * (w / camera.fx) / (h / camera.fy)
    alpha, cands, amb = thesis_alpha(ratio, beta_p, sign)
    return d, beta_p, alpha, z, cands, amb


def thesis_pose(m: EdgeMeasurements, camera: Camera, target: TargetSpec) -> PoseEstimate:
    """Eqs 4.3, 4.4, 4.5 and 4.13 on the half-pixel measurements.

    The covariance propagates the half-pixel rule's uniform +-0.5 px error of
    each edge through the equations by secant differences of one standard
    deviation (finite near the acos singularity). The root is the one of the sign of
    ``m.height_sign`` (eqs 4.14-4.15; for measurements without one, the sign of the
    bar-centre heights' difference); unless that sign was measured beyond its noise
    (:attr:`EdgeMeasurements.height_sign_sure`) and the roots differ in sign, the
    estimate is ``ambiguous`` and the variance of alpha includes the roots' spread.
    """
    h1, h2 = (float(v) for v in m.bar_heights)
    ex = np.asarray(m.edges_x, float)
    sign = m.height_sign or (0 if abs(h2 - h1) < 1e-9 else (1 if h2 > h1 else -1))
    d, beta_p, alpha, z, cands, amb = _thesis_core(ex, h1, h2, camera, target, sign)
    amb = amb or (not m.height_sign_sure and cands[0] * cands[1] < 0)
    base = np.array([d, beta_p, alpha])
    s = float(m.edges_sigma[0])
    cols = []
    for k in range(4):
        e = ex.copy()
        e[k] += s
        dd, bb, aa, *_ = _thesis_core(e, h1, h2, camera, target, sign)
        cols.append((np.array([dd, bb, aa]) - base))
    for k in range(2):
        hh = [h1, h2]
        hh[k] += s * math.sqrt(2.0)
        # the sign decision is the measurement's own
        dd, bb, aa, *_ = _thesis_core(ex, hh[0], hh[1], camera, target, sign)
        if (aa > 0) != (alpha > 0) and abs(alpha) > 1e-9:
            aa = alpha
        cols.append((np.array([dd, bb, aa]) - base))
    J = np.stack(cols, axis=1)  # already scaled by one sigma
    cov = J @ J.T
    # the sign choice of 4.13 can flip the whole root: add the root spread when ambiguous
    if amb:
        cov[2, 2] += (0.5 * (cands[0] - cands[1])) ** 2
    x = z * math.tan(beta_p)
    return PoseEstimate(d, beta_p, alpha, z, x, float("nan"), cov, cands, amb)
