"""``agvsim reproduce thesis``: the 18 test points of the thesis's Tables 5.1-5.4, side by side."""
from __future__ import annotations

import argparse

from agvsim.commands._args import number
from agvsim.commands._output import add_json_flag, emit_json


def register(sub) -> None:
    p = sub.add_parser("reproduce", help="reproduce a published result",
                       description="Reproduce a published result on synthetic frames.")
    p.add_argument("what", choices=("thesis",), help="thesis: Tables 5.1-5.4 (18 test points)")
    p.add_argument("--seed", type=number(0, integer=True), default=0, help="noise seed (default 0)")
    p.add_argument("--noise", type=number(0.0, unit="grey levels"), default=1.0, help="sensor noise sigma, grey levels (default 1)")
    p.add_argument("--blur", type=number(0.0, unit="px"), default=0.5, help="optical blur sigma, pixels (default 0.5)")
    p.add_argument("--column", type=number(unit="px"), default=40.0,
                   help="target centre this many pixels right of the principal point (default 40)")
    add_json_flag(p)
    p.set_defaults(func=run)


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
    from localizer.thesis.points import reproduce_thesis

    res = reproduce_thesis(args.seed, args.noise, args.blur, args.column)
    if args.json:
        emit_json(res)
    else:
        print(format_table(res))
    return 0
