r"""Re-localization when the filter is lost.

Every observation of a target, paired with every map target of the same
polarity, gives a full pose (:func:`~localizer.filter.measurement.pose_from_measurement`)
with covariance ``J R Jᵀ`` (J its Jacobian w.r.t. (d, β, α)). Each pairing is
a *hypothesis*, a small EKF of its own (a filterpy EKF,
:class:`~localizer.filter.update.PoseKF`), propagated by the same odometry as the
main filter and updated through the same filterpy update
(:mod:`localizer.filter.update`). Targets look alike, so later observations of the *same* target
fit every hypothesis equally well; only a second, different target tells them
apart. A hypothesis is therefore **confirmed** when it has matched
``confirm_targets`` distinct targets and no other live hypothesis has matched
as many. A hypothesis whose observations fail to match any target
``max_misses`` times is dropped (a single false detection does not kill the
right one). Hypotheses closer than ``merge_distance`` / ``merge_heading`` are merged.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from localizer.filter.association import ACCEPTED, GateConfig, associate
from localizer.filter.measurement import (Measurement, TargetMap, pose_from_measurement,
                                          pose_from_measurement_jacobian)
from localizer.filter.update import PoseKF, predict_pose, update_pose
from localizer.mount import CameraMount
from localizer.numeric import check_number, wrap_angle

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
        for name in ("confirm_targets", "max_misses", "max_hypotheses"):
            check_number(f"RelocalizeConfig.{name}", getattr(self, name), low=1, integer=True)
        check_number("RelocalizeConfig.merge_distance", self.merge_distance, low=0.0, unit="m")
        check_number("RelocalizeConfig.merge_heading", self.merge_heading, low=0.0, unit="rad")


class Hypothesis:
    """One candidate pose, a filterpy EKF of its own (:attr:`kf`), the targets it matched, misses.

    Args:
        x: (3,) pose (m, m, rad).
        P: (3, 3) its covariance.
        matched: ids of the targets it matched.
        misses: observations it failed to match.
    """

    def __init__(self, x, P, matched: Iterable[str] = (), misses: int = 0) -> None:
        self.kf = PoseKF(x, P)
        self.matched = set(matched)
        self.misses = misses

    @property
    def x(self) -> np.ndarray:
        """(3,) pose (a view of the EKF state)."""
        return self.kf.x.reshape(-1)

    @x.setter
    def x(self, value) -> None:
        self.kf.x = np.asarray(value, dtype=float).reshape(3, 1).copy()

    @property
    def P(self) -> np.ndarray:
        """(3, 3) covariance (the EKF's)."""
        return self.kf.P

    @P.setter
    def P(self, value) -> None:
        self.kf.P = np.asarray(value, dtype=float).copy()

    def __repr__(self) -> str:
        return f"Hypothesis(x={self.x!r}, matched={sorted(self.matched)!r}, misses={self.misses})"


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
            predict_pose(h.kf, u, Q)

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
                update_pose(h.kf, m, self.targets.positions[a.target], self.targets.yaws[a.target], self.mount)
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
