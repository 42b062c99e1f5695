"""The ``geometric`` source: true target geometry plus noise, no image.

The true (d, β, α) of each visible target (:func:`~agvsim.sensors.vision.visible_targets`)
plus Gaussian noise from a covariance model fitted to the localizer's reported
covariance (16 mm lens), optional missed and false detections. Fast; for tests,
sweeps and learning.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from agvsim.sensors.base import SimObservation
from agvsim.sensors.vision import VisionConfig, targets_from_map, visible_targets
from localizer.numeric import check_number, check_numbers

__all__ = ["GeometricNoise", "GeometricSource"]


@dataclass(frozen=True)
class GeometricNoise:
    """Covariance model of (d, β, α) fitted to the localizer's reported covariance
    (``exact``, 16 mm lens, blur 0.7 px, noise 2 grey levels, 2-8 m, |γ| <= 60°)::

        σ_d = d_coef d²,  σ_β = beta_sigma,  σ_α = alpha_coef d²

    Attributes:
        d_coef: (1/m).
        beta_sigma: (rad).
        alpha_coef: (rad/m²).
        floor: (σ_d m, σ_β rad, σ_α rad) lower bounds.
        error_scale: drawn error σ over reported σ (1 = the report is exact; the
            localizer's real errors were 0.3-0.6 of its report on synthetic frames).
        detection_probability: chance a visible target is reported.
        false_rate: mean number of false detections per frame (Poisson).
    """

    d_coef: float = 2.6e-4  # 1/m
    beta_sigma: float = 2e-5  # rad
    alpha_coef: float = 3.0e-4  # rad/m²
    floor: tuple[float, float, float] = (0.0005, 1e-5, 0.0005)  # m, rad, rad
    error_scale: float = 1.0
    detection_probability: float = 1.0
    false_rate: float = 0.0  # per frame

    def __post_init__(self) -> None:
        for name in ("d_coef", "beta_sigma", "alpha_coef", "error_scale", "false_rate"):
            check_number(f"GeometricNoise.{name}", getattr(self, name), low=0.0)
        check_numbers("GeometricNoise.floor", self.floor, 3, low=0.0)
        check_number("GeometricNoise.detection_probability", self.detection_probability, low=0.0, high=1.0)

    def covariance(self, d: float) -> np.ndarray:
        """(3, 3) diagonal covariance at distance ``d`` (m)."""
        s = np.maximum([self.d_coef * d * d, self.beta_sigma, self.alpha_coef * d * d], self.floor)
        return np.diag(s ** 2)


class GeometricSource:
    """True (d, β, α) of the visible targets plus noise (module docstring).

    Args:
        world_map: the map (targets, walls for occlusion).
        vision: the camera.
        noise: the covariance / error model.
    """

    name: ClassVar[str] = "geometric"
    draws_frames: ClassVar[bool] = False
    has_exposure: ClassVar[bool] = False

    def __init__(self, world_map, vision: VisionConfig | None = None,
                 noise: GeometricNoise = GeometricNoise()) -> None:
        self.map = world_map
        self.vision = (vision or VisionConfig()).for_map(world_map)
        self._targets = targets_from_map(world_map)
        self.noise = noise
        self.last_frame: np.ndarray | None = None

    def set_exposure(self, factor: float) -> None:
        """No frames, no exposure: a no-op (:attr:`has_exposure` is False)."""

    def observe(self, true_pose, rng: np.random.Generator,
                command: tuple[float, float] = (0.0, 0.0)) -> list[SimObservation]:
        out = []
        nz = self.noise
        for i, pose in visible_targets(self.map, self.vision, true_pose, self._targets):
            if nz.detection_probability < 1.0 and rng.random() >= nz.detection_probability:
                continue
            C = nz.covariance(pose.distance)
            e = rng.standard_normal(3) * np.sqrt(np.diag(C)) * nz.error_scale
            t = self.map.targets[i]
            out.append(SimObservation(pose.distance + e[0], pose.beta + e[1], pose.alpha + e[2], C,
                                      t.polarity, t.id))
        n_false = int(rng.poisson(nz.false_rate)) if nz.false_rate > 0 else 0
        half = self.vision.view_limits().half_fov if n_false else 0.0
        for _ in range(n_false):
            d = float(rng.uniform(1.0, self.vision.max_range))
            beta = float(rng.uniform(-half, half))
            alpha = beta + float(rng.uniform(-1.0, 1.0))
            out.append(SimObservation(d, beta, alpha, nz.covariance(d),
                                      "positive" if rng.random() < 0.5 else "negative", None))
        return out
