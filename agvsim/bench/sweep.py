"""``agvsim bench sweep``: one drift study on the local pool and on a local Ray, side by side.

The study: 2 odometry presets x 3 target densities (0, 1/3 and 1/2 of the targets removed) x
``--seeds`` seeds, ``--distance`` metres each on rendered frames (30 runs of 300 m by default).
It runs as ``agvsim sweep`` would be run by a user (a fresh command per configuration, its
folder started over), in this order: the local pool with 2 workers, a local Ray with 2
workers, the local pool with 1 worker. Reported per configuration: the command's wall time, the
sweep's own (from the first run started to the table written), the kernels' warm-up before
the fan-out and Ray's start-up (``ray.init`` to every actor ready); and whether the engines'
rows agree (figures, not timings). Floor: Ray within 15 % of the local pool.
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from agvsim.commands._args import number

#: Ray's wall time may exceed the local pool's by at most this share
FLOOR_RAY_OVER_LOCAL = 0.15
#: the configurations, in run order: (name, engine, workers)
CONFIGS: tuple[tuple[str, str, int], ...] = (("local_2", "local", 2), ("ray_2", "ray", 2), ("local_1", "local", 1))


def add_arguments(p) -> None:
    p.add_argument("--distance", type=number(0.0, low_open=True, unit="m"), default=300.0,
                   help="metres per run (default: %(default)s)")
    p.add_argument("--seeds", type=number(1, integer=True), default=5, help="seeds per point (default: %(default)s)")
    p.add_argument("--observations", default="rendered", choices=("rendered", "synthetic", "geometric"),
                   help="observation source (default: %(default)s)")
    p.add_argument("--configs", nargs="+", default=[c[0] for c in CONFIGS], choices=[c[0] for c in CONFIGS],
                   help="configurations to run (default: all)")
    p.add_argument("--out", type=Path, default=None, help="folder for the sweeps' results (default: a temporary one)")


def _spec(distance: float, seeds: int, observations: str) -> str:
    return (f"base: {{map: plant_floor, distance: {distance:g}, observations: {observations}}}\n"
            "grid:\n  odometry: [typical, worn]\n  targets_removed: [0.0, 0.33, 0.5]\n"
            f"seeds: {seeds}\n")


def _figures(out: Path) -> dict:
    from agvsim.sweep.folder import read_rows
    from agvsim.sweep.runs import TIMING_COLUMNS

    return {k: {c: v for c, v in r.items() if c not in TIMING_COLUMNS} for k, r in read_rows(out).items()}


def run(args) -> dict:
    from agvsim.commands._output import log

    folder = Path(args.out) if args.out is not None else Path(tempfile.mkdtemp(prefix="agvsim-bench-sweep-"))
    folder.mkdir(parents=True, exist_ok=True)
    spec = folder / "spec.yaml"
    spec.write_text(_spec(args.distance, args.seeds, args.observations))
    results: dict[str, dict] = {}
    for name, engine, workers in CONFIGS:
        if name not in args.configs:
            continue
        log(f"bench sweep: {name} ({engine}, {workers} workers) ...")
        started = time.perf_counter()
        p = subprocess.run([sys.executable, "-m", "agvsim", "sweep", str(spec), "--out", str(folder / name),
                            "--restart", "--engine", engine, "--workers", str(workers), "--no-plots",
                            "--no-progress", "--json"], capture_output=True, text=True)
        wall = time.perf_counter() - started
        if p.returncode != 0:
            raise RuntimeError(f"bench sweep: {name} failed: {p.stderr.strip().splitlines()[-1:]}")
        r = json.loads(p.stdout)
        results[name] = {"engine": engine, "workers": workers, "command_s": wall, "sweep_s": r["wall_time_s"],
                         "warmup_s": r["warmup_s"], "engine_startup_s": r["engine_startup_s"],
                         "runs": r["runs"], "failed": r["failed"]}
        log(f"  {wall:.1f} s")
    out = {"benchmark": "sweep", "distance_m": args.distance, "seeds": args.seeds,
           "observations": args.observations, "points": 6, "configs": results, "folder": str(folder)}
    if "local_2" in results and "ray_2" in results:
        ratio = results["ray_2"]["command_s"] / results["local_2"]["command_s"]
        out["ray_over_local"] = ratio
        out["rows_identical"] = _figures(folder / "local_2") == _figures(folder / "ray_2")
        out["floor"] = {"value": ratio - 1.0, "op": "<=", "limit": FLOOR_RAY_OVER_LOCAL,
                        "met": abs(ratio - 1.0) <= FLOOR_RAY_OVER_LOCAL}
    if "local_1" in results and "local_2" in results:
        out["speed_up_2_workers"] = results["local_1"]["command_s"] / results["local_2"]["command_s"]
    return out


def format_table(result: dict) -> str:
    m = result["machine"]
    lines = [f"machine: {m.get('cpu_model', m['machine'])} ({m['cpu_count']} cpus), python {m['python']}",
             f"sweep: 6 points x {result['seeds']} seeds, {result['distance_m']:g} m each, "
             f"{result['observations']} observations",
             f"{'config':8} {'engine':6} {'workers':>7} {'command s':>10} {'sweep s':>8} {'warm-up s':>10} "
             f"{'engine start s':>15} {'failed':>6}"]
    for name, r in result["configs"].items():
        lines.append(f"{name:8} {r['engine']:6} {r['workers']:7d} {r['command_s']:10.1f} {r['sweep_s']:8.1f} "
                     f"{r['warmup_s']:10.1f} {r['engine_startup_s']:15.1f} {r['failed']:6d}")
    if "ray_over_local" in result:
        f = result["floor"]
        lines.append(f"Ray / local pool (2 workers): {result['ray_over_local']:.3f} (floor within "
                     f"{100 * FLOOR_RAY_OVER_LOCAL:.0f} %: {'met' if f['met'] else 'NOT met'}); rows identical: "
                     f"{result['rows_identical']}")
    if "speed_up_2_workers" in result:
        lines.append(f"2 workers vs 1: {result['speed_up_2_workers']:.2f}x")
    return "\n".join(lines)
