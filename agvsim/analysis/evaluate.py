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
"""
from __future__ import annotations

import math

import numpy as np
from scipy.stats import chi2

from localizer.numeric import wrap_angle

__all__ = ["FLOORS", "floors_met", "run_metrics", "summarize"]

NEES_BOUNDS = (float(chi2.ppf(0.025, 3)), float(chi2.ppf(0.975, 3)))
NIS_95 = float(chi2.ppf(0.95, 3))

#: The drift-correction quality floors (plant_floor, default route, 1 km, typical odometry, 20 seeds).
FLOORS = {
    "position_rmse_m": ("<=", 0.03),
    "position_max_m": ("<=", 0.10),
    "heading_rmse_rad": ("<=", math.radians(0.3)),
    "nees_in_bounds": (">=", 0.90),
    "lost": ("<=", 0),
}


def _errors(log):
    e = log.estimate[:, :2] - log.true_pose[:, :2]
    dh = wrap_angle(log.estimate[:, 2] - log.true_pose[:, 2])
    return e, dh


def _nees(log) -> np.ndarray:
    e, dh = _errors(log)
    eps = np.concatenate([e, dh[:, None]], axis=1)
    return np.einsum("ni,nij,nj->n", eps, np.linalg.inv(log.covariance), eps)


def run_metrics(log) -> dict:
    """Metrics of one :class:`~agvsim.loop.mission.MissionLog` (SI units; see the module docstring)."""
    if len(log.time) == 0:
        raise ValueError("run_metrics: the run has no steps")
    e, dh = _errors(log)
    pos = np.hypot(e[:, 0], e[:, 1])
    odo = np.hypot(*(log.odometry_pose[:, :2] - log.true_pose[:, :2]).T)
    nees = _nees(log)
    lo, hi = NEES_BOUNDS
    nis = np.concatenate([f.nis for f in log.frames]) if log.frames else np.zeros(0)
    frames = log.frames
    with_obs = [f for f in frames if f.observations]
    obs = [o for f in frames for o in f.observations]
    accepted = [o for o in obs if o.status == "accepted"]
    wrong = [o for o in accepted if o.truth_id is not None and o.truth_id != o.target_id]
    false_accepted = [o for o in accepted if o.truth_id is None]
    # the estimate's position error when the follower passed each station: where the vehicle
    # really stands relative to where it believes it stands at the station
    arrival_err = np.array([a[3] for a in log.arrivals]) if log.arrivals else np.zeros(0)
    arrival_pass = np.array([a[2] for a in log.arrivals]) if log.arrivals else np.zeros(0)
    distance = float(log.distance[-1])
    statuses: dict[str, int] = {}
    for o in obs:
        statuses[o.status] = statuses.get(o.status, 0) + 1
    observe_ms = np.array([f.observe_ms for f in frames]) if frames else np.zeros(0)
    filter_ms = np.array([f.filter_ms for f in frames]) if frames else np.zeros(0)
    return {
        "completed": bool(log.completed),
        "distance_m": distance,
        "simulated_time_s": float(log.time[-1]),
        "steps": int(len(log.time)),
        "position_rmse_m": float(np.sqrt(np.mean(pos ** 2))),
        "position_p95_m": float(np.percentile(pos, 95)),
        "position_max_m": float(pos.max()),
        "position_final_m": float(pos[-1]),
        "heading_rmse_rad": float(np.sqrt(np.mean(dh ** 2))),
        "heading_max_rad": float(np.abs(dh).max()),
        "dead_reckoning_final_error_m": float(odo[-1]),
        "dead_reckoning_max_error_m": float(odo.max()),
        "dead_reckoning_drift_per_m": float(odo[-1] / max(distance, 1e-9)),
        "nees_mean": float(nees.mean()),
        "nees_in_bounds": float(np.mean((nees >= lo) & (nees <= hi))),
        "nees_below_upper": float(np.mean(nees <= hi)),
        "nis_mean": float(nis.mean()) if len(nis) else math.nan,
        "nis_below_95": float(np.mean(nis <= NIS_95)) if len(nis) else math.nan,
        "frames": len(frames),
        "frames_with_observation": float(len(with_obs) / max(len(frames), 1)),
        "frames_with_accepted_observation": float(np.mean([f.accepted > 0 for f in frames])) if frames else 0.0,
        "frames_with_accepted_of_observed": float(np.mean([f.accepted > 0 for f in with_obs])) if with_obs else 0.0,
        "observations": len(obs),
        "accepted": len(accepted),
        "rejections": int(log.rejections),
        "association_statuses": statuses,
        "wrong_associations": len(wrong),
        "false_detections_accepted": len(false_accepted),
        "relocalizations": int(log.relocalizations),
        "lost": int(log.lost_events),
        "lost_steps_share": float(np.mean(log.lost)),
        "time_lost_s": log.time_lost(),
        "stations_reached": len(log.arrivals),
        "arrival_error_mean_m": float(arrival_err.mean()) if len(arrival_err) else math.nan,
        "arrival_error_max_m": float(arrival_err.max()) if len(arrival_err) else math.nan,
        "arrival_passing_distance_mean_m": float(arrival_pass.mean()) if len(arrival_pass) else math.nan,
        "collisions": int(log.collisions),
        "observe_ms_median": float(np.median(observe_ms)) if len(observe_ms) else math.nan,
        "filter_ms_median": float(np.median(filter_ms)) if len(filter_ms) else math.nan,
        "wall_time_s": float(log.timings.get("total", math.nan)),
    }


def pooled(logs) -> dict:
    """Figures pooled over every step of every run."""
    pos = np.concatenate([np.hypot(*_errors(g)[0].T) for g in logs])
    dh = np.concatenate([_errors(g)[1] for g in logs])
    nees = np.concatenate([_nees(g) for g in logs])
    lo, hi = NEES_BOUNDS
    return {
        "position_rmse_m": float(np.sqrt(np.mean(pos ** 2))),
        "position_p95_m": float(np.percentile(pos, 95)),
        "position_max_m": float(pos.max()),
        "heading_rmse_rad": float(np.sqrt(np.mean(dh ** 2))),
        "nees_in_bounds": float(np.mean((nees >= lo) & (nees <= hi))),
        "nees_below_upper": float(np.mean(nees <= hi)),
        "nees_mean": float(nees.mean()),
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
