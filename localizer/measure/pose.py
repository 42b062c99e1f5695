"""Pose recovery from edge measurements (thesis §4.1-4.2, Appendix A): the result record.

Two methods: :func:`localizer.thesis.pose.thesis_pose` (the thesis's eqs 4.3-4.13 on the
half-pixel edges) and :func:`localizer.measure.exact_pose.exact_pose` (perspective-exact least
squares over every measured edge). Both return a :class:`PoseEstimate`.

Units: pixels in, metres and radians out. Conventions: :mod:`localizer.model.geometry`.
Image quantities are converted with the camera's focal lengths instead of the
thesis's millimetre factors (§4.7): ``x_m / f = (x - cx) / fx``,
``h_m / f = h / fy``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PoseEstimate:
    distance: float  # m
    beta: float  # rad
    alpha: float  # rad
    z: float  # m, along the optical axis
    x: float  # m, camera-frame lateral position of the target centre
    height: float  # m, camera-frame y of the target centre (nan if not estimated)
    covariance: np.ndarray  # (3, 3) over (d, beta, alpha), m and rad
    alpha_candidates: tuple[float, float]  # rad, the two roots of eq 4.13 / A.13
    ambiguous: bool  # both roots were legitimate (§4.2.2)
    edge_bias: float = 0.0  # px, common shift of every edge towards its dark side
    rms: float = float("nan")  # normalised fit residual (exact only)
    blur: float = float("nan")  # px, the row-mean blur sd the edges were measured at (exact_measure only)
