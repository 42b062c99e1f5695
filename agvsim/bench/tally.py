"""The figures of a localizer benchmark over frames with a known target pose, one condition at a
time (``agvsim bench envelope`` and ``agvsim bench pbr``): found, false detections, errors of d,
beta and alpha, their share within 3 sigma of the reported covariance, and ms per call, held to
the floors of :data:`agvsim.bench.envelope_conditions.FLOORS`.

A detection is the target when its bearing is within ``GATE_BETA`` of the truth and its distance
within ``GATE_DISTANCE`` of it; every other detection on the frame is false.
"""
from __future__ import annotations

import math

import numpy as np

from agvsim.bench.envelope_conditions import CHI2_3D_3SIGMA, FLOORS, GATE_BETA, GATE_DISTANCE, SPEED_SIZE
from agvsim.bench.floors import verdict

__all__ = ["KEEP_FRAMES", "Tally", "condition_floors", "settings_dict", "summary_floors", "thesis_fy"]

#: frame indices kept per condition for the report (missed, falsely detected, worst)
KEEP_FRAMES = 10


def settings_dict(settings) -> dict:
    """A frozen dataclass's fields as a JSON-ready dict."""
    return {k: getattr(settings, k) for k in settings.__dataclass_fields__}


def _pct(x) -> float | None:
    return None if x is None else 100.0 * x


class Tally:
    """The figures of one condition, frame by frame: ``name`` and ``help`` (its report line),
    ``size`` (width, height) px of its frames (the speed floors hold at one size), ``settings``
    (JSON-ready, reported) and ``rows_min``: the alpha floors count targets whose shorter bar
    is at least this tall (rows)."""

    def __init__(self, name: str, help: str, size: tuple[int, int], settings: dict, rows_min: float):
        self.name, self.help, self.size, self.settings, self.rows_min = name, help, tuple(size), settings, rows_min
        self.frames = self.found = self.false = 0
        self.missed, self.false_frames = [], []
        self.err = []  # (d %, beta deg, alpha deg, rows, z_d, z_beta, z_alpha, mahalanobis^2, frame)
        self.ms = []
        self.peer_ms: dict[str, list] = {}  # peer -> ms per frame (``--peers``)
        self.peer_found: dict[str, int] = {}  # peer -> frames where it found a marker

    def add_peer(self, name: str, found: bool, seconds: float) -> None:
        """A peer's call on the frame just added: whether it found its marker, its ``seconds``."""
        self.peer_ms.setdefault(name, []).append(1000.0 * seconds)
        self.peer_found[name] = self.peer_found.get(name, 0) + bool(found)

    def add(self, index: int, pose, obs, seconds: float, rows: float) -> None:
        """Frame ``index``: the truth ``pose``, the detections ``obs``, the call's ``seconds`` and
        the shorter bar's height ``rows`` (px)."""
        self.frames += 1
        self.ms.append(1000.0 * seconds)
        near = [o for o in obs if abs(o.beta - pose.beta) < GATE_BETA
                and abs(o.distance / pose.distance - 1.0) < GATE_DISTANCE]
        best = min(near, key=lambda o: abs(o.beta - pose.beta)) if near else None
        n_false = len(obs) - (best is not None)
        self.false += n_false
        if n_false and len(self.false_frames) < KEEP_FRAMES:
            self.false_frames.append(index)
        if best is None:
            if len(self.missed) < KEEP_FRAMES:
                self.missed.append(index)
            return
        self.found += 1
        e = np.array([best.distance - pose.distance, best.beta - pose.beta,
                      math.remainder(best.alpha - pose.alpha, 2 * math.pi)])
        c = np.asarray(best.covariance, float)
        sd = np.sqrt(np.clip(np.diag(c), 1e-300, None))
        try:
            m2 = float(e @ np.linalg.solve(c, e))
        except np.linalg.LinAlgError:
            m2 = math.inf
        if not math.isfinite(m2) or m2 < 0:
            m2 = math.inf
        self.err.append((100.0 * abs(e[0]) / pose.distance, math.degrees(abs(e[1])), math.degrees(abs(e[2])),
                         rows, *(np.abs(e) / sd).tolist(), m2, index))

    def report(self) -> dict:
        out = {"name": self.name, "help": self.help, "size": f"{self.size[0]}x{self.size[1]}",
               "settings": self.settings,
               "frames": self.frames, "found": self.found,
               "detection_pct": _pct(self.found / self.frames) if self.frames else None,
               "missed_frames": self.missed, "false_detections": self.false, "false_frames": self.false_frames,
               "alpha_min_rows": self.rows_min}
        a = np.array([x[:8] for x in self.err], float).reshape(-1, 8)
        big = a[:, 3] >= self.rows_min
        have = a.shape[0] > 0
        out.update({
            "d_error_pct_mean": float(a[:, 0].mean()) if have else None,
            "d_error_pct_max": float(a[:, 0].max()) if have else None,
            "beta_error_deg_mean": float(a[:, 1].mean()) if have else None,
            "beta_error_deg_max": float(a[:, 1].max()) if have else None,
            "alpha_frames": int(big.sum()),
            "alpha_error_deg_mean": float(a[big, 2].mean()) if big.any() else None,
            "alpha_error_deg_max": float(a[big, 2].max()) if big.any() else None,
            "alpha_error_deg_max_all_sizes": float(a[:, 2].max()) if have else None,
            "within_3sigma_pct": {k: (_pct(float((a[:, i] <= 3.0).mean())) if have else None)
                                  for k, i in (("d", 4), ("beta", 5), ("alpha", 6))},
            "worst_error_in_sigmas": {k: (float(a[:, i].max()) if have else None)
                                      for k, i in (("d", 4), ("beta", 5), ("alpha", 6))},
            "worst_d_frame": int(self.err[int(np.argmax(a[:, 0]))][8]) if have else None,
            "ms_median": float(np.median(self.ms)) if self.ms else None,
            "ms_p99": float(np.percentile(self.ms, 99)) if self.ms else None,
            "ms_max": float(np.max(self.ms)) if self.ms else None,
        })
        ours = out["ms_median"]
        out["peers"] = {k: {"ms_median": float(np.median(v)), "found": self.peer_found[k],
                            "times_slower": float(np.median(v)) / ours if ours else None}
                        for k, v in self.peer_ms.items()}
        out["within_3sigma_pct"]["mahalanobis_3d"] = _pct(float((a[:, 7] <= CHI2_3D_3SIGMA).mean())) if have else None
        w = [v for v in out["within_3sigma_pct"].values() if v is not None]
        out["within_3sigma_pct_worst"] = min(w) if len(w) == 4 else None
        out["floors"] = condition_floors(out, self.size)
        return out


