r"""A wide belief: the pose as a mixture of Gaussians where one Gaussian no longer fits.

Odometry alone spreads the estimate (a long turn with no target in view): once the heading σ
passes what the EKF's linearization carries (``FilterConfig.lost_heading_sigma``), one Gaussian
over (x, y, θ) would lie about where the vehicle can be (the true spread is a banana, not an
ellipse), and declaring the filter lost would throw away what it still knows. Instead
:class:`WideBelief` keeps the same belief as a weighted set of narrow Gaussians, each a
:class:`~localizer.filter.update.PoseKF` predicted and updated through the filter's one path
(:mod:`localizer.filter.update`):

* **split** (:func:`split`): a Gaussian ``N(x, P)`` whose heading σ ``s`` exceeds
  ``split_heading_sigma`` becomes ``K`` components spaced ``spacing`` apart in heading over
  ``±3√(s² - σ_c²)``, each with heading σ ``σ_c`` (``component_heading_sigma``), the position
  conditioned on the heading (means ``x + b μ_k / s²``, covariances ``P - (1 - σ_c²/s²) b bᵀ / s²``,
  ``b = P[:, 2]``), weights ``∝ exp(-μ_k² / 2(s² - σ_c²))``: the mixture's mean and covariance
  are the Gaussian's (to the discretization);
* **predict**: every component by the same odometry (those whose mean leaves the free space are
  dropped, unless none would be left); one that grows past
  ``split_heading_sigma`` again is split again, the widest first, as long as the mixture stays
  within ``max_components`` (a component left unsplit is still its Gaussian, only less finely
  resolved);
* **update** (:meth:`WideBelief.update`): every component associates the frame's observations
  (the main filter's χ² gate) and is updated with those it accepts; its weight is multiplied by
  the likelihood of what it saw: ``N(ν; 0, S)`` for an accepted observation, and for a refused
  one the density a clutter detection has, that of ``D² = gate`` under the observation's own
  ``R`` (a component that cannot explain what is seen loses against one that can);
  components outside the free space, or whose weight falls below ``prune_weight``, are dropped;
* **moments** (:meth:`WideBelief.moments`): the mixture's mean and covariance, what the filter
  reports (headings averaged relative to the heaviest component). When they are narrow again
  (heading σ within ``narrow_heading_sigma``, position σ within ``narrow_position_sigma``) the
  filter collapses the mixture to that one Gaussian and tracks as before.

The belief is given up (the filter declares itself lost) when its position σ passes
``max_position_sigma``, or when ``miss_frames`` frames in a row with an informative observation
had none that any component explained or found ambiguous (within its gate beside another target:
a component too wide to tell two targets apart is not contradicted by them).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from localizer.filter.association import ACCEPTED, AMBIGUOUS, DUPLICATE, GateConfig, associate
from localizer.filter.measurement import Measurement, TargetMap
from localizer.filter.update import PoseKF, position_sigma, predict_pose, update_pose
from localizer.model.mount import CameraMount
from localizer.numeric import check_number, wrap_angle

__all__ = ["UNKNOWN_HEADING_VARIANCE", "WideBelief", "WideConfig", "split"]

_LOG_2PI = math.log(2.0 * math.pi)
#: rad²: the variance of a heading uniform on the circle, π²/3, the most the moments report
UNKNOWN_HEADING_VARIANCE = math.pi ** 2 / 3.0


@dataclass(frozen=True)
class WideConfig:
    """Settings of the wide belief (module docstring).

    Attributes:
        component_heading_sigma: heading σ (rad) of each component a split makes.
        spacing: heading step (rad) between the means of a split's components.
        split_heading_sigma: a component whose heading σ (rad) passes this is split again.
        max_components: at most this many components.
        max_position_sigma: the belief is given up when the position σ (m) of its moments passes this.
        narrow_heading_sigma: the mixture collapses to one Gaussian when the heading σ (rad) of its
            moments is within this ...
        narrow_position_sigma: ... and their position σ (m) within this.
        prune_weight: components whose weight (of a total 1) falls below this are dropped.
        miss_frames: frames in a row with an informative observation and none explained by any
            component before the belief is given up.
    """

    component_heading_sigma: float = math.radians(4.0)  # rad
    spacing: float = math.radians(6.0)  # rad
    split_heading_sigma: float = math.radians(8.0)  # rad
    max_components: int = 48
    max_position_sigma: float = 10.0  # m
    narrow_heading_sigma: float = math.radians(10.0)  # rad
    narrow_position_sigma: float = 0.5  # m
    prune_weight: float = 1e-4  # dimensionless
    miss_frames: int = 8

    def __post_init__(self) -> None:
        for name in ("component_heading_sigma", "spacing", "split_heading_sigma", "narrow_heading_sigma"):
            check_number(f"WideConfig.{name}", getattr(self, name), low=0.0, low_open=True, unit="rad")
        for name in ("max_position_sigma", "narrow_position_sigma"):
            check_number(f"WideConfig.{name}", getattr(self, name), low=0.0, low_open=True, unit="m")
        check_number("WideConfig.max_components", self.max_components, low=2, integer=True)
        check_number("WideConfig.miss_frames", self.miss_frames, low=1, integer=True)
        check_number("WideConfig.prune_weight", self.prune_weight, low=0.0, high=1.0, high_open=True)
        if self.split_heading_sigma <= self.component_heading_sigma:
            raise ValueError(f"WideConfig.split_heading_sigma must exceed component_heading_sigma "
                             f"({self.component_heading_sigma!r} rad), got {self.split_heading_sigma!r}")


def split(x: np.ndarray, P: np.ndarray, config: WideConfig,
          most: int | None = None) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """The components of ``N(x, P)`` split along the heading (module docstring): ``(means, covariances,
    weights)``, lists of (3,) and (3, 3) arrays and a (K,) array summing to 1. One component (the
    Gaussian itself) when its heading σ is within ``component_heading_sigma``; at most ``most``
    (default ``max_components``) components, spaced wider where the spacing would make more."""
    x = np.asarray(x, dtype=float).reshape(3)
    P = np.asarray(P, dtype=float)
    s2 = P.item(2, 2)
    c2 = config.component_heading_sigma ** 2
    if s2 <= c2:
        return [x.copy()], [P.copy()], np.ones(1)
    spread = math.sqrt(s2 - c2)
    half = min(3.0 * spread, math.pi)
    most = config.max_components if most is None else most
    if most < 3:
        return [x.copy()], [P.copy()], np.ones(1)
    n = min(max(1, int(math.ceil(half / config.spacing))), (most - 1) // 2)
    mu = np.linspace(-half, half, 2 * n + 1)
    if half >= math.pi:  # the whole circle: -π and π are one heading
        mu = mu[:-1]
    w = np.exp(-0.5 * (mu / spread) ** 2)
    w /= w.sum()
    b = P[:, 2].copy()
    Pk = P - (1.0 - c2 / s2) * np.outer(b, b) / s2
    Pk = 0.5 * (Pk + Pk.T)
    return [x + b * (m / s2) for m in mu], [Pk.copy() for _ in mu], w


class WideBelief:
    """The pose as a Gaussian mixture (module docstring).

    Args:
        x: (3,) mean of the Gaussian it starts from (m, m, rad).
        P: (3, 3) its covariance.
        targets, mount: the map's targets and the camera mount.
        gate: association settings (the main filter's).
        config: settings.
        free_space: optional ``(x m, y m) -> bool``; components outside it are dropped.
    """

    def __init__(self, x, P, targets: TargetMap, mount: CameraMount, gate: GateConfig,
                 config: WideConfig = WideConfig(), free_space=None) -> None:
        self.targets = targets
        self.mount = mount
        self.gate = gate
        self.config = config
        self.free_space = free_space
        means, covs, w = split(x, P, config)
        self.components: list[PoseKF] = [PoseKF(m, c) for m, c in zip(means, covs)]
        self.weights = np.asarray(w, dtype=float)
        self.missed = 0  # frames in a row with informative observations no component explained

    def __len__(self) -> int:
        return len(self.components)

    # ------------------------------------------------------------ predict
    def predict(self, u: np.ndarray, Q: np.ndarray) -> None:
        """Move every component by the relative motion ``u`` (3,) with covariance ``Q`` (3, 3); split
        the ones grown past ``split_heading_sigma``, widest first, within ``max_components``."""
        for kf in self.components:
            predict_pose(kf, u, Q)
        if self.free_space is not None:
            alive = [k for k, kf in enumerate(self.components) if self._free(kf.x)]
            if alive and len(alive) < len(self.components):  # none left: the update's test says lost
                self.components = [self.components[k] for k in alive]
                self.weights = self.weights[alive] / self.weights[alive].sum()
        limit = self.config.split_heading_sigma ** 2
        wide = sorted((k for k, kf in enumerate(self.components) if kf.P.item(2, 2) > limit),
                      key=lambda k: -self.components[k].P.item(2, 2))
        room = self.config.max_components - len(self.components)
        parts: dict[int, tuple] = {}
        for k in wide:
            if room < 2:
                break
            kf = self.components[k]
            means, covs, ws = split(kf.x, kf.P, self.config, most=room + 1)
            if len(ws) > 1:
                parts[k] = (means, covs, ws)
                room -= len(ws) - 1
        if parts:
            comps, weights = [], []
            for k, (kf, w) in enumerate(zip(self.components, self.weights)):
                if k in parts:
                    means, covs, ws = parts[k]
                    comps.extend(PoseKF(m, c) for m, c in zip(means, covs))
                    weights.extend(w * ws)
                else:
                    comps.append(kf)
                    weights.append(w)
            self.components, self.weights = comps, np.asarray(weights)

    # ------------------------------------------------------------ update
    def update(self, measurements: Sequence[Measurement], informative: Sequence[bool]) -> tuple[int, list, list]:
        """Fuse one frame's measurements into every component and reweigh them (module docstring).

        ``informative``: per measurement, whether it alone places the vehicle precisely enough to
        count (a loose observation fits anything). Returns ``(explained, associations, nis)``:
        how many measurements some component accepted, and the associations and NIS of the
        heaviest component after the frame."""
        if not measurements:
            return 0, [], []
        gate = self.gate.gate
        clutter = [-0.5 * gate - 0.5 * (3 * _LOG_2PI + math.log(max(np.linalg.det(m.R), 1e-300)))
                   for m in measurements]
        loglik = np.zeros(len(self.components))
        fitted: set[int] = set()
        unresolved: set[int] = set()
        records = []
        for k, kf in enumerate(self.components):
            assoc = associate(kf.x, kf.P, measurements, self.targets, self.mount, self.gate)
            nis = []
            for a in assoc:
                if a.status in (AMBIGUOUS, DUPLICATE):  # within the gate of two: no contradiction
                    unresolved.add(a.observation)
                if a.status != ACCEPTED:
                    loglik[k] += clutter[a.observation]
                    continue
                m = measurements[a.observation]
                d2 = update_pose(kf, m, self.targets.positions[a.target], self.targets.yaws[a.target], self.mount)
                nis.append(d2)
                loglik[k] += -0.5 * d2 - 0.5 * (3 * _LOG_2PI + math.log(max(np.linalg.det(kf.S), 1e-300)))
                fitted.add(a.observation)
            records.append((assoc, nis))
        w = self.weights * np.exp(loglik - loglik.max())
        alive = [k for k in range(len(w)) if self._free(self.components[k].x)]
        if alive:
            w = w[alive] / w[alive].sum()
            keep = [n for n in range(len(alive)) if w[n] >= self.config.prune_weight]
            self.components = [self.components[alive[n]] for n in keep]
            records = [records[alive[n]] for n in keep]
            self.weights = w[keep] / w[keep].sum()
        else:
            self.components, records, self.weights = [], [], np.zeros(0)
        if any(informative[k] for k in range(len(measurements))):
            self.missed = 0 if any(informative[k] for k in fitted | unresolved) else self.missed + 1
        if not self.components:
            return len(fitted), [], []
        best = int(np.argmax(self.weights))
        return len(fitted), list(records[best][0]), records[best][1]

    def _free(self, x) -> bool:
        return self.free_space is None or bool(self.free_space(float(x[0, 0]), float(x[1, 0])))

    # ------------------------------------------------------------ read
    def moments(self) -> tuple[np.ndarray, np.ndarray]:
        """The mixture's mean (3,) and covariance (3, 3) (headings relative to the heaviest)."""
        return _moments(self.components, self.weights)

    def lost_reason(self) -> str | None:
        """Why the belief is to be given up (module docstring), or None."""
        if not self.components:
            return "no wide-belief component left in free space"
        if self.missed >= self.config.miss_frames:
            return f"{self.missed} frames in a row whose detections no wide-belief component explains"
        _, P = self.moments()
        sigma = position_sigma(P)
        if sigma > self.config.max_position_sigma:
            return f"wide belief's position sigma {sigma:.2f} m > {self.config.max_position_sigma:g} m"
        return None

    def narrow(self) -> bool:
        """Whether the moments are narrow enough for one Gaussian again."""
        _, P = self.moments()
        return (P.item(2, 2) <= self.config.narrow_heading_sigma ** 2
                and position_sigma(P) <= self.config.narrow_position_sigma)


def _moments(components: Sequence[PoseKF], weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean (3,) and covariance (3, 3) of the weighted components (headings relative to the heaviest,
    the mean heading wrapped; a heading variance beyond :data:`UNKNOWN_HEADING_VARIANCE` scaled down
    to it, with its row and column, which keeps the matrix positive semi-definite)."""
    X = np.array([kf.x.reshape(3) for kf in components])
    w = np.asarray(weights, dtype=float) / float(np.sum(weights))
    ref = X[int(np.argmax(w)), 2]
    X[:, 2] = ref + (X[:, 2] - ref + math.pi) % (2.0 * math.pi) - math.pi
    mean = w @ X
    d = X - mean
    P = sum(wk * kf.P for wk, kf in zip(w, components)) + (d * w[:, None]).T @ d
    P = 0.5 * (P + P.T)
    if P.item(2, 2) > UNKNOWN_HEADING_VARIANCE:  # no heading is known: say so, not more
        f = math.sqrt(UNKNOWN_HEADING_VARIANCE / P.item(2, 2))
        P[2, :] *= f
        P[:, 2] *= f
    mean[2] = wrap_angle(float(mean[2]))
    return mean, P
