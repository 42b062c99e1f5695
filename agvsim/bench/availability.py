"""``agvsim bench availability``: is the pose filter there, and honest, while an agent drives?

The filter is driven as a reinforcement-learning agent drives it: through the Gymnasium env
(``agvsim/PlantFloor-v2``, ``agvsim/Corridor-v2``; rendered frames, raycast backend, the envs'
defaults), ``reset(seed=s)`` for seeds ``0 .. --seeds - 1``, then ``--steps`` policy steps
(10 Hz) of one policy of :data:`POLICIES`, the env reset whenever an episode ends:

``uniform``
    ``env.action_space.seed(s)``, then ``env.action_space.sample()`` every step (uniform in
    ``[-1, 1]²``: as often backwards as forwards, turning hard).
``forward``
    The forward-biased smoothed walk ``a <- 0.9 a + 0.1 (U(0.2, 1), U(-1, 1))`` drawn from
    ``numpy.random.default_rng(s)`` (as ``agvsim bench localization-integrity``'s random agent).
``wall``
    The constant action :data:`WALL_ACTION` (half speed straight ahead, 0.75 m/s): from the
    start station into whatever wall or obstacle lies ahead, then pushing into it, wheels
    spinning, to the episode's end (the envs' ``goto`` task also ends an episode at its goal
    station, which a straight drive along the corridor can reach).

Each step reads what an agent gets: ``info["localization"]`` (``status``, ``position_sigma``,
``reason``), ``info["observations"]`` (targets accepted and rejected this step: a target was
*measured* when either is non-zero), the ``covariance`` observation (its 2 x 2 position block)
and, for the scoring only, ``info["true_pose"]`` against ``info["estimated_pose"]``: the
position error ``e`` (m). Figures per (env, policy), summed over the seeds
(:func:`episode_figures`):

- *tracking*: % of steps with the status ``tracking``;
- *honest*: % of steps not tracking, or with ``eᵀ P⁻¹ e <= χ²₂(0.9973) = 11.83`` (inside the
  reported "3σ" region);
- *confident-wrong*: steps tracking with ``|e| > 0.5 m`` outside that region;
- *lost events*: steps from ``tracking`` into ``lost`` or ``relocalizing``; *false* when, at
  the last tracking step before, ``|e| < 10 cm`` and ``position_sigma < 10 cm``;
- *recovery* of each loss: the steps with a target measured after the loss step, up to and
  including the first step tracking with ``|e| <= 10 cm`` (median, max); a loss that never
  gets there before its episode ends is *unrecovered* (the JSON keeps its measured steps so far,
  and every loss's reason, its numbers as ``N``).

``--wide`` gives the filter its opt-in wide belief (``FilterConfig.wide``, the env's
``filter_config={"wide": WideConfig()}``). Kidnaps, unknown starts and scripted wall pushes on
an oracle driver are ``agvsim bench localization-integrity``'s: not repeated here.
"""
from __future__ import annotations

import re
import sys
import time
from typing import NamedTuple

import numpy as np

from agvsim.bench.floors import floor_line, verdict
from agvsim.bench.localization_integrity import CHI2_2_3SIGMA
from agvsim.commands._args import number
from agvsim.commands._output import plural

__all__ = ["ENVS", "FLOORS", "POLICIES", "POLICY_SUMMARIES", "StepRecord", "add_arguments", "empty_figures",
           "episode_figures", "format_table", "merge_figures", "reason_kind", "run", "summarize", "worst_floors"]

#: the envs driven, by Gymnasium id
ENVS = ("agvsim/PlantFloor-v2", "agvsim/Corridor-v2")
#: policy -> what it does (module docstring), in report order
POLICY_SUMMARIES = {
    "uniform": "env.action_space.sample() every step",
    "forward": "the smoothed forward-biased walk a <- 0.9 a + 0.1 (U(0.2, 1), U(-1, 1))",
    "wall": "half speed straight ahead into a wall or obstacle, then pushing",
}
#: the policies, in report order
POLICIES = tuple(POLICY_SUMMARIES)
#: the ``wall`` policy's action: (forward speed, yaw rate) as fractions of the vehicle's limits
WALL_ACTION = (0.5, 0.0)
CONFIDENT_WRONG_M = 0.5  # m: a tracking error beyond this, outside 3σ, is confident and wrong
FALSE_LOST_M = 0.10  # m: error and σ at the last tracking step below which a loss was false
RECOVERED_M = 0.10  # m: tracking within this error again ends a loss
#: floor name -> (figure, op, limit, unit)
FLOORS = {
    "false lost events": ("false_lost_events", "<=", 0, ""),
    "tracking": ("tracking_pct", ">=", 90.0, "%"),
    "honest": ("honest_pct", ">=", 99.0, "%"),
    "recovery median": ("recovery_median", "<=", 8, "measured steps"),
    "recovery max": ("recovery_max", "<=", 30, "measured steps"),
    "confident-wrong steps": ("confident_wrong", "<=", 0, ""),
}


