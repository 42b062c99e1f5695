"""Figures, floors and the table of ``agvsim bench localization-integrity``
(:mod:`agvsim.bench.localization_integrity`) from its trial records."""
from __future__ import annotations

import numpy as np

from agvsim.commands._output import plural

__all__ = ["format_table", "summarize"]

#: the floors (BENCHMARKS.md)
FLOOR_HONEST = 0.99  # share of steps
FLOOR_TRACKING_P95 = 0.10  # m
FLOOR_DETECT_S = 5.0  # s, first refused detection -> lost
FLOOR_RECOVER_S = 15.0  # s, two distinct targets seen -> error <= 10 cm while tracking
FLOOR_RECOVERED_SHARE = 0.95  # of trials


def summarize(results: list[dict]) -> dict:
    """Figures and floors per experiment (and per map for ``unknown``)."""
    out: dict = {}
    groups: dict[str, list[dict]] = {}
    for r in results:
        key = r["experiment"] if r["experiment"] != "unknown" else f"unknown:{r['map']}"
        groups.setdefault(key, []).append(r)
    for key, rs in groups.items():
        steps = sum(r["steps"] for r in rs)
        errs = np.concatenate([np.asarray(r["tracking_errors"], dtype=float) for r in rs])
        lost_ms = np.concatenate([np.asarray(r["lost_ms"], dtype=float) for r in rs])
        g = {"trials": len(rs), "steps": steps, "honest_share": sum(r["honest"] for r in rs) / max(steps, 1),
             "lost_share": sum(r["lost_steps"] for r in rs) / max(steps, 1),
             "tracking_p95_m": float(np.percentile(errs, 95)) if len(errs) else None,
             "relocalizations": sum(r["relocalizations"] for r in rs),
             "wrong_relocalizations": sum(len(r["wrong"]) for r in rs),
             "lost_frame_ms_median": float(np.median(lost_ms)) if len(lost_ms) else None,
             "lost_frame_ms_p95": float(np.percentile(lost_ms, 95)) if len(lost_ms) else None}
        floors = {"no_wrong_relocalization": g["wrong_relocalizations"] == 0}
        if key in ("random", "wall"):  # after a kidnap the filter may be wrong until it notices (detect_s)
            floors["honest_share"] = g["honest_share"] >= FLOOR_HONEST
        if key == "random":
            floors["tracking_p95"] = g["tracking_p95_m"] is not None and g["tracking_p95_m"] <= FLOOR_TRACKING_P95
        else:
            det = [r["detect_s"] for r in rs if r["refused"]]
            # over the trials in which two distinct targets came into view after the event (the
            # oracle driver does not always bring them: those are counted in saw_two_share)
            rec_ok = [r["recover_s"] is not None and r["recover_s"] <= FLOOR_RECOVER_S for r in rs if r["saw_two"]]
            g["detect_s_max"] = max((d for d in det if d is not None), default=None)
            g["detect_within_5s_share"] = (sum(d is not None and d <= FLOOR_DETECT_S for d in det) / len(det)
                                           if det else None)
            g["never_declared"] = sum(1 for r in rs if r["refused"] and not r["declared_lost"])
            g["recovered_share"] = sum(rec_ok) / len(rec_ok) if rec_ok else None
            g["recover_s_median"] = (float(np.median([r["recover_s"] for r in rs if r["recover_s"] is not None]))
                                     if any(r["recover_s"] is not None for r in rs) else None)
            g["saw_two_share"] = sum(r["saw_two"] for r in rs) / len(rs)
            if not key.startswith("unknown"):  # in >= 95 % of trials, as the recovery
                floors["detect_within_5s"] = (g["never_declared"] == 0 and g["detect_within_5s_share"] is not None
                                              and g["detect_within_5s_share"] >= FLOOR_RECOVERED_SHARE)
            floors["recovered_95"] = g["recovered_share"] is not None and g["recovered_share"] >= FLOOR_RECOVERED_SHARE
        g["floors"] = floors
        out[key] = g
    return out


def _fmt(v, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def _pct(v, width: int) -> str:
    return ("-" if v is None else f"{100 * v:.0f}").rjust(width) + "%"


def format_table(res: dict) -> str:
    m = res["machine"]
    lines = [f"agvsim bench localization-integrity: {plural(res['workers'], 'worker')}, {res['wall_s']:.0f} s wall",
             f"machine: {m.get('cpu_model', m.get('processor'))}, {m.get('cpu_count')} CPUs",
             f"{'experiment':18s} {'trials':>6s} {'steps':>7s} {'honest':>8s} {'lost':>6s} {'p95 trk':>8s} "
             f"{'reloc':>5s} {'wrong':>5s} {'det<=5s':>7s} {'det max':>7s} {'recovered':>9s} {'saw 2':>5s} {'rec med':>7s} "
             f"{'lost ms':>7s} {'p95':>5s}"]
    for key, g in res["summary"].items():
        lines.append(f"{key:18s} {g['trials']:6d} {g['steps']:7d} {100 * g['honest_share']:7.2f}% "
                     f"{100 * g['lost_share']:5.1f}% {_fmt(g['tracking_p95_m'] and 100 * g['tracking_p95_m'], '7.1f')}c "
                     f"{g['relocalizations']:5d} {g['wrong_relocalizations']:5d} "
                     f"{_pct(g.get('detect_within_5s_share'), 6)} {_fmt(g.get('detect_s_max'), '6.1f')}s "
                     f"{_pct(g.get('recovered_share'), 8)} {_pct(g.get('saw_two_share'), 4)} "
                     f"{_fmt(g.get('recover_s_median'), '6.1f')}s {_fmt(g['lost_frame_ms_median'], '7.1f')} "
                     f"{_fmt(g['lost_frame_ms_p95'], '5.0f')}")
        bad = [k for k, ok in g["floors"].items() if not ok]
        lines.append(f"{'':18s} floors: {'all met' if not bad else 'NOT met: ' + ', '.join(bad)}")
    lines.append("honest: steps with the true error inside the reported 3-sigma region, or the filter "
                 "reporting itself lost; p95 trk: error while tracking; detect: first refused detection -> "
                 "lost (floor 5 s in >= 95 % of trials); recovered: error <= 10 cm while tracking within 15 s "
                 "of two distinct targets seen, over the trials that saw two (saw 2: their share); lost ms: filter ms per frame while lost (median, p95)")
    return "\n".join(lines)
