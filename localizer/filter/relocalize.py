r"""Global re-localization when the filter is lost (the kidnapped robot).

Every observation of a target, paired with every map target of the same polarity, gives a
full pose (:func:`~localizer.filter.measurement.pose_from_measurement`) with covariance
``J R Jᵀ`` (J its Jacobian w.r.t. (d, β, α)). Each pairing is a *hypothesis*, a small EKF of
its own (a filterpy EKF, :class:`~localizer.filter.update.PoseKF`), propagated by the same
odometry as the main filter and updated through the same filterpy update
(:mod:`localizer.filter.update`). Nothing of the lost filter's own estimate is used.

Each frame (:meth:`Relocalizer.process`): every live hypothesis associates the frame's
observations (the main filter's χ² gate) and is updated with those it accepts; then every
observation seeds hypotheses (all its pairings; those that duplicate a live hypothesis merge
into it; none from an observation that alone places the vehicle only beyond ``max_sigma``),
so the right pose is among them even when a wrong hypothesis happens to explain what is seen.
Hypotheses outside the map's free space are dropped, as are those that refused
``max_misses`` observations another hypothesis fits since the last frame they explained whole
(a false detection, which fits no hypothesis, does not kill the right one; a loose observation,
one that is no evidence, neither counts for a hypothesis nor against it), and
of two hypotheses closer than ``merge_distance`` / ``merge_heading`` only the better supported
is kept. A match counts as evidence only while the hypothesis is precise (position σ within
``confirm_sigma``): a loose gate accepts anything; and only from an informative observation (one
that alone places the vehicle within ``evidence_sigma``): a loose observation fits anything.
Refusals are counted by reason (:attr:`Relocalizer.refusals`). At most
``max_hypotheses`` live (the best supported, then the newest), which bounds the cost per
frame (about ``max_hypotheses`` associations).

Targets look alike, so later observations of the *same* target fit every hypothesis seeded
from it equally well; only a different target tells them apart. A hypothesis is
**confirmed** when, for ``confirm_frames`` frames in a row (frames with an informative
observation: one of loose observations only says nothing), it alone has *explained* the most
distinct targets ``confirm_sightings`` times each, at least ``confirm_targets`` (accepted
informative observations of them through its gate in as many frames, whether they counted as
evidence or not: a rival whose gate is too loose for evidence still fits what is seen; a false
detection that happens to fit fits once; the seeding observation is no test, the hypothesis
was made to fit it), it matched ``confirm_targets`` targets as evidence, it explained its last
frame whole, and its position σ is within ``confirm_sigma``. An observation
that no hypothesis fits counts against none (it is likely a false detection). On a map whose
targets are laid out symmetrically (two places from which the same targets look the same), two
hypotheses keep explaining as many targets as each other: the filter then stays
``relocalizing``, never picks one, until a target that breaks the symmetry is seen.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Iterable, Sequence

import numpy as np

from localizer.filter.association import ACCEPTED, GateConfig, associate
from localizer.filter.measurement import (Measurement, TargetMap, pose_from_measurement,
                                          pose_from_measurement_jacobian)
from localizer.filter.update import PoseKF, is_positive_definite, position_sigma, predict_pose, update_pose
from localizer.model.mount import CameraMount
from localizer.numeric import check_number, wrap_angle

__all__ = ["Hypothesis", "RelocalizeConfig", "Relocalizer"]


@dataclass(frozen=True)
class RelocalizeConfig:
    """Re-localization settings.

    Attributes:
        confirm_targets: distinct targets a hypothesis must match to be confirmed.
        confirm_sightings: times (frames) a hypothesis must have explained a target for it to
            count towards confirmation (the seeding observation not included).
        confirm_frames: frames in a row (with an informative observation) it must lead (be the
            one that would be confirmed): one observation whose covariance does not fit its
            error can tip the lead once.
        max_misses: informative observations that another hypothesis fits, refused since the
            last frame a hypothesis explained whole, before it is dropped.
        max_hypotheses: cap on live hypotheses (the best-supported are kept).
        merge_distance: hypotheses closer than this (m) ...
        merge_heading: ... and this (rad): only the better supported is kept.
        bounds: optional (xmin, ymin, xmax, ymax) (m) the vehicle must be inside.
        max_sigma: a hypothesis whose position σ (m, largest) grows past this is dropped (its
            gate would accept anything; while the wheels slip against a wall, fresh
            observations seed precise ones again).
        confirm_sigma: position σ (m) a hypothesis must be within to be confirmed (its covariance
            finite and positive definite besides).
        evidence_sigma: a match counts towards confirmation only when the observation alone
            places the vehicle within this position σ (m, the largest of ``J R Jᵀ``): an
            observation whose covariance is loose fits any hypothesis and tells none apart.
        view_margin: extra bearing (rad) on the gate's view margin when a hypothesis predicts
            which targets are in view (a target at the edge of the image must not count
            against the right hypothesis).
        replay_frames: at most this many frames since the last accepted observation (with the
            odometry between them) the main filter keeps while tracking and replays into the re-localization when it finds itself lost: the
            detections that made it lost are the first evidence of where the vehicle is.
    """

    confirm_targets: int = 2
    confirm_sightings: int = 2
    confirm_frames: int = 2
    max_misses: int = 3
    max_hypotheses: int = 96
    merge_distance: float = 0.3  # m
    merge_heading: float = math.radians(5.0)  # rad
    bounds: tuple[float, float, float, float] | None = None  # m
    max_sigma: float = 1.0  # m
    confirm_sigma: float = 0.25  # m
    evidence_sigma: float = 1.0  # m
    view_margin: float = math.radians(4.0)  # rad
    replay_frames: int = 60

    def __post_init__(self) -> None:
        for name in ("confirm_targets", "confirm_sightings", "confirm_frames", "max_misses", "max_hypotheses",
                     "replay_frames"):
            check_number(f"RelocalizeConfig.{name}", getattr(self, name), low=1, integer=True)
        check_number("RelocalizeConfig.merge_distance", self.merge_distance, low=0.0, unit="m")
        check_number("RelocalizeConfig.merge_heading", self.merge_heading, low=0.0, unit="rad")
        check_number("RelocalizeConfig.view_margin", self.view_margin, low=0.0, unit="rad")
        for name in ("max_sigma", "confirm_sigma", "evidence_sigma"):
            check_number(f"RelocalizeConfig.{name}", getattr(self, name), low=0.0, low_open=True, unit="m")


class Hypothesis:
    """One candidate pose, a filterpy EKF of its own (:attr:`kf`), the targets it matched, misses.

    Args:
        x: (3,) pose (m, m, rad).
        P: (3, 3) its covariance.
        matched: ids of the targets it matched as evidence (towards its confirmation).
        misses: observations it failed to match.
        explained: times it accepted an informative observation through its gate, evidence or
            not, by target id (what it fits, towards its confirmation and against a rival's;
            default: once each ``matched`` id).

    ``unexplained``: the informative observations of the last frame it refused.
    """

    def __init__(self, x, P, matched: Iterable[str] = (), misses: int = 0, born: int = 0,
                 explained: dict[str, int] | None = None) -> None:
        self.kf = PoseKF(x, P)
        self.matched = set(matched)
        self.explained = {t: 1 for t in self.matched} if explained is None else dict(explained)
        self.unexplained = 0
        self.misses = misses
        self.born = born  # creation order (newer is larger)

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

    def position_sigma(self) -> float:
        """The largest standard deviation of the position (m)."""
        return position_sigma(self.kf.P)

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
                 config: RelocalizeConfig = RelocalizeConfig(), free_space=None) -> None:
        self.targets = targets
        self.mount = mount
        self.gate = gate
        self.config = config
        # the hypotheses' gate: the main filter's, seeing a little wider (view_margin)
        self._gate = replace(gate, view=replace(gate.view, margin=gate.view.margin + config.view_margin))
        self.free_space = free_space  # (x m, y m) -> bool, or None
        self.hypotheses: list[Hypothesis] = []
        self._born = 0  # hypotheses made so far (their age order)
        #: refusals by reason: ``uninformative_match`` (a match from an observation too loose to
        #: be evidence), ``unsound_seed`` (a pairing whose pose covariance is not finite positive
        #: definite), ``imprecise_confirmation`` (the best-supported hypothesis refused as
        #: confirmed: covariance not positive definite or position σ above ``confirm_sigma``)
        self.refusals: dict[str, int] = {}
        self._leader: Hypothesis | None = None  # the one that would be confirmed ...
        self._lead = 0  # ... for this many frames in a row

    def reset(self) -> None:
        """Drop every hypothesis."""
        self.hypotheses = []
        self._leader, self._lead = None, 0

    def predict(self, u: np.ndarray, Q: np.ndarray) -> None:
        """Move every hypothesis by the relative motion u (3,) with covariance Q (3, 3)."""
        for h in self.hypotheses:
            predict_pose(h.kf, u, Q)

    def _free(self, x) -> bool:
        b = self.config.bounds
        if b is not None and not (b[0] <= x[0] <= b[2] and b[1] <= x[1] <= b[3]):
            return False
        return self.free_space is None or bool(self.free_space(float(x[0]), float(x[1])))

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
                if not self._free(x):
                    continue
                J = pose_from_measurement_jacobian(m.z, self.targets.positions[j], self.targets.yaws[j],
                                                   self.mount)
                evidence = J @ m.R @ J.T
                P = evidence + np.diag([1e-6, 1e-6, 1e-8])
                if not is_positive_definite(P):
                    self._refuse("unsound_seed")
                    continue
                sigma = position_sigma(evidence)
                if sigma > self.config.max_sigma:  # the next test would drop it; in _merge it could
                    self._refuse("uninformative_match")  # displace a sound hypothesis at its place
                    continue
                self._born += 1
                # the seeding observation is the first match, when it is evidence (is_evidence); it
                # explains nothing (a hypothesis made from an observation fits it by construction)
                if sigma <= self.config.evidence_sigma:
                    matched = {self.targets.ids[j]}
                else:
                    matched = set()
                    self._refuse("uninformative_match")
                self.hypotheses.append(Hypothesis(x, P, matched, born=self._born, explained={}))
                added += 1
        self._merge()
        return added

    def _merge(self) -> None:
        kept: list[Hypothesis] = []
        cfg = self.config
        for h in sorted(self.hypotheses, key=lambda h: (-len(h.matched), h.misses, -h.born)):
            dup = False
            for k in kept:
                if (np.hypot(*(h.x[:2] - k.x[:2])) < cfg.merge_distance
                        and abs(wrap_angle(float(h.x[2] - k.x[2]))) < cfg.merge_heading):
                    dup = True  # the better supported one is kept (no union of evidence) ...
                    for t, n in h.explained.items():  # ... and fits what either fitted, against its rivals
                        k.explained[t] = max(k.explained.get(t, 0), n)
                    break
            if not dup:
                kept.append(h)
        self.hypotheses = kept[:cfg.max_hypotheses]

    def update(self, measurements: Sequence[Measurement]) -> Hypothesis | None:
        """Test every hypothesis against a frame; returns the confirmed one, if any."""
        if self._test(measurements):
            self._follow_lead()
        return self.confirmed()

    def process(self, measurements: Sequence[Measurement], evidence: bool = True) -> Hypothesis | None:
        """One frame while lost (module docstring): test the live hypotheses, seed new ones
        from every observation (those a live hypothesis already explains merge into it);
        returns the confirmed one, if any. ``evidence=False`` (the wheels may be slipping):
        the hypotheses are updated, but what they match does not count towards confirmation."""
        if not measurements:
            return None
        informed = self._test(measurements, evidence)
        self.seed(measurements)  # duplicates of live hypotheses merge away
        if informed:  # a frame of loose observations only says nothing, for the lead either
            self._follow_lead()
        return self.confirmed()

    def _test(self, measurements: Sequence[Measurement], evidence: bool = True) -> bool:
        """Associate and update every live hypothesis; drop the dead; whether the frame held an
        informative observation."""
        if not measurements:
            return False
        # a loose observation fits anything: it updates a hypothesis, but says nothing for or against it
        informative = [self.is_evidence(m) for m in measurements]
        fitted: set[int] = set()  # the informative observations some hypothesis accepted
        refusals = []
        for h in self.hypotheses:
            assoc = associate(h.x, h.P, measurements, self.targets, self.mount, self._gate)
            refused, accepted = [], 0
            # a match is evidence only when the gate was tight (a loose one accepts anything)
            precise = evidence and h.position_sigma() <= self.config.confirm_sigma and is_positive_definite(h.P)
            for a in assoc:
                if a.status != ACCEPTED:
                    if informative[a.observation]:
                        refused.append(a.observation)
                    continue
                m = measurements[a.observation]
                pos, yaw = self.targets.positions[a.target], self.targets.yaws[a.target]
                update_pose(h.kf, m, pos, yaw, self.mount)
                if informative[a.observation]:
                    accepted += 1
                    fitted.add(a.observation)
                    h.explained[a.target_id] = h.explained.get(a.target_id, 0) + 1
                    if precise:
                        h.matched.add(a.target_id)
                elif precise:
                    self._refuse("uninformative_match")
            refusals.append((refused, accepted))
        alive: list[Hypothesis] = []
        for h, (refused, accepted) in zip(self.hypotheses, refusals):
            h.unexplained = len(refused)
            # misses: since the last frame it explained whole, the informative observations it
            # refused that another hypothesis fits (one that fits nowhere is likely a false detection)
            against = sum(k in fitted for k in refused)
            h.misses = h.misses + against if against else (0 if accepted and not refused else h.misses)
            if (h.misses < self.config.max_misses and h.position_sigma() <= self.config.max_sigma
                    and is_positive_definite(h.P) and self._free(h.x)):
                alive.append(h)
        self.hypotheses = alive
        self._merge()
        return any(informative)

    def confirmed(self) -> Hypothesis | None:
        """The hypothesis that has led (:meth:`_leading`) for ``confirm_frames`` frames in a
        row (frames with an informative observation); or None."""
        if self._lead >= self.config.confirm_frames and self._leader in self.hypotheses:
            return self._leader
        return None

    def _follow_lead(self) -> None:
        """After a frame: the leader, and for how many frames in a row it has led."""
        h = self._leading()
        self._lead = self._lead + 1 if h is not None and h is self._leader else int(h is not None)
        self._leader = h

    def _leading(self) -> Hypothesis | None:
        """The hypothesis that alone explained the most distinct targets ``confirm_sightings``
        times each (``confirm_targets`` at least), matched ``confirm_targets`` as evidence,
        explained its last frame whole, within ``confirm_sigma``; or None."""
        if not self.hypotheses:
            return None
        k = self.config.confirm_sightings
        # what each fits: the targets it explained k times (a false detection fits once)
        fits = [sum(n >= k for n in h.explained.values()) for h in self.hypotheses]
        best = max(fits)
        if best >= self.config.confirm_targets and fits.count(best) == 1:  # no rival fits as much
            h = self.hypotheses[fits.index(best)]
            if len(h.matched) < self.config.confirm_targets or h.unexplained:
                return None  # too little of it evidence, or the frame not explained whole
            P = h.P
            if is_positive_definite(P) and float(np.linalg.eigvalsh(P[:2, :2])[-1]) <= self.config.confirm_sigma ** 2:
                return h
            self._refuse("imprecise_confirmation")
        return None

    def is_evidence(self, m: Measurement) -> bool:
        """Whether ``m`` alone places the vehicle within ``evidence_sigma`` (position σ of
        ``J R Jᵀ``, J the Jacobian of the pose it gives from a target: the same for every
        target, as moving or turning the target moves or turns that pose)."""
        J = pose_from_measurement_jacobian(m.z, (0.0, 0.0), 0.0, self.mount)
        sigma = position_sigma(J @ m.R @ J.T)
        return sigma <= self.config.evidence_sigma  # False for nan

    def _refuse(self, reason: str) -> None:
        self.refusals[reason] = self.refusals.get(reason, 0) + 1
