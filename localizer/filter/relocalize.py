r"""Re-localization when the filter is lost.

Every observation of a target, paired with every map target of the same
polarity, gives a full pose (:func:`~localizer.filter.measurement.pose_from_measurement`)
with covariance ``J R Jᵀ`` (J its Jacobian w.r.t. (d, β, α)). Each pairing is
a *hypothesis*, a small EKF of its own, propagated by the same odometry as the
main filter. Targets look alike, so later observations of the *same* target
fit every hypothesis equally well; only a second, different target tells them
apart. A hypothesis is therefore **confirmed** when it has matched
``confirm_targets`` distinct targets and no other live hypothesis has matched
as many. A hypothesis whose observations fail to match any target
``max_misses`` times is dropped (a single false detection does not kill the
right one). Hypotheses closer than ``merge_distance`` / ``merge_heading`` are merged.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from localizer.mount import CameraMount
from localizer.filter.association import ACCEPTED, GateConfig, associate, innovation
from localizer.filter.measurement import (Measurement, TargetMap, measurement_jacobian,
                                          pose_from_measurement, pose_from_measurement_jacobian,
                                          predict_measurement, wrap_angle)
from localizer.filter.motion import compose, compose_jacobians

__all__ = ["Hypothesis", "RelocalizeConfig", "Relocalizer"]


@dataclass(frozen=True)
class RelocalizeConfig:
    """Re-localization settings.

    Attributes:
        confirm_targets: distinct targets a hypothesis must match to be confirmed.
        max_misses: unmatched observations before a hypothesis is dropped.
        max_hypotheses: cap on live hypotheses (the best-supported are kept).
        merge_distance: hypotheses closer than this (m) ...
        merge_heading: ... and this (rad) are merged.
        bounds: optional (xmin, ymin, xmax, ymax) (m) the vehicle must be inside.
    """

    confirm_targets: int = 2
    max_misses: int = 3
    max_hypotheses: int = 256
    merge_distance: float = 0.3  # m
    merge_heading: float = math.radians(5.0)  # rad
    bounds: tuple[float, float, float, float] | None = None  # m

    def __post_init__(self) -> None:
        if self.confirm_targets < 1 or self.max_misses < 1 or self.max_hypotheses < 1:
            raise ValueError("RelocalizeConfig: confirm_targets, max_misses and max_hypotheses must be >= 1")
        if not (self.merge_distance >= 0 and self.merge_heading >= 0):
            raise ValueError("RelocalizeConfig: merge_distance and merge_heading must be >= 0")


@dataclass
class Hypothesis:
    """One candidate pose: state x (3,), covariance P (3, 3), the targets it matched, misses."""

    x: np.ndarray
    P: np.ndarray
    matched: set = field(default_factory=set)
    misses: int = 0


class Relocalizer:
    """Keeps hypotheses while the main filter is lost (see the module docstring).

    Args:
        targets, mount: map targets and camera mount.
        gate: association settings (the χ² gate is reused).
        config: re-localization settings.
    """

    def __init__(self, targets: TargetMap, mount: CameraMount, gate: GateConfig = GateConfig(),
                 config: RelocalizeConfig = RelocalizeConfig()) -> None:
        self.targets = targets
        self.mount = mount
        self.gate = gate
        self.config = config
        self.hypotheses: list[Hypothesis] = []

    def reset(self) -> None:
        """Drop every hypothesis."""
        self.hypotheses = []

    def predict(self, u: np.ndarray, Q: np.ndarray) -> None:
        """Move every hypothesis by the relative motion u (3,) with covariance Q (3, 3)."""
        for h in self.hypotheses:
            F, G = compose_jacobians(h.x, u)
            h.x = compose(h.x, u)
            h.P = F @ h.P @ F.T + G @ Q @ G.T

    def seed(self, measurements: Sequence[Measurement], prior: Hypothesis | None = None) -> int:
        """Add hypotheses from every (observation, same-polarity target) pairing; returns how many."""
        added = 0
        if prior is not None:
            self.hypotheses.append(prior)
        for m in measurements:
            for j in range(len(self.targets)):
                pol = self.targets.polarities[j]
                if self.gate.use_polarity and m.polarity is not None and pol not in (None, m.polarity):
                    continue
                gamma = wrap_angle(float(m.z[2] - m.z[1]))
                if abs(gamma) > self.gate.view.max_incidence:
                    continue
                x = pose_from_measurement(m.z, self.targets.positions[j], self.targets.yaws[j], self.mount)
                b = self.config.bounds
                if b is not None and not (b[0] <= x[0] <= b[2] and b[1] <= x[1] <= b[3]):
                    continue
                J = pose_from_measurement_jacobian(m.z, self.targets.positions[j], self.targets.yaws[j],
                                                   self.mount)
                P = J @ m.R @ J.T + np.diag([1e-6, 1e-6, 1e-8])
                self.hypotheses.append(Hypothesis(x, P, {self.targets.ids[j]}))
                added += 1
        self._merge()
        return added

    def _merge(self) -> None:
        kept: list[Hypothesis] = []
        cfg = self.config
        for h in sorted(self.hypotheses, key=lambda h: (-len(h.matched), h.misses)):
            dup = False
            for k in kept:
                if (np.hypot(*(h.x[:2] - k.x[:2])) < cfg.merge_distance
                        and abs(wrap_angle(float(h.x[2] - k.x[2]))) < cfg.merge_heading):
                    k.matched |= h.matched
                    dup = True
                    break
            if not dup:
                kept.append(h)
        self.hypotheses = kept[:cfg.max_hypotheses]

    def update(self, measurements: Sequence[Measurement]) -> Hypothesis | None:
        """Test every hypothesis against a frame; returns the confirmed one, if any."""
        if not measurements:
            return None
        alive: list[Hypothesis] = []
        for h in self.hypotheses:
            assoc = associate(h.x, h.P, measurements, self.targets, self.mount, self.gate)
            for a in assoc:
                if a.status != ACCEPTED:
                    h.misses += 1
                    continue
                m = measurements[a.observation]
                pos, yaw = self.targets.positions[a.target], self.targets.yaws[a.target]
                H = measurement_jacobian(h.x, pos, yaw, self.mount)
                S = H @ h.P @ H.T + m.R
                K = h.P @ H.T @ np.linalg.inv(S)
                h.x = h.x + K @ innovation(m.z, predict_measurement(h.x, pos, yaw, self.mount))
                I_KH = np.eye(3) - K @ H
                h.P = I_KH @ h.P @ I_KH.T + K @ m.R @ K.T
                h.matched.add(a.target_id)
            if h.misses < self.config.max_misses:
                alive.append(h)
        self.hypotheses = alive
        self._merge()
        if not alive:
            return None
        best = max(len(h.matched) for h in self.hypotheses)
        top = [h for h in self.hypotheses if len(h.matched) == best]
        if best >= self.config.confirm_targets and len(top) == 1:
            return top[0]
        return None