def add_arguments(parser) -> None:
    parser.add_argument("--seeds", type=number(1, integer=True), default=12,
                        help="seeds per env and policy (default: %(default)s)")
    parser.add_argument("--steps", type=number(1, integer=True), default=2000,
                        help="policy steps (10 Hz) per seed (default: %(default)s)")
    parser.add_argument("--envs", nargs="+", default=list(ENVS), choices=ENVS, help="default: both")
    parser.add_argument("--policies", nargs="+", default=list(POLICIES), choices=POLICIES,
                        help="; ".join(f"{k}: {v}" for k, v in POLICY_SUMMARIES.items()) + " (default: all)")
    parser.add_argument("--workers", type=number(1, integer=True), default=2,
                        help="worker processes (default: %(default)s)")
    parser.add_argument("--wide", action="store_true",
                        help="give the filter its opt-in wide belief (FilterConfig.wide)")


# ----------------------------------------------------------------------------- the figures


class StepRecord(NamedTuple):
    """What one step (or the reset) left to score."""

    status: str  # localization status
    error_m: float  # true position error (m)
    mahalanobis2: float  # eᵀ P⁻¹ e of that error under the reported position covariance (dimensionless)
    sigma_m: float  # info["localization"]["position_sigma"] (m)
    measured: bool  # a target accepted or rejected this step
    reason: str | None = None  # why lost (None while tracking)


def empty_figures() -> dict:
    """The figures of nothing driven yet, to :func:`merge_figures` into: step counts, lost events,
    ``recoveries`` (measured steps of each recovered loss), ``unrecovered_measured`` (those of
    each loss unrecovered at its episode's end), reason counts, and the filter's own counts
    (``filter_lost_events``, ``relocalizations``, from ``info["localization"]``)."""
    return {"episodes": 0, "steps": 0, "tracking_steps": 0, "not_tracking_steps": 0, "honest_steps": 0,
            "confident_wrong": 0, "lost_events": 0, "false_lost_events": 0, "recoveries": [], "unrecovered": 0,
            "unrecovered_measured": [], "lost_reasons": {}, "false_lost_reasons": {}, "filter_lost_events": 0,
            "relocalizations": 0}


def reason_kind(reason: str | None) -> str:
    """The filter's lost reason with its numbers as ``N`` (``heading sigma N deg > N deg``), to count by."""
    return re.sub(r"-?\d+(\.\d+)?", "N", str(reason))


def episode_figures(records: list[StepRecord]) -> dict:
    """The figures of one episode; ``records[0]`` is the state at reset (not a step), each later
    record one step. Losses still unrecovered at the last record are counted ``unrecovered``."""
    fig = empty_figures()
    fig["episodes"] = 1
    prev = records[0]
    pending: list[int] = []  # measured steps so far of each loss not yet recovered
    for r in records[1:]:
        tracking = r.status == "tracking"
        inside = r.mahalanobis2 <= CHI2_2_3SIGMA
        fig["steps"] += 1
        fig["tracking_steps"] += tracking
        fig["not_tracking_steps"] += not tracking
        fig["honest_steps"] += (not tracking) or inside
        fig["confident_wrong"] += tracking and r.error_m > CONFIDENT_WRONG_M and not inside
        if r.measured:
            pending = [n + 1 for n in pending]
        if tracking and r.error_m <= RECOVERED_M and pending:
            fig["recoveries"] += pending
            pending = []
        if prev.status == "tracking" and not tracking:
            fig["lost_events"] += 1
            kind = reason_kind(r.reason)
            false = prev.error_m < FALSE_LOST_M and prev.sigma_m < FALSE_LOST_M
            fig["false_lost_events"] += false
            for key in ("lost_reasons", "false_lost_reasons") if false else ("lost_reasons",):
                fig[key][kind] = fig[key].get(kind, 0) + 1
            pending.append(0)
        prev = r
    fig["unrecovered"] = len(pending)
    fig["unrecovered_measured"] = pending
    return fig


def merge_figures(total: dict, part: dict) -> dict:
    """``total`` with ``part`` added in (counts summed, recoveries joined, reasons counted)."""
    for key, value in part.items():
        if isinstance(value, dict):
            for k, n in value.items():
                total[key][k] = total[key].get(k, 0) + n
        else:
            total[key] = total[key] + value
    return total


