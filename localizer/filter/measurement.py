r"""Measurement model of the pose filter: what a camera on the vehicle sees of a wall target.

Plain data only: a target is its face centre ``t = (tx, ty)`` (m, map frame)
and its facing yaw ``ψ_t`` (rad, the direction its printed face looks, CCW
from +x); the camera mount is its lens centre ``m = (mx, my)`` (m, vehicle
frame: x forward, y left) and its yaw ``ψ_m`` (rad, optical axis relative to
the vehicle heading, CCW; ``-π/2`` looks to the right).

Geometry (top view, map frame x east, y north, θ CCW)::

    vehicle pose x = (px, py, θ)
    lens centre  c = p + R(θ) m                      R(θ) = [[cos θ, -sin θ], [sin θ, cos θ]]
    optical axis φ = θ + ψ_m                         (camera z axis, map yaw)
    r = t - c,  d = |r|,  λ = atan2(r_y, r_x)       (map bearing of the target centre)

The camera frame's x axis (right) is the map direction ``φ - π/2``, so a
target right of the optical axis has ``λ < φ`` and (thesis eq 4.4,
:mod:`localizer.model.geometry`)::

    β = wrap(φ - λ)

α is the angle between the target normal pointing *away* from the camera and
the optical axis, positive when the target's right edge is nearer; in the
camera's (x, z) plane that normal is ``(sin α, cos α)``. The away-pointing
normal has map yaw ``ψ_t + π`` and a map direction of yaw ``a`` has camera
components ``(sin(φ - a), cos(φ - a))``, so::

    α = wrap(φ - ψ_t - π) = wrap(θ + ψ_m - ψ_t - π)

(check: a target squarely facing the camera has ``ψ_t + π = λ`` and α = β).

Jacobian ``H = ∂(d, β, α)/∂(px, py, θ)`` (3 x 3). With
``∂c/∂(px, py) = I`` and ``∂c/∂θ = R'(θ) m = (-sin θ mx - cos θ my, cos θ mx - sin θ my) =: c_θ``::

    ∂d/∂(px, py) = -r / d                 ∂d/∂θ = -(r · c_θ) / d
    ∂λ/∂c = (r_y, -r_x) / d²              (since ∂λ/∂r = (-r_y, r_x) / d² and r = t - c)
    ∂β/∂(px, py) = -∂λ/∂c = (-r_y, r_x) / d²
    ∂β/∂θ = 1 - (r_y c_θx - r_x c_θy) / d²
    ∂α/∂(px, py) = 0                      ∂α/∂θ = 1

Inverse (one observation of a known target gives the whole pose; used to
re-localize)::

    θ = ψ_t + π + α - ψ_m,   φ = θ + ψ_m,   λ = φ - β
    c = t - d (cos λ, sin λ),   p = c - R(θ) m

with ``J = ∂(px, py, θ)/∂(d, β, α)``::

    ∂p/∂d = -(cos λ, sin λ)
    ∂p/∂β = -d (sin λ, -cos λ)
    ∂p/∂α = d (sin λ, -cos λ) - R'(θ) m
    ∂θ/∂(d, β, α) = (0, 0, 1)
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from localizer.model.mount import CameraMount
from localizer.numeric import check_number, wrap_angle

__all__ = [
    "MAX_MEASUREMENT_SIGMA", "Measurement", "check_covariance", "informative", "is_positive_definite",
    "symmetric_minors", "TargetMap", "ViewLimits", "measurement_jacobian",
    "pose_from_measurement", "pose_from_measurement_jacobian", "predict_measurement",
    "predict_all",
]


#: largest standard deviations (d m, β rad, α rad) of an observation the filter fuses: beyond
#: them an observation says next to nothing (its χ² gate accepts almost any target) and the
#: filter refuses it (counted, :meth:`~localizer.filter.ekf.PoseEKF.diagnostics`). Over the
#: localizer's envelope (16 mm lens 1-10 m, 50 mm 4-20 m, |α| <= 70°, bars >= 5 px wide and
#: 16 rows tall, dim to saturated) the detector reports σ_d up to 0.3 m and σ_β up to 0.2 mrad;
#: σ_α reaches 1.4 rad (``exact``, small saturated targets) and 4.4 rad (``thesis``: its two
#: roots of α apart), while d and β still place the vehicle within decimetres: such an
#: observation is fused for them, its α all but ignored. So σ_d is bounded at three times the
#: envelope's largest, σ_β far above it, and σ_α at a whole turn, only to keep the arithmetic
#: sane (beyond π an α says nothing). Re-localization asks more of an observation
#: (``RelocalizeConfig.evidence_sigma``).
MAX_MEASUREMENT_SIGMA = (1.0, 0.5, 2.0 * math.pi)  # m, rad, rad


def symmetric_minors(P) -> tuple[float, tuple[float, float, float], tuple[float, float, float], float] | None:
    """``(scale, diagonal, 2 x 2 principal minors, determinant)`` of a (3, 3) matrix ``P`` on floats,
    or None unless it is finite and symmetric (to 1e-9 of ``scale``, its largest entry): what the
    definiteness tests below read (cheap enough for every observation and hypothesis of a frame).
    The minors: ``(a d - b², a f - c², d f - e²)`` for ``P = [[a, b, c], [b, d, e], [c, e, f]]``."""
    a, b, c, b2, d, e, c2, e2, f = np.asarray(P, dtype=float).reshape(-1).tolist()
    vals = (a, b, c, d, e, f, b2, c2, e2)
    if not all(math.isfinite(v) for v in vals):
        return None
    scale = max(abs(v) for v in vals)
    if max(abs(b - b2), abs(c - c2), abs(e - e2)) > 1e-9 * scale:
        return None
    det = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c)
    return scale, (a, d, f), (a * d - b * b, a * f - c * c, d * f - e * e), det


def is_positive_definite(P) -> bool:
    """Whether the (3, 3) matrix ``P`` is finite, symmetric and positive definite (Sylvester's
    criterion on its leading minors)."""
    m = symmetric_minors(P)
    return m is not None and m[1][0] > 0.0 and m[2][0] > 0.0 and m[3] > 0.0


def check_covariance(where: str, R) -> np.ndarray:
    """``R`` (3, 3) as an array if it is finite, symmetric and positive semi-definite (every
    principal minor >= 0, each to 1e-12 of its own scale); else one ``ValueError`` naming
    ``where``, the value and the expectation."""
    R = np.asarray(R, dtype=float)
    m = symmetric_minors(R) if R.shape == (3, 3) else None
    if m is not None:
        scale, diagonal, minors, det = m
        tol = 1e-12 * scale
        ok = min(diagonal) >= -tol and min(minors) >= -tol * scale and det >= -tol * scale * scale
    if m is None or not ok:
        raise ValueError(f"{where} must be a finite symmetric positive semi-definite (3, 3) covariance "
                         f"(m², rad²), got {R.tolist()!r}")
    return R


def informative(R) -> bool:
    """Whether a fused observation covariance ``R`` (3, 3) (floor included) is positive definite
    with every standard deviation within :data:`MAX_MEASUREMENT_SIGMA`."""
    return (R.item(0, 0) <= MAX_MEASUREMENT_SIGMA[0] ** 2 and R.item(1, 1) <= MAX_MEASUREMENT_SIGMA[1] ** 2
            and R.item(2, 2) <= MAX_MEASUREMENT_SIGMA[2] ** 2 and is_positive_definite(R))


@dataclass(frozen=True)
class ViewLimits:
    """Where the camera can recognise a target (used to predict which targets are in view).

    Attributes:
        half_fov: half the horizontal angle of view (rad); 16 mm thesis lens: 15.4°.
        min_range, max_range: horizontal distance limits (m).
        max_incidence: largest |γ| = |α - β| (rad), the angle between the line of
            sight and the target normal, at which a target is still recognised (default: the
            localizer's envelope, |α| <= 70° anywhere across a 16 mm lens's view, 85.4°).
        margin: extra bearing (rad) added to ``half_fov`` when predicting candidates,
            so a target near the image border is still considered.
    """

    half_fov: float = math.radians(15.4)  # rad
    min_range: float = 0.5  # m
    max_range: float = 12.0  # m
    max_incidence: float = math.radians(70.0 + 15.4)  # rad
    margin: float = math.radians(2.0)  # rad

    def __post_init__(self) -> None:
        check_number("ViewLimits.half_fov", self.half_fov, low=0.0, high=math.pi, low_open=True, high_open=True,
                     unit="rad")
        check_number("ViewLimits.min_range", self.min_range, low=0.0, unit="m")
        check_number("ViewLimits.max_range", self.max_range, low=self.min_range, low_open=True,
                     unit="m")
        check_number("ViewLimits.max_incidence", self.max_incidence, low=0.0, high=math.pi / 2, low_open=True,
                     unit="rad")
        check_number("ViewLimits.margin", self.margin, low=0.0, unit="rad")


@dataclass(frozen=True, eq=False)
class TargetMap:
    """The map's targets as plain data.

    Attributes:
        ids: target ids, length N.
        positions: ``(N, 2)`` face centres (m, map frame), read-only.
        yaws: ``(N,)`` facing directions (rad, CCW from +x), read-only.
        polarities: ``"positive"``/``"negative"`` per target, or ``None`` entries when unknown.
    """

    ids: tuple[str, ...]
    positions: np.ndarray
    yaws: np.ndarray
    polarities: tuple[str | None, ...] = field(default=())

    def __post_init__(self) -> None:
        ids = tuple(str(i) for i in self.ids)
        pos = np.array(self.positions, dtype=float).reshape(-1, 2) if len(ids) else np.zeros((0, 2))
        yaws = np.array(self.yaws, dtype=float).reshape(-1)
        pols = tuple(self.polarities) if self.polarities else (None,) * len(ids)
        if pos.shape != (len(ids), 2) or yaws.shape != (len(ids),) or len(pols) != len(ids):
            raise ValueError(f"TargetMap: {len(ids)} ids need positions (N, 2), yaws (N,) and N polarities; "
                             f"got {pos.shape}, {yaws.shape}, {len(pols)}")
        if not (np.isfinite(pos).all() and np.isfinite(yaws).all()):
            raise ValueError("TargetMap: positions and yaws must be finite")
        if len(set(ids)) != len(ids):
            raise ValueError("TargetMap: target ids must be unique")
        for p in pols:
            if p not in (None, "positive", "negative"):
                raise ValueError(f"TargetMap: polarity must be 'positive', 'negative' or None, got {p!r}")
        pos.setflags(write=False)
        yaws.setflags(write=False)
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "yaws", yaws)
        object.__setattr__(self, "polarities", pols)

    def __len__(self) -> int:
        return len(self.ids)

    def index(self, target_id: str) -> int:
        """Index of ``target_id`` (KeyError if unknown)."""
        try:
            return self.ids.index(target_id)
        except ValueError:
            raise KeyError(f"no target {target_id!r}") from None

    def subset(self, keep: Sequence[int]) -> "TargetMap":
        """The targets at indices ``keep``."""
        keep = list(keep)
        return TargetMap(tuple(self.ids[i] for i in keep), self.positions[keep], self.yaws[keep],
                         tuple(self.polarities[i] for i in keep))


@dataclass(frozen=True, eq=False)
class Measurement:
    """One target observation as the filter uses it.

    Attributes:
        z: ``(3,)`` (d m, β rad, α rad), thesis conventions.
        R: ``(3, 3)`` covariance of z (m², rad²).
        polarity: ``"positive"``/``"negative"`` or None when unknown.
    """

    z: np.ndarray
    R: np.ndarray
    polarity: str | None = None

    def __post_init__(self) -> None:
        z = np.array(self.z, dtype=float).reshape(-1)
        R = np.array(self.R, dtype=float)
        if z.shape != (3,) or R.shape != (3, 3):
            raise ValueError(f"Measurement needs z (3,) and R (3, 3), got {z.shape}, {R.shape}")
        if not np.isfinite(z).all() or z[0] <= 0:
            raise ValueError(f"Measurement.z must be finite (d m, β rad, α rad) with d > 0, got z={z}")
        check_covariance("Measurement.R", R)
        object.__setattr__(self, "z", z)
        object.__setattr__(self, "R", 0.5 * (R + R.T))

    def plus_noise(self, extra: np.ndarray) -> "Measurement":
        """``Measurement(z, R + extra, polarity)`` for a finite ``extra`` (3, 3) covariance, without
        re-checking what this measurement already passed (z, shapes): the per-observation hot path."""
        R = self.R + extra
        if R.shape != (3, 3):
            raise ValueError(f"Measurement.plus_noise: R + extra must be a (3, 3) matrix, got shape {R.shape}")
        check_covariance("Measurement.plus_noise: R + extra", R)
        m = object.__new__(Measurement)
        object.__setattr__(m, "z", self.z.copy())
        object.__setattr__(m, "R", 0.5 * (R + R.T))
        object.__setattr__(m, "polarity", self.polarity)
        return m

    @classmethod
    def from_observation(cls, obs, floor: np.ndarray | None = None) -> "Measurement":
        """From a :class:`localizer.TargetObservation` (or anything with ``distance``,
        ``beta``, ``alpha``, ``covariance``, ``polarity``); ``floor`` (3,) standard
        deviations (m, rad, rad) added in quadrature."""
        R = np.array(obs.covariance, dtype=float)
        if floor is not None:
            R = R + np.diag(np.asarray(floor, dtype=float) ** 2)
        return cls(np.array([obs.distance, obs.beta, obs.alpha]), R, getattr(obs, "polarity", None))


def _lens(x: np.ndarray, mount: CameraMount) -> tuple[float, float, float, float]:
    """Lens centre (cx, cy) and c_θ = R'(θ) m components."""
    th = float(x[2])
    c, s = math.cos(th), math.sin(th)
    cx = float(x[0]) + c * mount.forward - s * mount.lateral
    cy = float(x[1]) + s * mount.forward + c * mount.lateral
    return cx, cy, -s * mount.forward - c * mount.lateral, c * mount.forward - s * mount.lateral