def thesis_fy() -> float:
    """fy (px) of the thesis camera with its 16 mm lens (the alpha floors' rows are counted at it)."""
    from localizer import Camera

    return Camera.thesis(16.0).fy


def condition_floors(r: dict, size: tuple[int, int]) -> dict:
    """The floors (:data:`~agvsim.bench.envelope_conditions.FLOORS`) of one condition's report ``r``."""
    values = {"detection_pct": r["detection_pct"], "d_error_pct_mean": r["d_error_pct_mean"],
              "d_error_pct_max": r["d_error_pct_max"], "alpha_error_deg_mean": r["alpha_error_deg_mean"],
              "alpha_error_deg_max": r["alpha_error_deg_max"], "within_3sigma_pct": r["within_3sigma_pct_worst"],
              "false_detections": r["false_detections"], "ms_median": r["ms_median"], "ms_p99": r["ms_p99"],
              "ms_median_2448": r["ms_median"],
              "peer_ratio": min((p["times_slower"] for p in r["peers"].values()), default=None)}
    out = {}
    for key, (op, limit, unit, _) in FLOORS.items():
        if key in SPEED_SIZE and SPEED_SIZE[key] != size:
            continue
        if key == "peer_ratio" and not r["peers"]:
            continue  # peers not run
        if key.startswith("alpha") and r["found"] and not r["alpha_frames"]:
            continue  # targets found, none of them tall enough for the alpha floors
        out[key] = verdict(values[key], op, limit, unit)
    return out


def summary_floors(conditions: list[dict], target_free: dict) -> dict:
    """Each floor over every condition it applies to (their reports): the worst value, met only
    if met in every one, and the conditions that miss it (name -> value); and the false
    detections on ``target_free`` frames (size -> ``{"false_detections": n, ...}``)."""
    out = {}
    for key, (op, limit, unit, what) in FLOORS.items():
        rows = [(r["name"], r["floors"][key]) for r in conditions if key in r["floors"]]
        if not rows:
            continue
        vals = [f["value"] for _, f in rows if f["value"] is not None]
        worst = (min(vals) if op == ">=" else max(vals)) if vals else None
        v = verdict(worst, op, limit, unit)  # the worst value there is; a condition without one fails
        v["met"] = v["met"] and len(vals) == len(rows)
        v["failing"] = {name: f["value"] for name, f in rows if not f["met"]}
        v["what"] = what
        out[key] = v
    free = target_free
    if free:
        total = sum(f["false_detections"] for f in free.values())
        v = verdict(total, "<=", 0.0)
        v["failing"] = {size: f["false_detections"] for size, f in free.items() if f["false_detections"]}
        v["what"] = "false detections on target-free frames"
        out["target_free_false_detections"] = v
    return out
