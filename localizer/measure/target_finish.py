"""The last steps of a target's pose in :func:`localizer.detect_targets`: the photometric
refinement where its edges fall short (:func:`photometric_pose`), and the checks every reported
pose passes (:func:`finish`); the sRGB-linearized window's camera and stack for the refinement
(:func:`window_parts`).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from localizer._kernels.clipped import SIGMA_BLURRED
from localizer.model.camera import Camera
from localizer.model.params import DetectorParams
from localizer.measure.photometric import refine_pose
from localizer.model.target import TargetSpec

__all__ = ["BLURRED_ALPHA_SHARE", "MAX_ALPHA", "MAX_FIT_RMS", "PHOTOMETRIC_GATE", "SRGB_TO_LINEAR", "finish",
           "linear_grey", "photometric_pose", "window_parts"]

#: an exact fit whose normalised residual (``sqrt(chi2 / 3)``) exceeds this is not a target:
#: true targets reach 2.2 on the envelope benchmark's independent frames (dim light) and 3.7 in
#: 4,800 frames of the accuracy sweep (a saturated target 7.6 m away); a pair of strokes of
#: lettering, or a stroke beside a light strip, fits with 4 to 7
MAX_FIT_RMS = 5.0
#: the largest |alpha| of a reported pose (rad)
MAX_ALPHA = math.radians(89.0)
#: largest Mahalanobis distance (under the edge-based covariance) of an accepted photometric
#: refinement from the edge-based pose; on 1,648 refinements of the accuracy sweep the
#: largest was 4.9
PHOTOMETRIC_GATE = 6.0
#: a blurred target's orientation (:func:`photometric_pose`): this share of the refinement's move
#: from the edge-based one. On the envelope's blur3 frames (seeds 0-6, bars >= 60 rows, the
#: refinement with its light slope) the alpha error from the edges, their mean and the refinement:
#: mean 0.30, 0.28, 0.28 deg, max 5.0, 2.6, 3.2 deg (without the slope the refinement's max was
#: 9 deg, the mean's 5.9). The range stays the refinement's
BLURRED_ALPHA_SHARE = 0.5
#: the sRGB curve's inverse, code for code (8 bits): linear light of an sRGB-encoded grey level
SRGB_TO_LINEAR = np.clip(np.rint(255.0 * np.where(np.arange(256) <= 10.31475, np.arange(256) / (255.0 * 12.92),
                                                  ((np.arange(256) / 255.0 + 0.055) / 1.055) ** 2.4)), 0, 255
                         ).astype(np.uint8)

def finish(img: np.ndarray, camera: Camera, target: TargetSpec, v, p: DetectorParams, est, blur: float,
            saturated: bool, pending, refine: bool = True):
    """The edge-based pose ``est`` of the verified stack ``v`` (``blur`` its blur sd, px) refined
    on the pixels ``img`` as ``p.photometric`` says (when ``refine``; ``pending``: the frame's
    camera, stack and box of the linearized window ``img``, whose own camera and stack are made
    only for a refinement), then checked: None when it is not in front of the camera, faces it
    at more than :data:`MAX_ALPHA`, fits worse than :data:`MAX_FIT_RMS` or has a covariance
    that is not finite."""
    if refine and p.photometric != "off" and not camera.has_distortion and est.z > 0 and math.isfinite(est.distance):
        c = est.covariance
        # "uncertain": the edges' pose falls short of what the refinement is for (DetectorParams)
        uncertain = bool(abs(c[2, 2]) > p.refine_alpha_sd ** 2 or abs(c[0, 0]) > (p.refine_range_sd * est.distance) ** 2)
        if p.photometric == "all" or (p.photometric == "clipped" and saturated) or (p.photometric == "auto" and uncertain):
            # an uncertain saturated pose may be off by more than the fit's basin: several starts
            if pending is not None:
                camera, v = window_parts(*pending)
            est = photometric_pose(img, camera, target, v, est, uncertain and saturated, blur)
    if not (est.z > 0 and math.isfinite(est.distance) and abs(est.alpha) < MAX_ALPHA
            and est.rms < MAX_FIT_RMS and all(math.isfinite(x) for x in est.covariance.ravel().tolist())):
        return None
    return est


def window_parts(camera: Camera, v, box: tuple[int, int, int, int]):
    """``(camera, stack)`` of the linearized window ``box = (r0, r1, c0, c1)`` of a frame
    (:func:`localizer.detect._linear_box`): ``camera`` with its principal point moved by the window's first column
    ``c0`` and row ``r0``, and ``v`` in the window's pixels with its grey levels linearized."""
    r0, r1, c0, c1 = box
    cam = camera.cropped(c0, r0, c1, r1)
    lv = dataclasses.replace(v, rows=v.rows - r0, x=v.x - c0, ends=tuple((int(a) - r0, int(b) - r0) for a, b in v.ends),
                             median_x=None if v.median_x is None else v.median_x - c0,
                             dark=linear_grey(v.dark), bright=linear_grey(v.bright))
    return cam, lv


