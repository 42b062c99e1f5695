"""Where to hang targets: the fewest placements that keep the predicted error within a budget.

The prediction (:mod:`agvsim.deploy.predict`) gives, for any set of targets, the filter's
largest position standard deviation σ after each camera frame of a lap of the route; the
budget is on the bound ``3σ`` (a Gaussian error exceeds it at a point once in 370 frames).
Selection is greedy, then pruned:

1. **Greedy on the predicted gain.** Each round tries every remaining candidate on top of the
   targets placed so far (one batch: :func:`agvsim.deploy.predict.propagate`, two laps from the
   current set's steady state, the second scored) and keeps the one that most reduces the
   *excess*: the route-integral of how far ``3σ`` exceeds the budget (a tie broken by the
   integral of ``3σ``). The excess falls as targets are added and each added target helps less
   where others already see (diminishing returns): the setting in which greedy selection is
   near-optimal for landmark placement (Beinhofer, Müller and Burgard, "Effective landmark
   placement for accurate and reliable mobile robot navigation", RAS 2013). It stops when the
   budget holds everywhere, or when no candidate reduces the excess (the budget is out of
   reach: the result says how close it came and with how many targets).
2. **Pruning.** Greedy choices made early can become redundant once later ones are placed:
   each placed target (latest first) is dropped if the budget still holds without it.

Candidates closer than ``min_spacing`` to a placed target are withdrawn. Polarities alternate
along the route (a neighbour of the other polarity cannot be confused with it).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from agvsim.deploy.predict import RouteModel, Sightings, propagate, steady_start

__all__ = ["Plan", "plan_targets"]

#: weight of the integral of 3σ beside the excess (breaks ties once the excess is zero nearby)
TIE_WEIGHT = 1e-3


@dataclass(frozen=True)
class Plan:
    """The planner's answer.

    Attributes:
        targets: every target of the new layout (kept ones first), polarities set.
        placed: ids of the targets the planner placed.
        sigma: ``(N,)`` predicted largest position σ (m) after each frame of a steady lap.
        s: ``(N,)`` route position of each frame (m).
        budget: the bound asked for on ``3σ`` (m).
        met: whether ``3σ <= budget`` along the whole route.
        longest_blind: longest stretch of route with no target in view (m).
        candidates: candidate placements considered (seen from the route).
        rounds: greedy rounds run.
    """

    targets: tuple
    placed: tuple[str, ...]
    sigma: np.ndarray
    s: np.ndarray
    budget: float
    met: bool
    longest_blind: float
    candidates: int
    rounds: int

    @property
    def worst_bound(self) -> float:
        """The predicted worst-point ``3σ`` (m)."""
        return float(3.0 * self.sigma.max())


def _excess(sigma: np.ndarray, budget: float, step: float) -> np.ndarray:
    bound = 3.0 * sigma
    return step * (np.maximum(bound - budget, 0.0).sum(axis=-1) + TIE_WEIGHT * bound.sum(axis=-1))


def _lap(model: RouteModel, sightings: Sightings) -> np.ndarray:
    """``(N,)`` σ over a steady lap with these sightings."""
    P0 = steady_start(model, sightings)
    _, sigma = propagate(model, P0[None], sightings)
    return sigma[0]


def _blind(model: RouteModel, sightings: Sightings) -> float:
    seen = np.zeros(model.frames, bool)
    seen[sightings.frame] = True
    runs, run = [], 0
    for v in np.concatenate([seen, seen] if model.path.loop else [seen]):  # (a loop's gap may wrap)
        run = 0 if v else run + 1
        runs.append(run)
    return min(max(runs, default=0), model.frames) * model.step


def plan_targets(model: RouteModel, candidates: list, keep: tuple = (), budget: float = 0.10,
                 min_spacing: float = 2.0, max_targets: int = 200, progress=None) -> Plan:
    """Choose placements among ``candidates`` (module docstring).

    Args:
        model: the route on paper. candidates: ``MapTarget`` placements (ids unique).
        keep: targets that stay. budget: bound on ``3σ`` (m). min_spacing: m between placed
        targets. max_targets: the most to place. progress: called with ``(round, worst 3σ m)``.
    Raises:
        ValueError: the camera sees no candidate and no kept target anywhere along the route.
    """
    everything = list(keep) + list(candidates)
    sights = model.sightings(everything)
    n_keep = len(keep)
    seen = np.unique(sights.target)
    pool = [int(k) for k in seen if k >= n_keep]
    considered = len(pool)
    if not len(seen):
        raise ValueError(f"route {model.route!r} of map {model.map.name!r}: the camera sees no place on the walls "
                         "from anywhere along it (check the route, the camera mount, the walls' surfaces and --forbid)")
    positions = np.array([t.position for t in everything]).reshape(-1, 2)
    chosen = list(range(n_keep))
    sigma = _lap(model, sights.of(chosen))
    rounds = 0
    while 3.0 * sigma.max() > budget and pool and len(chosen) - n_keep < max_targets:
        rounds += 1
        common = sights.of(chosen)
        P0 = np.repeat(steady_start(model, common)[None], len(pool), axis=0)
        batch_of = np.full(len(everything), -1)
        batch_of[pool] = np.arange(len(pool))
        each = sights.of(pool)
        P, _ = propagate(model, P0, common, each, batch_of)
        _, trial = propagate(model, P, common, each, batch_of)  # (the second lap is scored)
        gain = _excess(sigma, budget, model.step) - _excess(trial, budget, model.step)
        best = int(np.argmax(gain))
        if gain[best] <= 1e-12:
            break  # nothing helps: the budget is out of reach
        pick = pool[best]
        chosen.append(pick)
        sigma = trial[best]
        near = np.hypot(*(positions[pool] - positions[pick]).T) < min_spacing
        pool = [k for k, n in zip(pool, near) if not n]
        if progress is not None:
            progress(rounds, float(3.0 * sigma.max()))
    met = bool(3.0 * sigma.max() <= budget)
    if met:  # pruning: the latest first
        for k in list(reversed(chosen[n_keep:])):
            trial_set = [c for c in chosen if c != k]
            s = _lap(model, sights.of(trial_set))
            if 3.0 * s.max() <= budget:
                chosen, sigma = trial_set, s
    final = _lap(model, sights.of(chosen))
    placed = _polarities(model, sights, everything, chosen, n_keep)
    return Plan(targets=tuple(placed), placed=tuple(t.id for t in placed[n_keep:]), sigma=final, s=model.s,
                budget=budget, met=bool(3.0 * final.max() <= budget), longest_blind=_blind(model, sights.of(chosen)),
                candidates=considered, rounds=rounds)


def _polarities(model: RouteModel, sights: Sightings, everything: list, chosen: list[int], n_keep: int) -> list:
    """The chosen targets, new ones renamed ``P01``, ``P02``, ... in the order the route first
    sees them, with polarities alternating in that order (kept targets keep theirs)."""
    first = {}
    for f, t in zip(sights.frame, sights.target):
        first.setdefault(int(t), int(f))
    new = sorted(chosen[n_keep:], key=lambda k: first.get(k, model.frames))
    taken = {t.id for t in everything[:n_keep]}
    out = list(everything[:n_keep])
    polarity = "positive"
    number = 0
    for k in new:
        number += 1
        while f"P{number:02d}" in taken:
            number += 1
        out.append(replace(everything[k], id=f"P{number:02d}", polarity=polarity))
        polarity = "negative" if polarity == "positive" else "positive"
    return out
