"""Whole-target photometric pose refinement (saturated, small, far or dim targets).

The edge-based pose (:mod:`localizer.measure.subpixel_edges`, :mod:`localizer.measure.exact_pose`) measures each edge on
its own and then fits the pose to eight edge positions. Where the edges are poor that
throws information away. On a saturated frame the bright side of every edge is clipped at 255, so an edge
measured on its own is known only to lie somewhere inside its clipped pixel (up to
~0.6 px for sharp edges: the edge-based pose then carries 2-3 % distance error on
targets ~20 rows tall). The pixels still hold more than the edges taken one at a
time: every edge of the target is tied to the others by the pose, all share one
blur and one pair of grey levels, and every unclipped transition pixel gives its
edge's exact coverage once the (unseen, clipped) bright level is known. This module
fits that whole model to the pixels of the target at once:

    grey(c, r) = (dark + (bright - dark) * b(c, r)) * (1 + slope * s(c)), observed through min(., 255)

with ``b`` the blurred box-pixel fraction of the bright paint at column ``c``, row
``r``: ``1 - bars`` for a positive target (black bars on white), ``bars`` for a
negative one, where ``bars(c, r) = (Fx1(c) + Fx2(c)) * Fy(c, r)``: ``Fx`` the
fractions of the pixel between each bar's two vertical edges, ``Fy`` the fraction
between the top and bottom lines of the target at that column, both blurred by one
sampled Gaussian of sd ``sigma`` on the pixel grid (:func:`localizer._kernels.blur.blurred_step`),
and ``s`` the column's place across the fitted columns (-1 at the first, +1 at the last): the light
on a target is rarely even (a lamp's falloff, vignetting, shading), and one pair of grey levels
over bars lit 3-7 % apart moved a blurred target's alpha by up to 6 deg (envelope benchmark,
blur3: the bars' heights, which carry the orientation near frontal, differ by 0.09 px per degree
at 65 rows, and the fit made up the light's difference with them).
The geometry is the exact pose model's (:mod:`localizer._kernels.projection`): the
target centre at ``(X, Y, Z)`` in the camera frame (m), orientation ``alpha`` (rad, thesis sign), and a point at target
abscissa ``u`` imaging at ``x = cx + fx (X + u cos a) / (Z - u sin a)``; the tops and
bottoms are the lines ``y = cy + fy (Y -+ H/2) / z(c)`` with ``z(c)`` the range where
the ray of column ``c`` meets the target plane.

Clipped observations are censored: a pixel seen at 255 costs nothing while the model
is at or above 255 and ``255 - model`` below it (likewise at 0); an unclipped pixel costs
``model - grey`` with the unclipped model. Eight unknowns (X, Z, alpha, Y, dark,
bright, sigma, slope) by Levenberg-Marquardt with an analytic Jacobian, from the edge-based
pose (and the other root of eq A.14; for an uncertain start also from that pose scaled
along its line of sight and turned by +-12 deg; the lowest cost wins). A start's fit stops
when it reaches the basin of an earlier start's end (it would end there too) or when after
two steps its cost is still a hundred times the best end's (it is headed for a worse
minimum); a certain pose's mirror start is given up before its first step when it starts
from a hundred times the first start's end cost (:data:`~localizer._kernels.photometric.MIRROR_GIVE_UP`); each fit stops when a step, or the step the linear model promises, gains less
than a small share of the cost; the blur sd is held at its bounds (0.2-4 px) rather than
clamped step after step. Only pixels of
the printed target (bars, gap and half of the margin, which is what separates a target
from the background behind it) within a few pixels of an edge enter the fit, at most
``MAX_LINES`` rows along each vertical edge and columns along each top and bottom, so the
cost stays ~0.3-1 ms per target whatever its size (several starts: ~1-3 ms; 512x480
frames of the envelope benchmark, 2 shared cores). The normal equations are formed from
the uncensored pixels' Jacobian rows only; a blurred step of sd >= 1 px costs one ``exp``
per pixel side (:func:`localizer._kernels.blur.gauss_cdf_pdf`), each side shared by the two
pixels that meet there.

What the pixels cannot tell stays untold: on small, sharp, saturated targets the cost
can be flat along a combination of range, orientation and the (clipped, unseen) bright
level, and the fit then lands anywhere in that valley. The caller therefore keeps the
edge-based covariance (:func:`localizer.measure.target_finish.photometric_pose`).

Lens distortion is not modelled: the refinement applies to undistorted cameras only.
"""
from __future__ import annotations

import numpy as np

from localizer._kernels.photometric import ITERATIONS, MARGIN_SHARE, MAX_LINES, REACH, SIGMA_MIN, refine
from localizer._kernels.records import Intrinsics, Levels, TargetConstants

__all__ = ["ITERATIONS", "MARGIN_SHARE", "MAX_LINES", "REACH", "SIGMA_MIN", "refine_pose"]


def refine_pose(image: np.ndarray, camera, target, pose: tuple[float, float, float, float], positive: bool,
                dark: float, bright: float = 255.0, sigma: float = 0.4, alt_alpha: float | None = None,
                wide: bool = True):
    """Refine an edge-based pose of a target on its pixels (module docstring).

    Args:
        image: ``(H, W)`` uint8 grey frame.
        camera: an undistorted :class:`localizer.Camera`.
        target: :class:`localizer.TargetSpec`.
        pose: ``(X, Z, alpha, Y)`` start (m, rad), camera frame (:mod:`localizer._kernels.projection`).
        positive: target polarity.
        dark: start of the dark grey level.
        bright: the bright grey level seen (255 when clipped: the fit then starts above it).
        sigma: start of the blur sd (px).
        alt_alpha: a second orientation to start from (rad; the other root of eq A.14).
        wide: start from several poses around ``pose`` (scaled along the line of sight, turned
            by +-12 deg), for an uncertain start; else from ``pose`` (and ``alt_alpha``) alone.
    Returns:
        ``None`` if the target has too few pixels or the fit is not finite, else
        ``(p, n_pixels, cost)``: ``p`` (8,) = (X, Z, alpha, Y, dark, bright, sigma, slope), the number
        of pixels fitted and the final sum of squared (censored) residuals, grey levels^2. No
        covariance: on clipped targets the normal matrix cannot see the flat directions
        (module docstring), so callers keep the edge-based one.
    """
    pose = np.asarray(pose, np.float64)
    alt = float(pose[2] if alt_alpha is None else alt_alpha)
    ok, p, n, cost = refine(image, pose, alt, Levels(float(dark), float(bright), float(sigma)),
                            Intrinsics(float(camera.fx), float(camera.fy), float(camera.cx), float(camera.cy)),
                            TargetConstants(float(target.bar_width), float(target.bar_height), float(target.margin)),
                            bool(positive), bool(wide))
    if not ok or not np.all(np.isfinite(p)):
        return None
    return p, n, cost