def predict_measurement(x, target_position, target_yaw: float, mount: CameraMount) -> np.ndarray:
    """h(x): the ``(3,)`` (d m, β rad, α rad) a camera at vehicle pose ``x`` (3,) sees of a target."""
    x = np.asarray(x, dtype=float).reshape(-1)
    cx, cy, _, _ = _lens(x, mount)
    rx, ry = float(target_position[0]) - cx, float(target_position[1]) - cy
    phi = float(x[2]) + mount.yaw
    d = math.hypot(rx, ry)
    beta = wrap_angle(phi - math.atan2(ry, rx))
    alpha = wrap_angle(phi - float(target_yaw) - math.pi)
    return np.array([d, beta, alpha])


def measurement_jacobian(x, target_position, target_yaw: float, mount: CameraMount) -> np.ndarray:
    """H = ∂h/∂x, ``(3, 3)`` (see the module docstring for the derivation)."""
    x = np.asarray(x, dtype=float).reshape(-1)
    cx, cy, ctx, cty = _lens(x, mount)
    rx, ry = float(target_position[0]) - cx, float(target_position[1]) - cy
    d2 = rx * rx + ry * ry
    if d2 <= 1e-18:
        raise ValueError("measurement_jacobian: the lens centre coincides with the target")
    d = math.sqrt(d2)
    return np.array([
        [-rx / d, -ry / d, -(rx * ctx + ry * cty) / d],
        [-ry / d2, rx / d2, 1.0 - (ry * ctx - rx * cty) / d2],
        [0.0, 0.0, 1.0],
    ])