def summarize(fig: dict) -> dict:
    """Percentages, recovery median and max, and the floors (:data:`FLOORS`) of summed figures."""
    steps = fig["steps"]
    rec = fig["recoveries"]
    out = {**fig,
           "tracking_pct": 100.0 * fig["tracking_steps"] / steps if steps else None,
           "honest_pct": 100.0 * fig["honest_steps"] / steps if steps else None,
           "recovered": len(rec),
           "recovery_median": float(np.median(rec)) if rec else None,
           "recovery_max": int(max(rec)) if rec else None}
    floors = {}
    for name, (key, op, limit, unit) in FLOORS.items():
        floors[name] = verdict(out[key], op, limit, unit)
        if key.startswith("recovery") and fig["lost_events"] == 0:
            floors[name] = {**floors[name], "met": True, "note": "no loss to recover from"}
    out["floors"] = floors
    return out


# ----------------------------------------------------------------------------- driving


def _policy(name: str, env, seed: int):
    """A function of no arguments -> the next action ((2,) float32) of policy ``name``."""
    if name == "uniform":
        env.action_space.seed(seed)
        return env.action_space.sample
    if name == "wall":
        action = np.array(WALL_ACTION, dtype=np.float32)
        return lambda: action.copy()
    rng = np.random.default_rng(seed)
    state = {"a": np.zeros(2)}

    def forward():
        state["a"] = 0.9 * state["a"] + 0.1 * np.array([rng.uniform(0.2, 1.0), rng.uniform(-1.0, 1.0)])
        return state["a"].astype(np.float32)

    return forward


def _record(obs: dict, info: dict, flat_index) -> StepRecord:
    """The step's record from the agent's observation and info (the position covariance read
    back from the ``covariance`` observation, flat or a matrix)."""
    loc = info["localization"]
    cov = np.asarray(obs["covariance"], dtype=float)
    if cov.shape == (3, 3):
        P = cov[:2, :2]
    else:
        full = np.zeros((3, 3))
        for value, (i, j) in zip(cov, flat_index):
            full[i, j] = full[j, i] = value
        P = full[:2, :2]
    e = np.asarray(info["true_pose"][:2], dtype=float) - np.asarray(info["estimated_pose"][:2], dtype=float)
    try:
        m2 = float(e @ np.linalg.solve(P, e))
    except np.linalg.LinAlgError:
        m2 = float("inf")
    seen = info["observations"]
    return StepRecord(loc["status"], float(np.hypot(e[0], e[1])), m2 if m2 >= 0 else float("inf"),
                      float(loc["position_sigma"]), bool(seen["accepted"] or seen["rejected"]), loc["reason"])


def _drive(task: tuple) -> dict:
    """One (env id, policy, seed, steps, wide) drive -> its summed figures (:func:`episode_figures`)."""
    import gymnasium as gym

    import envs  # noqa: F401  (registers the envs)
    from envs.agv_env import COVARIANCE_FLAT_INDEX
    from localizer.filter.wide import WideConfig

    env_id, policy, seed, steps, wide = task
    t0 = time.perf_counter()
    env = gym.make(env_id, **({"filter_config": {"wide": WideConfig()}} if wide else {}))
    obs, info = env.reset(seed=seed)
    act = _policy(policy, env, seed)
    total = empty_figures()
    records = [_record(obs, info, COVARIANCE_FLAT_INDEX)]

    def close_episode(last_info) -> None:
        merge_figures(total, episode_figures(records))
        total["filter_lost_events"] += last_info["localization"]["lost_events"]
        total["relocalizations"] += last_info["localization"]["relocalizations"]

    for k in range(steps):
        obs, _, terminated, truncated, info = env.step(act())
        records.append(_record(obs, info, COVARIANCE_FLAT_INDEX))
        if terminated or truncated:
            close_episode(info)
            records = []
            if k + 1 < steps:
                obs, info = env.reset()
                records = [_record(obs, info, COVARIANCE_FLAT_INDEX)]
    if len(records) > 1:
        close_episode(info)
    env.close()
    return {"env": env_id, "policy": policy, "seed": seed, "wall_s": time.perf_counter() - t0, "figures": total}


# ----------------------------------------------------------------------------- run / report


