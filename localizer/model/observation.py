"""Result types of :func:`localizer.detect_targets`."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ImageMeasurements:
    """What was measured in the image (pixels, undistorted; §4.7, Fig. 3.6).

    ``edges_x`` (4,): x of the four vertical bar edges, left to right.
    ``outer_edges``: (x_left, x_right) = ``edges_x[0], edges_x[3]``.
    ``h1``, ``h2``: heights of the left/right bar at their centre columns ``bar_cx`` (2,).
    ``delta_x``: target image width Δx = x_right - x_left; ``delta_y``: Δy = (h1 + h2) / 2.
    ``centre``: (x, y) of the target centre line (mean of the bar centre lines, mid-height).
    ``top_y``, ``bottom_y`` (2,): bar tops and bottoms at ``bar_cx``.
    ``rows``: (first, last) image rows of the recognised stack; ``n_rows`` its line count.
    ``dark``, ``bright``: mean grey levels of the dark and light segments.
    """

    edges_x: tuple[float, float, float, float]
    outer_edges: tuple[float, float]
    h1: float
    h2: float
    delta_x: float
    delta_y: float
    centre: tuple[float, float]
    bar_cx: tuple[float, float]
    top_y: tuple[float, float]
    bottom_y: tuple[float, float]
    rows: tuple[int, int]
    n_rows: int
    dark: float
    bright: float


@dataclass(frozen=True)
class TargetObservation:
    """One recognised target and the camera's pose relative to it.

    Attributes:
        distance: d (m), horizontal distance lens centre -> target centre (eq 4.5).
        beta: β (rad), bearing of the target centre, > 0 right of the optical axis.
        alpha: α (rad), target plane vs image plane; > 0 when the target's right edge
            is nearer; α = β when the target squarely faces the camera
            (see :mod:`localizer.model.geometry`).
        z: range of the target centre along the optical axis (m).
        x: lateral camera-frame position of the target centre (m, right positive).
        height: camera-frame y of the target centre (m, down positive; NaN for "thesis").
        polarity: "positive" (black bars on white) or "negative".
        method: "thesis" or "exact".
        covariance: (3, 3) covariance of (d, β, α), m and rad.
        measurements: the image measurements.
        alpha_candidates: the two roots (rad) of eq 4.13 (thesis) or A.13 (exact start).
        alpha_ambiguous: both roots were legitimate under §4.2.2 (thesis only).
        edge_bias: common shift (px) of the edges towards their dark side (exact only).
        fit_rms: normalised residual of the exact fit (NaN for "thesis").
    """

    distance: float
    beta: float
    alpha: float
    z: float
    x: float
    height: float
    polarity: str
    method: str
    covariance: np.ndarray
    measurements: ImageMeasurements
    alpha_candidates: tuple[float, float]
    alpha_ambiguous: bool
    edge_bias: float
    fit_rms: float

    @property
    def sigma(self) -> np.ndarray:
        """(3,) standard deviations of (d, β, α) (m, rad)."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def gamma(self) -> float:
        """γ = α - β (rad), angle between the target normal and the line of sight (eq 4.6)."""
        return self.alpha - self.beta

    def to_dict(self) -> dict:
        """JSON-friendly dict (SI units plus degrees for display)."""
        m = self.measurements
        return {
            "distance_m": self.distance, "beta_rad": self.beta, "alpha_rad": self.alpha,
            "beta_deg": math.degrees(self.beta), "alpha_deg": math.degrees(self.alpha),
            "z_m": self.z, "x_m": self.x, "height_m": self.height,
            "polarity": self.polarity, "method": self.method,
            "covariance": np.asarray(self.covariance).tolist(),
            "sigma": {"distance_m": float(self.sigma[0]), "beta_rad": float(self.sigma[1]),
                      "alpha_rad": float(self.sigma[2])},
            "alpha_candidates_rad": list(self.alpha_candidates),
            "alpha_ambiguous": self.alpha_ambiguous,
            "edge_bias_px": self.edge_bias, "fit_rms": self.fit_rms,
            "measurements": {
                "edges_x": list(m.edges_x), "outer_edges": list(m.outer_edges), "h1": m.h1, "h2": m.h2,
                "delta_x": m.delta_x, "delta_y": m.delta_y, "centre": list(m.centre),
                "bar_cx": list(m.bar_cx), "top_y": list(m.top_y), "bottom_y": list(m.bottom_y),
                "rows": list(m.rows), "n_rows": m.n_rows, "dark": m.dark, "bright": m.bright,
            },
        }


def observation_of(edges: tuple, cxs: tuple, top: tuple, bottom: tuple, rows: tuple[int, int], dark: float,
                   bright: float, polarity: str, method: str, pose: tuple) -> TargetObservation:
    """The observation of a target whose edges (px: 4 columns, 2 bar centre columns, 2 tops and 2
    bottoms) make the pose ``pose``: ``(distance, beta, alpha, z, x, height, covariance,
    alpha_candidates, alpha_ambiguous, edge_bias, fit_rms)`` as :class:`TargetObservation` holds
    them (Python floats, a ``(3, 3)`` array, a pair of floats, a bool: :func:`pose_fields`);
    ``rows`` the (first, last) row of its stack, ``dark`` and ``bright`` its grey levels."""
    ex = edges
    h1, h2 = bottom[0] - top[0], bottom[1] - top[1]
    meas = ImageMeasurements(ex, (ex[0], ex[3]), h1, h2, ex[3] - ex[0], 0.5 * (h1 + h2),
                             (0.25 * sum(ex), 0.25 * (sum(top) + sum(bottom))), cxs, top, bottom, rows,
                             rows[1] - rows[0] + 1, float(dark), float(bright))
    distance, beta, alpha, z, x, height, cov, candidates, ambiguous, bias, rms = pose
    return TargetObservation(distance, beta, alpha, z, x, height, polarity, method, cov, meas, candidates, ambiguous,
                             bias, rms)


def pose_fields(est) -> tuple:
    """The pose of :func:`observation_of` from a :class:`localizer.measure.pose.PoseEstimate`."""
    return (float(est.distance), float(est.beta), float(est.alpha), float(est.z), float(est.x), float(est.height),
            np.asarray(est.covariance, float), tuple(float(a) for a in est.alpha_candidates), bool(est.ambiguous),
            float(est.edge_bias), float(est.rms))