def predict_all(x, targets: TargetMap, mount: CameraMount, limits: ViewLimits | None = None):
    """Predicted measurements of every target and which are in view.

    Returns:
        ``(Z, visible)``: ``Z`` (N, 3) predicted (d, β, α); ``visible`` (N,) bool:
        within range, within ``half_fov + margin`` of the axis, facing the camera
        with ``|α - β| <= max_incidence``. No occlusion test (the filter has no walls).
    """
    x = np.asarray(x, dtype=float).reshape(-1)
    n = len(targets)
    if n == 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=bool)
    cx, cy, _, _ = _lens(x, mount)
    r = targets.positions - np.array([cx, cy])
    d = np.hypot(r[:, 0], r[:, 1])
    phi = float(x[2]) + mount.yaw
    beta = wrap_angle(phi - np.arctan2(r[:, 1], r[:, 0]))
    alpha = wrap_angle(phi - targets.yaws - math.pi)
    Z = np.empty((n, 3))  # np.stack([d, beta, alpha], axis=1), without its overhead
    Z[:, 0] = d
    Z[:, 1] = beta
    Z[:, 2] = alpha
    if limits is None:
        return Z, np.ones(n, dtype=bool)
    gamma = wrap_angle(alpha - beta)
    visible = ((d >= limits.min_range) & (d <= limits.max_range)
               & (np.abs(beta) <= limits.half_fov + limits.margin)
               & (np.abs(gamma) <= limits.max_incidence))
    return Z, visible