def linear_grey(g: float) -> float:
    """:data:`SRGB_TO_LINEAR` at the grey level ``g`` (0..255), interpolated."""
    i = min(max(int(g), 0), 254)
    f = min(max(g - i, 0.0), 1.0)
    return float((1.0 - f) * int(SRGB_TO_LINEAR[i]) + f * int(SRGB_TO_LINEAR[i + 1]))


def photometric_pose(img: np.ndarray, camera: Camera, target: TargetSpec, v, est, wide: bool, blur: float):
    """The edge-based pose ``est`` refined on the target's pixels (:mod:`localizer.measure.photometric`),
    from several starts when ``wide``.

    The edge-based covariance is kept: on clipped targets the censored pixels make the fit's
    own normal matrix blind to the directions in which clipped edges can slide, and on the
    others its pixel-level model error (background bleeding into the margin, the blur
    model) is not in it; the edge-based covariance (with its per-edge floor for clipped
    pixels) is the conservative statement. On a blurred target (``blur``, the row-mean
    profile's sd, px, at least :data:`~localizer._kernels.clipped.SIGMA_BLURRED`) the fit starts
    from that blur, and the difference ``dv`` between the two estimates is added to the
    covariance (``+ dv dv^T``): the two models of its edges (a Gaussian blur in both) disagree
    by more than the edges' noise where the blur is as wide as a bar."""
    alt = [a for a in est.alpha_candidates if abs(a - est.alpha) > 0.01]
    blurred = blur >= SIGMA_BLURRED
    try:
        r = refine_pose(img, camera, target, (est.x, est.z, est.alpha, est.height), bool(v.positive),
                        float(v.dark), float(v.bright), sigma=blur if blurred else 0.4,
                        alt_alpha=alt[0] if alt else None, wide=wide)
    except (np.linalg.LinAlgError, ZeroDivisionError, FloatingPointError):  # a degenerate fit: the edges' answer
        return est
    if r is None:
        return est
    X, Z, alpha, Y = (float(x) for x in r[0][:4])
    if not (Z > 0 and abs(alpha) < math.radians(89.0)):
        return est
    d, beta = math.hypot(X, Z), math.atan2(X, Z)
    # a refinement far outside the edge-based covariance means the pixel model does not hold
    # here (something across the target, uneven light): keep the edges' answer
    dv = np.array([d - est.distance, beta - est.beta, alpha - est.alpha])
    if not float(dv @ np.linalg.solve(est.covariance, dv)) <= PHOTOMETRIC_GATE ** 2:
        return est
    cov = est.covariance
    if blurred:  # two models of a blurred target's edges that disagree: at least as uncertain as their difference
        cov = cov + np.outer(dv, dv)
        # the orientation rests on sub-pixel differences of the bars' widths and heights, where what
        # the pixel model still leaves out at this blur (light that is not linear across the
        # target, the wall's glow into the margins) moves its alpha by about as much as the edges'
        # noise, the two errors nearly independent: their mean (:data:`BLURRED_ALPHA_SHARE`)
        alpha = est.alpha + BLURRED_ALPHA_SHARE * (alpha - est.alpha)
    return dataclasses.replace(est, distance=d, beta=beta, alpha=alpha, z=Z, x=X, height=Y, covariance=cov)
