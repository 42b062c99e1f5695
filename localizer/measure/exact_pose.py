"""The perspective-exact pose (Appendix A) by weighted Gauss-Newton over every measured edge.

Units: pixels in, metres and radians out. Conventions: :mod:`localizer.model.geometry`.
Kernels: :mod:`localizer._kernels.exact_pose` (the model and the fit) and
:mod:`localizer._kernels.measure` (edges, target test and fit in one call).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from localizer._kernels import measure
from localizer._kernels.exact_pose import alpha_a14, fit
from localizer._kernels.records import ExactSettings, FitStatus, MeasuredEdges, PoseFit, as_record
from localizer.model.camera import Camera
from localizer.measure.edges import EdgeMeasurements
from localizer.measure.pose import PoseEstimate
from localizer.model.target import TargetSpec

__all__ = ["ExactSettings", "alpha_a14", "exact_measure", "exact_measure_lut", "exact_pose"]


def exact_pose(m: EdgeMeasurements, camera: Camera, target: TargetSpec, positive: bool,
               sigma_floor: float = 0.05, iterations: int = 8) -> PoseEstimate:
    """Perspective-exact pose by weighted Gauss-Newton over every measured edge.

    Unknowns ``(X, Z, alpha, Y, delta)``: target centre (m), orientation (rad), and
    ``delta`` (px), the common shift of every edge towards its dark side (blur
    asymmetry, saturation clipping) -- identifiable because the gap and the bars
    are equally wide on the target.

    Far away the widths alone allow two orientations (the thesis's ambiguity,
    §4.2.2; the mirror solution about the line of sight) and only the small
    bar-height difference separates them. The fit is therefore started from
    the root of Appendix A's analytic solution (eq A.14) nearer the bar-height
    estimate and again from the other root (unless the two are within 0.5 deg);
    the better minimum is reported. When the other one is not ruled out (chi-square difference below
    16) the covariance is widened by the separation of the two minima, weighted
    by their relative likelihood, so that it says honestly how little the image
    tells about alpha.

    Measurement standard deviations are the edges' standard errors plus
    ``sigma_floor`` (px) in quadrature; the covariance is ``(J^T W J)^-1``
    scaled up by the reduced chi-square when it exceeds one, mapped to
    (d, beta, alpha).
    """
    edges = MeasuredEdges(m.edges_x, m.edges_sigma, m.bar_cx, m.top_y, m.bottom_y, m.top_sigma, m.bottom_sigma)
    return _estimate(fit(edges, camera.intrinsics, target.constants, bool(positive), float(sigma_floor),
                         int(iterations)))


def _estimate(f: PoseFit) -> PoseEstimate:
    """The :class:`PoseEstimate` of a :func:`localizer._kernels.exact_pose.fit` result (raises
    ``LinAlgError`` on failure)."""
    if f.status == FitStatus.SINGULAR:
        raise np.linalg.LinAlgError("singular normal equations in the pose fit")
    if f.status == FitStatus.BEHIND:
        raise np.linalg.LinAlgError("no pose fit converged")
    X, Z, alpha, Y, delta = f.p.tolist()
    return PoseEstimate(math.hypot(X, Z), math.atan2(X, Z), alpha, Z, X, Y, f.cov, (f.alpha1, f.alpha2),
                        f.n_solutions > 1, delta, math.sqrt(f.chi2 / 3.0))  # 8 measurements, 5 unknowns


def exact_measure(image: np.ndarray, camera: Camera, target: TargetSpec, st, settings: ExactSettings):
    """:func:`localizer.measure.subpixel_edges.subpixel_edges`, the target test of
    :func:`localizer._kernels.target_test.makes_target` and :func:`exact_pose` of the
    verified stack ``st`` of ``image`` (``(H, W)`` uint8), in one compiled call
    (:func:`localizer._kernels.measure.measure`, the one the fused frame call makes too), for a
    camera without lens distortion: the per-target path of ``detect_targets``, where Python
    between the steps cost as much as the steps. ``settings``: the per-edge error floor (px),
    the Gauss-Newton iterations and the target test's tolerances.

    Returns ``(edges, bar_cx, top, bottom, pose)``: tuples of pixel coordinates (4, 2, 2, 2)
    and the :class:`PoseEstimate` (None when the edges do not make a target or the fit
    fails).
    """
    return _unpack(measure.measure(image, *_stack(st), camera.intrinsics_record, target.constants_record,
                                   _settings(settings)))


def exact_measure_lut(image: np.ndarray, lut: np.ndarray, box: tuple[int, int, int, int], camera: Camera,
                      target: TargetSpec, st, settings: ExactSettings):
    """:func:`exact_measure` of the window ``box = (r0, r1, c0, c1)`` of ``image`` (rows ``r0:r1``,
    columns ``c0:c1``) with its grey levels passed through ``lut`` ``(256,)`` uint8, in one
    compiled call (:func:`localizer._kernels.measure.measure_lut`; ``st`` in the frame's
    pixels). Returns ``(edges, bar_cx, top, bottom, pose, window)``: as :func:`exact_measure`'s,
    in the window's pixels, and the ``(r1 - r0, c1 - c0)`` uint8 window measured."""
    r0, r1, c0, c1 = box
    r, window = measure.measure_lut(image, lut, (int(r0), int(r1), int(c0), int(c1)), *_stack(st),
                                    camera.intrinsics_record, target.constants_record, _settings(settings))
    return (*_unpack(r), window)


def _stack(st) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """The verified stack ``st``'s ``(rows, bounds, ends, positive)`` as the compiled measurement
    takes them (the types the fused frame call passes: one compiled kernel): ``(n,)`` int64 rows,
    ``(4,)`` float64 median run boundaries, ``(2, 2)`` int64 rough bar ends."""
    return (np.ascontiguousarray(st.rows, np.int64), np.ascontiguousarray(st.bounds, np.float64),
            np.array(st.ends, np.int64).reshape(2, 2), bool(st.positive))


def _unpack(r: np.ndarray):
    """``(edges, bar_cx, top, bottom, pose)`` of an :data:`~localizer._kernels.records.EXACT_RESULT` record."""
    (found, e0, e1, e2, e3, cx1, cx2, t1, t2, b1, b2, d, beta, alpha, z, x, height, bias, a1, a2, nsols, chi2,
     blur, cov), = r.tolist()
    est = None
    if found:
        est = PoseEstimate(d, beta, alpha, z, x, height, cov, (a1, a2), nsols > 1, bias,
                           math.sqrt(chi2 / 3.0), blur)  # 8 measurements, 5 unknowns
    return (e0, e1, e2, e3), (cx1, cx2), (t1, t2), (b1, b2), est


@functools.lru_cache(maxsize=64)
def _settings(settings: ExactSettings) -> np.ndarray:
    """The :data:`~localizer._kernels.records.EXACT_SETTINGS` record of ``settings`` (cached;
    the caller must not change it)."""
    return as_record(ExactSettings(float(settings.sigma_floor), int(settings.iterations),
                                   float(settings.width_tolerance), float(settings.width_slack),
                                   float(settings.min_rows)))
