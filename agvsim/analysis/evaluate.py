r"""Metrics of closed-loop runs (:class:`agvsim.loop.mission.MissionLog`).

Per run:

* position error e_k = |p̂_k - p_k| (m) each control step: RMSE, 95th percentile, max, final;
  heading error wrapped to [-π, π): RMSE, max.
* dead reckoning: final and max position error, drift per metre (final error / distance).
* NEES_k = ε_kᵀ P_k⁻¹ ε_k with ε = (x̂ - x, ŷ - y, wrap(θ̂ - θ)); for a consistent
  filter NEES ~ χ²(3). ``nees_in_bounds``: share of steps inside the two-sided 95 %
  interval [χ²₃(0.025), χ²₃(0.975)] = [0.216, 9.35]; also the share under the upper bound alone.
* NIS of every fused observation (χ²(3) when consistent): mean, share under χ²₃(0.95).
* frames: share with an accepted observation (of all frames, and of frames with
  observations), observations, rejections, wrong associations (accepted but not
  the target really seen; simulated sources know the truth), re-localizations (recoveries),
  lost events, time lost (s: the simulated time of the steps after which the filter was lost).
* station arrivals: the estimate's position error when the follower passed each
  station (where the vehicle really is against where it believes it is there), and
  the true distance to the station then (the follower passes within its arrival radius).

Over seeds (:func:`summarize`): pooled over every step of every run (RMSE, p95,
max, NEES share), totals of counts, and the per-seed figures.

A long run's log keeps a thinned record and totals over every step and frame
(:mod:`agvsim.loop.record`): its figures come from the totals, the same sums over
the same steps (the 95th percentile from their histogram, within 0.14 %); a run
recorded in full is measured on its arrays.
"""
from __future__ import annotations

import math

import numpy as np

from agvsim.loop.record import NEES_BOUNDS, NIS_95, histogram_percentile, nees, pose_errors, step_totals

__all__ = ["FLOORS", "floors_met", "run_metrics", "summarize"]

#: The drift-correction quality floors (plant_floor, default route, 1 km, typical odometry, 20 seeds).
FLOORS = {
    "position_rmse_m": ("<=", 0.03),
    "position_max_m": ("<=", 0.10),
    "heading_rmse_rad": ("<=", math.radians(0.3)),
    "nees_in_bounds": (">=", 0.90),
    "lost": ("<=", 0),
}


def _errors(log):
    return pose_errors(log.estimate, log.true_pose)


def _nees(log) -> np.ndarray:
    return nees(log.estimate, log.true_pose, log.covariance)


def _step_figures(log) -> dict:
    """The per-step figures: from the arrays when every step is recorded, else from the totals
    over every step (the 95th percentile then from their histogram, within 0.14 %)."""
    e, dh = _errors(log)
    pos = np.hypot(e[:, 0], e[:, 1])
    odo = np.hypot(*(log.odometry_pose[:, :2] - log.true_pose[:, :2]).T)
    t = getattr(log, "step_totals", None)
    if getattr(log, "stride", 1) == 1 or t is None:
        v = _nees(log)
        lo, hi = NEES_BOUNDS
        return {"steps": int(len(log.time)), "position_rmse_m": float(np.sqrt(np.mean(pos ** 2))),
                "position_p95_m": float(np.percentile(pos, 95)), "position_max_m": float(pos.max()),
                "position_final_m": float(pos[-1]), "heading_rmse_rad": float(np.sqrt(np.mean(dh ** 2))),
                "heading_max_rad": float(np.abs(dh).max()), "odometry_final": float(odo[-1]),
                "odometry_max": float(odo.max()), "nees_mean": float(v.mean()),
                "nees_in_bounds": float(np.mean((v >= lo) & (v <= hi))), "nees_below_upper": float(np.mean(v <= hi)),
                "lost_steps_share": float(np.mean(log.lost))}
    n = t.steps
    return {"steps": n, "position_rmse_m": math.sqrt(t.position_sq_sum / n),
            "position_p95_m": histogram_percentile(t.position_histogram, 95, t.position_max),
            "position_max_m": t.position_max, "position_final_m": float(pos[-1]),
            "heading_rmse_rad": math.sqrt(t.heading_sq_sum / n), "heading_max_rad": t.heading_max,
            "odometry_final": float(odo[-1]), "odometry_max": t.odometry_max, "nees_mean": t.nees_sum / n,
            "nees_in_bounds": t.nees_in_bounds / n, "nees_below_upper": t.nees_below_upper / n,
            "lost_steps_share": t.lost_steps / n}


