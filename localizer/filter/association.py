r"""Data association: which map target did each observation see?

All targets look alike (only the polarity differs), so each observation is
matched by its Mahalanobis distance to every map target predicted in view::

    ν_j = z ⊖ h_j(x)       (angles wrapped)
    S_j = H_j P H_jᵀ + R
    D²_j = ν_jᵀ S_j⁻¹ ν_j  ~ χ²(3) for the right target

The observation is *accepted* for the nearest candidate when its D² is inside
the χ² gate (``gate_probability``), *refused as ambiguous* when a second
candidate is also inside the gate and not clearly worse
(``D²_2 - D²_1 < ambiguity_margin``), and *rejected* otherwise. Two
observations claiming one target in a frame are both refused.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Sequence

import numpy as np
from scipy.stats import chi2

from localizer.filter.measurement import (Measurement, TargetMap, ViewLimits,
                                          measurement_jacobian, predict_all)
from localizer.model.mount import CameraMount
from localizer.numeric import check_number, wrap_angle

__all__ = ["ACCEPTED", "AMBIGUOUS", "Association", "DUPLICATE", "GATED", "GateConfig", "NO_CANDIDATE",
           "associate", "gate_threshold", "innovation"]

ACCEPTED = "accepted"
GATED = "gated"  # nearest candidate outside the χ² gate
AMBIGUOUS = "ambiguous"  # two candidates inside the gate
NO_CANDIDATE = "no_candidate"  # no target predicted in view (with matching polarity)
DUPLICATE = "duplicate"  # another observation in the frame claimed the same target
STATUSES = (ACCEPTED, GATED, AMBIGUOUS, NO_CANDIDATE, DUPLICATE)


@lru_cache(maxsize=None)
def gate_threshold(probability: float, dof: int = 3) -> float:
    """The χ²(``dof``) quantile of ``probability``: the gate on D² (computed once per pair;
    ``scipy.stats.chi2.ppf`` costs about 0.1 ms a call)."""
    return float(chi2.ppf(probability, dof))


@dataclass(frozen=True)
class GateConfig:
    """Association settings.

    Attributes:
        gate_probability: χ²(3) probability of the validation gate.
        ambiguity_margin: a second in-gate candidate within this D² of the best makes the match ambiguous.
        use_polarity: only match targets of the observed polarity.
        view: which targets are predicted in view.
    """

    gate_probability: float = 0.999  # dimensionless
    ambiguity_margin: float = 9.0  # D², dimensionless
    use_polarity: bool = True
    view: ViewLimits = ViewLimits()

    def __post_init__(self) -> None:
        check_number("GateConfig.gate_probability", self.gate_probability, low=0.0, high=1.0, low_open=True,
                     high_open=True)
        check_number("GateConfig.ambiguity_margin", self.ambiguity_margin, low=0.0, unit="D²")

    @property
    def gate(self) -> float:
        """The gate threshold on D² (χ²(3) quantile)."""
        return gate_threshold(self.gate_probability, 3)


@dataclass(frozen=True)
class Association:
    """The association of one observation.

    Attributes:
        observation: index of the observation in the frame.
        status: one of ``accepted``, ``gated``, ``ambiguous``, ``no_candidate``, ``duplicate``.
        target: index into the :class:`TargetMap` of the best candidate, or -1.
        target_id: its id, or ``""``.
        d2: D² of the best candidate (inf when none).
        d2_second: D² of the runner-up (inf when none).
        candidates: number of candidates predicted in view.
    """

    observation: int
    status: str
    target: int
    target_id: str
    d2: float
    d2_second: float
    candidates: int


def innovation(z: np.ndarray, hx: np.ndarray) -> np.ndarray:
    """z ⊖ h(x) with the angle components (β, α) wrapped to [-π, π); shapes (3,) or (3, 1)."""
    y = np.subtract(z, hx)
    flat = y.reshape(-1)
    flat[1] = wrap_angle(float(flat[1]))
    flat[2] = wrap_angle(float(flat[2]))
    return y


def associate(x, P, measurements: Sequence[Measurement], targets: TargetMap, mount: CameraMount,
              config: GateConfig = GateConfig()) -> list[Association]:
    """Associate every measurement of one frame with a map target (see the module docstring).

    Args:
        x: (3,) pose estimate at the frame's capture time.
        P: (3, 3) its covariance.
        measurements: the frame's observations.
        targets, mount: the map's targets and the camera mount.
        config: gate settings.
    """
    x = np.asarray(x, dtype=float).reshape(-1)
    P = np.asarray(P, dtype=float)
    Z, visible = predict_all(x, targets, mount, config.view)
    cand = np.nonzero(visible)[0]
    gate = config.gate
    out: list[Association] = []
    for k, m in enumerate(measurements):
        idx = cand
        if config.use_polarity and m.polarity is not None:
            idx = np.array([j for j in cand if targets.polarities[j] in (None, m.polarity)], dtype=int)
        if len(idx) == 0:
            out.append(Association(k, NO_CANDIDATE, -1, "", math.inf, math.inf, 0))
            continue
        d2 = np.empty(len(idx))
        for n, j in enumerate(idx):
            H = measurement_jacobian(x, targets.positions[j], targets.yaws[j], mount)
            S = H @ P @ H.T + m.R
            nu = innovation(m.z, Z[j])
            try:
                d2[n] = float(nu @ np.linalg.solve(S, nu))
            except np.linalg.LinAlgError:
                d2[n] = math.inf
        order = np.argsort(d2)
        best = int(idx[order[0]])
        d2_1 = float(d2[order[0]])
        d2_2 = float(d2[order[1]]) if len(order) > 1 else math.inf
        if d2_1 > gate:
            status = GATED
        elif d2_2 <= gate and d2_2 - d2_1 < config.ambiguity_margin:
            status = AMBIGUOUS
        else:
            status = ACCEPTED
        out.append(Association(k, status, best, targets.ids[best], d2_1, d2_2, len(idx)))
    # two accepted observations claiming one target: refuse both
    claimed: dict[int, list[int]] = {}
    for a in out:
        if a.status == ACCEPTED:
            claimed.setdefault(a.target, []).append(a.observation)
    for target, obs in claimed.items():
        if len(obs) > 1:
            for k in obs:
                a = out[k]
                out[k] = Association(a.observation, DUPLICATE, a.target, a.target_id, a.d2, a.d2_second,
                                     a.candidates)
    return out
