"""``agvsim reproduce thesis``: the 18 test points of the thesis's Tables 5.1-5.4, side by side."""
from __future__ import annotations

import argparse

from agvsim.commands._output import add_json_flag, emit_json

#: (lens mm, measured d mm, computed d mm, measured alpha deg, computed alpha deg), Tables 5.1 and 5.2
THESIS_POINTS: tuple[tuple[float, float, float, float, float], ...] = (
    (16, 1410, 1362, 0.0, 4.4), (16, 1990, 1905, 43.0, 45.8), (16, 2030, 1975, 5.0, 13.0),
    (16, 3240, 3164, -23.0, -20.0), (16, 3710, 3584, -50.0, -46.4), (16, 4060, 3913, 51.0, 48.1),
    (16, 4380, 4109, 42.0, 40.0), (16, 4400, 4126, 30.0, 28.3), (16, 5720, 5341, 70.0, 71.8),
    (50, 4910, 4881, 37.0, 38.8), (50, 5910, 5714, -40.0, -37.6), (50, 5940, 5929, 10.0, 14.5),
    (50, 6330, 6103, 65.0, 61.7), (50, 6370, 6281, 46.0, 43.0), (50, 6540, 6318, 57.0, 53.1),
    (50, 7330, 7410, 60.0, 57.3), (50, 8150, 8074, -20.0, -17.2), (50, 9520, 9334, 0.0, 6.8),
)


def register(sub) -> None:
    p = sub.add_parser("reproduce", help="reproduce a published result",
                       description="Reproduce a published result on synthetic frames.")
    p.add_argument("what", choices=("thesis",), help="thesis: Tables 5.1-5.4 (18 test points)")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument("--noise", type=float, default=1.0, help="sensor noise sigma, grey levels (default 1)")
    p.add_argument("--blur", type=float, default=0.5, help="optical blur sigma, pixels (default 0.5)")
    p.add_argument("--column", type=float, default=40.0,
                   help="target centre this many pixels right of the principal point (default 40)")
    add_json_flag(p)
    p.set_defaults(func=run)


def reproduce_thesis(seed: int = 0, noise: float = 1.0, blur: float = 0.5, column: float = 40.0) -> dict:
    import math

    import numpy as np

    from localizer import Camera, TargetSpec, detect_targets
    from localizer.synthetic import pose_at_column, render_frame

    rng = np.random.default_rng(seed)
    target = TargetSpec()
    rows = []
    for i, (lens, d_m, d_c, a_m, a_c) in enumerate(THESIS_POINTS):
        cam = Camera.thesis(lens)
        pose = pose_at_column(cam, d_m / 1000.0, math.radians(a_m), cam.cx + column)
        img = render_frame(cam, pose, target, "positive", "normal", blur, noise, 0.55, rng)
        row = {"point": i + 1, "lens_mm": lens, "d_measured_mm": d_m, "alpha_measured_deg": a_m,
               "thesis": {"d_mm": d_c, "d_error_pct": 100.0 * (d_m - d_c) / d_m,
                          "alpha_deg": a_c, "alpha_error_deg": a_m - a_c}}
        for method in ("thesis", "exact"):
            obs = detect_targets(img, cam, target, method=method)
            if obs:
                o = obs[0]
                row[method + "_method"] = {
                    "d_mm": 1000.0 * o.distance, "d_error_pct": 100.0 * (d_m / 1000.0 - o.distance) / (d_m / 1000.0),
                    "alpha_deg": math.degrees(o.alpha), "alpha_error_deg": a_m - math.degrees(o.alpha),
                    "sigma_d_mm": 1000.0 * float(o.sigma[0]), "sigma_alpha_deg": math.degrees(float(o.sigma[2]))}
            else:
                row[method + "_method"] = None
        rows.append(row)
    means = {}
    for key in ("thesis", "thesis_method", "exact_method"):
        for lens in (16, 50):
            sel = [r[key] for r in rows if r["lens_mm"] == lens and r[key] is not None]
            means[f"{key}_{lens}mm"] = {
                "n": len(sel),
                "mean_abs_d_error_pct": float(np.mean([abs(s["d_error_pct"]) for s in sel])) if sel else None,
                "mean_abs_alpha_error_deg": float(np.mean([abs(s["alpha_error_deg"]) for s in sel])) if sel else None}
    return {"conditions": {"lighting": "normal", "blur_px": blur, "noise_grey": noise, "seed": seed,
                           "column_offset_px": column, "polarity": "positive"},
            "points": rows, "means": means}


def format_table(res: dict) -> str:
    def cell(r, key):
        v = r[key]
        if v is None:
            return f"{'not found':>27}"
        return f"{v['d_mm']:6.0f} {v['d_error_pct']:5.1f}% {v['alpha_deg']:6.1f} {v['alpha_error_deg']:5.1f}"

    lines = ["Thesis Tables 5.1-5.4 on synthetic frames (errors = measured - computed)",
             f"{'#':>2} {'lens':>4} {'d meas':>6} {'a meas':>6} | {'thesis (published)':^27} | "
             f"{'ours, method=thesis':^27} | {'ours, method=exact':^27}",
             f"{'':>2} {'mm':>4} {'mm':>6} {'deg':>6} | " + " | ".join([f"{'d mm':>6} {'err':>6} {'a deg':>6} {'err':>5}"] * 3)]
    for r in res["points"]:
        lines.append(f"{r['point']:>2} {r['lens_mm']:>4} {r['d_measured_mm']:6.0f} {r['alpha_measured_deg']:6.1f} | "
                     f"{cell(r, 'thesis')} | {cell(r, 'thesis_method')} | {cell(r, 'exact_method')}")
    lines.append("means of |error|:")
    for lens in (16, 50):
        parts = []
        for key, label in (("thesis", "published"), ("thesis_method", "ours/thesis"), ("exact_method", "ours/exact")):
            m = res["means"][f"{key}_{lens}mm"]
            if m["n"]:
                parts.append(f"{label}: d {m['mean_abs_d_error_pct']:.2f}%, alpha {m['mean_abs_alpha_error_deg']:.2f} deg"
                             f" (n={m['n']})")
            else:
                parts.append(f"{label}: none found")
        lines.append(f"  {lens} mm  " + "; ".join(parts))
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    res = reproduce_thesis(args.seed, args.noise, args.blur, args.column)
    if args.json:
        emit_json(res)
    else:
        print(format_table(res))
    return 0