def _frame_figures(log) -> dict:
    """The per-frame and per-arrival figures: from the record when it holds every frame
    (arrival), else from the totals; the median timings from the frames recorded."""
    frames = log.frames
    observe_ms = np.array([f.observe_ms for f in frames]) if frames else np.zeros(0)
    filter_ms = np.array([f.filter_ms for f in frames]) if frames else np.zeros(0)
    out = {"observe_ms_median": float(np.median(observe_ms)) if len(observe_ms) else math.nan,
           "filter_ms_median": float(np.median(filter_ms)) if len(filter_ms) else math.nan}
    t = getattr(log, "event_totals", None)
    if getattr(log, "frame_stride", 1) == 1 or t is None:
        nis = np.concatenate([f.nis for f in frames]) if frames else np.zeros(0)
        with_obs = [f for f in frames if f.observations]
        obs = [o for f in frames for o in f.observations]
        accepted = [o for o in obs if o.status == "accepted"]
        statuses: dict[str, int] = {}
        for o in obs:
            statuses[o.status] = statuses.get(o.status, 0) + 1
        out.update({
            "nis_mean": float(nis.mean()) if len(nis) else math.nan,
            "nis_below_95": float(np.mean(nis <= NIS_95)) if len(nis) else math.nan,
            "frames": len(frames),
            "frames_with_observation": float(len(with_obs) / max(len(frames), 1)),
            "frames_with_accepted_observation": float(np.mean([f.accepted > 0 for f in frames])) if frames else 0.0,
            "frames_with_accepted_of_observed": float(np.mean([f.accepted > 0 for f in with_obs])) if with_obs else 0.0,
            "observations": len(obs), "accepted": len(accepted), "association_statuses": statuses,
            "wrong_associations": len([o for o in accepted if o.truth_id is not None and o.truth_id != o.target_id]),
            "false_detections_accepted": len([o for o in accepted if o.truth_id is None])})
    else:
        out.update({
            "nis_mean": t.nis_sum / t.nis_count if t.nis_count else math.nan,
            "nis_below_95": t.nis_below_95 / t.nis_count if t.nis_count else math.nan,
            "frames": t.frames,
            "frames_with_observation": t.with_observation / max(t.frames, 1),
            "frames_with_accepted_observation": t.with_accepted / t.frames if t.frames else 0.0,
            "frames_with_accepted_of_observed": (t.observed_with_accepted / t.with_observation
                                                 if t.with_observation else 0.0),
            "observations": t.observations, "accepted": t.accepted, "association_statuses": dict(t.statuses),
            "wrong_associations": t.wrong, "false_detections_accepted": t.false_accepted})
    # the estimate's position error when the follower passed each station: where the vehicle
    # really stands relative to where it believes it stands at the station
    if getattr(log, "arrival_stride", 1) == 1 or t is None:
        arrival_err = np.array([a[3] for a in log.arrivals]) if log.arrivals else np.zeros(0)
        arrival_pass = np.array([a[2] for a in log.arrivals]) if log.arrivals else np.zeros(0)
        out.update({"stations_reached": len(log.arrivals),
                    "arrival_error_mean_m": float(arrival_err.mean()) if len(arrival_err) else math.nan,
                    "arrival_error_max_m": float(arrival_err.max()) if len(arrival_err) else math.nan,
                    "arrival_passing_distance_mean_m": float(arrival_pass.mean()) if len(arrival_pass) else math.nan})
    else:
        out.update({"stations_reached": t.arrivals, "arrival_error_mean_m": t.arrival_error_sum / t.arrivals,
                    "arrival_error_max_m": t.arrival_error_max,
                    "arrival_passing_distance_mean_m": t.arrival_passing_sum / t.arrivals})
    return out