def pose_from_measurement(z, target_position, target_yaw: float, mount: CameraMount) -> np.ndarray:
    """The vehicle pose ``(3,)`` at which the camera would measure ``z`` = (d, β, α) of the target."""
    d, beta, alpha = (float(v) for v in np.asarray(z, dtype=float).reshape(-1))
    theta = wrap_angle(float(target_yaw) + math.pi + alpha - mount.yaw)
    lam = theta + mount.yaw - beta
    cx = float(target_position[0]) - d * math.cos(lam)
    cy = float(target_position[1]) - d * math.sin(lam)
    c, s = math.cos(theta), math.sin(theta)
    return np.array([cx - (c * mount.forward - s * mount.lateral), cy - (s * mount.forward + c * mount.lateral), theta])


def pose_from_measurement_jacobian(z, target_position, target_yaw: float,
                                   mount: CameraMount) -> np.ndarray:
    """J = ∂(px, py, θ)/∂(d, β, α), ``(3, 3)`` (module docstring)."""
    d, beta, alpha = (float(v) for v in np.asarray(z, dtype=float).reshape(-1))
    theta = float(target_yaw) + math.pi + alpha - mount.yaw
    lam = theta + mount.yaw - beta
    cl, sl = math.cos(lam), math.sin(lam)
    c, s = math.cos(theta), math.sin(theta)
    ctx, cty = -s * mount.forward - c * mount.lateral, c * mount.forward - s * mount.lateral
    return np.array([
        [-cl, -d * sl, d * sl - ctx],
        [-sl, d * cl, -d * cl - cty],
        [0.0, 0.0, 1.0],
    ])