def run(args) -> dict:
    import multiprocessing as mp

    from tqdm import tqdm

    for flag in ("seeds", "steps", "workers"):
        if getattr(args, flag) < 1:
            raise ValueError(f"--{flag} must be >= 1, got {getattr(args, flag)}")
    env_ids = [e for e in ENVS if e in args.envs]
    policies = [p for p in POLICIES if p in args.policies]
    tasks = [(e, p, s, args.steps, bool(args.wide)) for e in env_ids for p in policies for s in range(args.seeds)]
    totals = {e: {p: empty_figures() for p in policies} for e in env_ids}
    t0 = time.perf_counter()
    bar = tqdm(total=len(tasks) * args.steps, desc="availability", unit=" steps", file=sys.stderr, leave=False)
    try:
        with mp.get_context("spawn").Pool(min(args.workers, len(tasks))) as pool:
            for r in pool.imap_unordered(_drive, tasks):
                merge_figures(totals[r["env"]][r["policy"]], r["figures"])
                bar.update(args.steps)
    finally:
        bar.close()
    results = {e: {p: summarize(f) for p, f in by_policy.items()} for e, by_policy in totals.items()}
    return {"wall_s": time.perf_counter() - t0, "workers": args.workers, "seeds": args.seeds, "steps": args.steps,
            "wide": bool(args.wide), "results": results, "floors": worst_floors(results)}


def worst_floors(results: dict) -> dict:
    """Each floor over every (env, policy): met where it is met in every row; the worst value
    of a row and ``where`` it is (among the failing rows if any), and ``no_value``: the failing
    rows without a value (losses, none recovered)."""
    out = {}
    for name, (_, op, _, _) in FLOORS.items():
        rows = [(f"{e.split('/')[-1]} {p}", g["floors"][name]) for e, by in results.items() for p, g in by.items()]
        failed = [wf for wf in rows if not wf[1]["met"]]
        valued = [wf for wf in (failed or rows) if wf[1]["value"] is not None]
        sign = 1.0 if op == "<=" else -1.0
        where, worst = max(valued, key=lambda wf: sign * wf[1]["value"]) if valued else (failed or rows)[0]
        out[name] = {**worst, "met": not failed, "where": where,
                     "no_value": [w for w, f in failed if f["value"] is None]}
    return out


def _cell(v, spec: str, width: int) -> str:
    return ("-" if v is None else format(v, spec)).rjust(width)


def format_table(result: dict) -> str:
    m = result["machine"]
    lines = [f"agvsim bench availability{' --wide' if result['wide'] else ''}: {plural(result['seeds'], 'seed')} x "
             f"{plural(result['steps'], 'step')} per env and policy, {plural(result['workers'], 'worker')}, "
             f"{result['wall_s']:.0f} s wall",
             f"machine: {m.get('cpu_model', m.get('processor'))}, {m.get('cpu_count')} CPUs, "
             f"Python {m.get('python')}",
             f"{'env':14s} {'policy':8s} {'steps':>6s} {'track':>6s} {'honest':>7s} {'conf-wr':>7s} {'lost':>5s} "
             f"{'false':>5s} {'rec med':>7s} {'rec max':>7s} {'unrec':>5s} {'episodes':>8s}"]
    for env_id, by_policy in result["results"].items():
        for policy, g in by_policy.items():
            bad = [k for k, f in g["floors"].items() if not f["met"]]
            lines.append(f"{env_id.split('/')[-1]:14s} {policy:8s} {g['steps']:6d} "
                         f"{_cell(g['tracking_pct'], '.1f', 5)}% "
                         f"{_cell(g['honest_pct'], '.2f', 6)}% {g['confident_wrong']:7d} {g['lost_events']:5d} "
                         f"{g['false_lost_events']:5d} {_cell(g['recovery_median'], '.1f', 7)} "
                         f"{_cell(g['recovery_max'], 'd', 7)} {g['unrecovered']:5d} {g['episodes']:8d}"
                         f"  {'all floors met' if not bad else 'NOT met: ' + ', '.join(bad)}")
            for label in ("lost", "false_lost"):
                if g[f"{label}_reasons"]:
                    lines.append(f"{'':23s} {label.replace('_', ' ')}: " + "; ".join(
                        f"{n} x {why}" for why, n in sorted(g[f"{label}_reasons"].items(), key=lambda kv: -kv[1])))
            if g["unrecovered_measured"]:
                lines.append(f"{'':23s} unrecovered: measured steps before the episode's end "
                             f"{' '.join(str(n) for n in sorted(g['unrecovered_measured']))}")
    for name, f in result["floors"].items():
        none = f"; none recovered: {', '.join(f['no_value'])}" if f.get("no_value") else ""
        lines.append(floor_line(name, f, ".2f" if f["unit"] == "%" else ".4g", f"worst: {f['where']}{none}"))
    lines.append("track: % of steps tracking; honest: % of steps not tracking or with the true error inside the "
                 "reported 3-sigma region; conf-wr: steps tracking > 0.5 m off, outside it; lost: tracking -> lost "
                 "or relocalizing; false: of those, error and sigma < 10 cm just before; rec: steps with a target "
                 "measured from a loss to tracking within 10 cm; unrec: losses unrecovered at their episode's end")
    return "\n".join(lines)