def run_metrics(log) -> dict:
    """Metrics of one :class:`~agvsim.loop.mission.MissionLog` (SI units; see the module
    docstring), over every step and frame (also of a thinned record: :mod:`agvsim.loop.record`)."""
    if len(log.time) == 0:
        raise ValueError("run_metrics: the run has no steps")
    s = _step_figures(log)
    f = _frame_figures(log)
    distance = float(log.distance[-1])
    return {
        "completed": bool(log.completed),
        "distance_m": distance,
        "simulated_time_s": float(log.time[-1]),
        "steps": s["steps"],
        **{k: s[k] for k in ("position_rmse_m", "position_p95_m", "position_max_m", "position_final_m",
                             "heading_rmse_rad", "heading_max_rad")},
        "dead_reckoning_final_error_m": s["odometry_final"],
        "dead_reckoning_max_error_m": s["odometry_max"],
        "dead_reckoning_drift_per_m": float(s["odometry_final"] / max(distance, 1e-9)),
        **{k: s[k] for k in ("nees_mean", "nees_in_bounds", "nees_below_upper")},
        **{k: f[k] for k in ("nis_mean", "nis_below_95", "frames", "frames_with_observation",
                             "frames_with_accepted_observation", "frames_with_accepted_of_observed",
                             "observations", "accepted")},
        "rejections": int(log.rejections),
        **{k: f[k] for k in ("association_statuses", "wrong_associations", "false_detections_accepted")},
        "relocalizations": int(log.relocalizations),
        "lost": int(log.lost_events),
        "lost_steps_share": s["lost_steps_share"],
        "time_lost_s": log.time_lost(),
        **{k: f[k] for k in ("stations_reached", "arrival_error_mean_m", "arrival_error_max_m",
                             "arrival_passing_distance_mean_m")},
        "collisions": int(log.collisions),
        **{k: f[k] for k in ("observe_ms_median", "filter_ms_median")},
        "wall_time_s": float(log.timings.get("total", math.nan)),
    }


def pooled(logs) -> dict:
    """Figures pooled over every step of every run: from the arrays when every run's are all
    there, else from the runs' totals (``step_totals``; computed from the arrays of a run
    without them)."""
    logs = list(logs)
    if any(getattr(g, "stride", 1) != 1 for g in logs):
        return _pooled_totals([g.step_totals if getattr(g, "step_totals", None) is not None else step_totals(g)
                               for g in logs])
    pos = np.concatenate([np.hypot(*_errors(g)[0].T) for g in logs])
    dh = np.concatenate([_errors(g)[1] for g in logs])
    nees_all = np.concatenate([_nees(g) for g in logs])
    lo, hi = NEES_BOUNDS
    return {
        "position_rmse_m": float(np.sqrt(np.mean(pos ** 2))),
        "position_p95_m": float(np.percentile(pos, 95)),
        "position_max_m": float(pos.max()),
        "heading_rmse_rad": float(np.sqrt(np.mean(dh ** 2))),
        "nees_in_bounds": float(np.mean((nees_all >= lo) & (nees_all <= hi))),
        "nees_below_upper": float(np.mean(nees_all <= hi)),
        "nees_mean": float(nees_all.mean()),
    }


def _pooled_totals(totals) -> dict:
    n = sum(t.steps for t in totals)
    high = float(np.max([t.position_max for t in totals]))
    return {
        "position_rmse_m": math.sqrt(sum(t.position_sq_sum for t in totals) / n),
        "position_p95_m": histogram_percentile(sum(t.position_histogram for t in totals), 95, high),
        "position_max_m": high,
        "heading_rmse_rad": math.sqrt(sum(t.heading_sq_sum for t in totals) / n),
        "nees_in_bounds": sum(t.nees_in_bounds for t in totals) / n,
        "nees_below_upper": sum(t.nees_below_upper for t in totals) / n,
        "nees_mean": sum(t.nees_sum for t in totals) / n,
    }


def summarize(per_seed: list[dict], pooled_figures: dict | None = None) -> dict:
    """Combine per-seed :func:`run_metrics` dicts (and optional :func:`pooled` figures).

    Pooled figures win where given; otherwise RMSEs are combined by step count, maxima
    by max, shares by step/frame-weighted mean, counts summed.
    """
    if not per_seed:
        raise ValueError("summarize: no runs")
    steps = np.array([m["steps"] for m in per_seed], dtype=float)
    frames = np.array([max(m["frames"], 0) for m in per_seed], dtype=float)

    def wmean(key, w):
        vals = np.array([m[key] for m in per_seed], dtype=float)
        ok = np.isfinite(vals)
        return float(np.sum(vals[ok] * w[ok]) / max(np.sum(w[ok]), 1e-12)) if ok.any() else math.nan

    out = {
        "runs": len(per_seed),
        "completed": int(sum(m["completed"] for m in per_seed)),
        "distance_m_mean": float(np.mean([m["distance_m"] for m in per_seed])),
        "position_rmse_m": float(np.sqrt(wmean_sq(per_seed, "position_rmse_m", steps))),
        "position_p95_m": float(np.max([m["position_p95_m"] for m in per_seed])),
        "position_max_m": float(np.max([m["position_max_m"] for m in per_seed])),
        "heading_rmse_rad": float(np.sqrt(wmean_sq(per_seed, "heading_rmse_rad", steps))),
        "heading_max_rad": float(np.max([m["heading_max_rad"] for m in per_seed])),
        "nees_in_bounds": wmean("nees_in_bounds", steps),
        "nees_below_upper": wmean("nees_below_upper", steps),
        "nees_mean": wmean("nees_mean", steps),
        "nis_mean": wmean("nis_mean", np.array([m["accepted"] for m in per_seed], dtype=float)),
        "dead_reckoning_final_error_m": float(np.mean([m["dead_reckoning_final_error_m"] for m in per_seed])),
        "dead_reckoning_final_error_max_m": float(np.max([m["dead_reckoning_final_error_m"] for m in per_seed])),
        "dead_reckoning_drift_per_m": float(np.mean([m["dead_reckoning_drift_per_m"] for m in per_seed])),
        "frames_with_accepted_observation": wmean("frames_with_accepted_observation", frames),
        "frames_with_observation": wmean("frames_with_observation", frames),
        "observation_count": int(sum(m["observations"] for m in per_seed)),
        "accepted": int(sum(m["accepted"] for m in per_seed)),
        "rejections": int(sum(m["rejections"] for m in per_seed)),
        "wrong_associations": int(sum(m["wrong_associations"] for m in per_seed)),
        "false_detections_accepted": int(sum(m["false_detections_accepted"] for m in per_seed)),
        "relocalizations": int(sum(m["relocalizations"] for m in per_seed)),
        "lost": int(sum(m["lost"] for m in per_seed)),
        "time_lost_s": float(sum(m["time_lost_s"] for m in per_seed)),
        "collisions": int(sum(m["collisions"] for m in per_seed)),
        "arrival_error_mean_m": wmean("arrival_error_mean_m", np.array([m["stations_reached"] for m in per_seed], float)),
        "arrival_error_max_m": _nanmax([m["arrival_error_max_m"] for m in per_seed]),
        "observe_ms_median": _nanmedian([m["observe_ms_median"] for m in per_seed]),
        "filter_ms_median": _nanmedian([m["filter_ms_median"] for m in per_seed]),
    }
    if pooled_figures:
        out.update(pooled_figures)
        out["position_p95_m"] = pooled_figures.get("position_p95_m", out["position_p95_m"])
    return out


def _nanmax(values) -> float:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(v.max()) if len(v) else math.nan


def _nanmedian(values) -> float:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.median(v)) if len(v) else math.nan


def wmean_sq(per_seed, key, w):
    vals = np.array([m[key] for m in per_seed], dtype=float) ** 2
    return float(np.sum(vals * w) / np.sum(w))


def floors_met(summary: dict) -> dict:
    """{floor key: (value, op, limit, met)} for the drift floors (:data:`FLOORS`)."""
    out = {}
    for key, (op, limit) in FLOORS.items():
        v = summary.get(key, math.nan)
        met = (v <= limit) if op == "<=" else (v >= limit)
        out[key] = {"value": v, "op": op, "limit": limit, "met": bool(met)}
    return out
