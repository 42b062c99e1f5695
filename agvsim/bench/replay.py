"""``agvsim bench replay``: logged drives and recordings, on the demo's own drive.

The demo (``agvsim demo`` on ``--map``) is driven once with ``--export-log`` and ``--export-bag``
(the drive with its truth, in both formats); ``agvsim track`` then runs along each log, timed
in this process (the kernels already loaded): the real-time factor is the drive's duration over
the track's wall time, and the round trip's position RMSE and max are against the log's truth,
beside the closed loop's own in the same run. The recording's cost is the demo command's wall
time with ``--record`` over its time without (each a process of its own, as a user runs it),
interleaved ``--repeats`` times (medians), with the file's size per kilometre.
"""
from __future__ import annotations

import contextlib
import io
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

from agvsim.bench.floors import floor_line, verdict
from agvsim.commands._args import number

#: floors: the round trip's position RMSE and max (m), track's real-time factor, the recording's
#: share of the run's time, and its size per km (MB)
FLOOR_RMSE_M = 0.02
FLOOR_MAX_M = 0.10
FLOOR_REAL_TIME = 20.0
FLOOR_RECORD_SHARE = 0.15
FLOOR_RECORD_MB_PER_KM = 200.0


def add_arguments(parser) -> None:
    parser.add_argument("--map", default="plant_floor", help="the demo's map (default: %(default)s)")
    parser.add_argument("--repeats", type=number(1, integer=True), default=5,
                        help="interleaved demo runs with and without --record (default: %(default)s)")


def _command(argv: list[str]) -> tuple[dict, float]:
    """``agvsim ARGV --json`` in this process: its JSON and wall seconds."""
    from agvsim.cli import main

    out = io.StringIO()
    started = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        rc = main([*argv, "--json"])
    wall = time.perf_counter() - started
    if rc != 0:
        raise ValueError(f"agvsim {' '.join(argv)} failed (exit status {rc})")
    return json.loads(out.getvalue()), wall


def _process(argv: list[str]) -> float:
    """Wall seconds of ``agvsim ARGV`` as a command of its own (what a user waits for)."""
    import subprocess
    import sys

    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "agvsim", *argv], capture_output=True, text=True)
    if done.returncode != 0:
        raise ValueError(f"agvsim {' '.join(argv)} failed: {done.stderr.strip().splitlines()[-1:]}")
    return time.perf_counter() - started


def run(args) -> dict:
    with tempfile.TemporaryDirectory(prefix="agvsim-bench-replay-") as tmp:
        root = Path(tmp)
        demo = ["demo", "--map", args.map, "--frames", "0", "--no-progress"]
        loop, _ = _command([*demo, "--out", str(root / "demo"), "--export-log", str(root / "log"),
                            "--export-bag", str(root / "bag" / "drive.mcap")])
        tracks = {}
        for fmt, log in (("folder", root / "log"), ("bag", root / "bag" / "drive.mcap")):
            summary, wall = _command(["track", str(log), "--map", args.map, "--out", str(root / f"track-{fmt}"),
                                      "--no-progress", "--no-plots"])
            tracks[fmt] = {"rmse_m": summary["position_rmse_m"], "max_m": summary["position_max_m"],
                           "wall_s": wall, "duration_s": summary["duration_s"],
                           "real_time_factor": summary["duration_s"] / wall, "frames": summary["frames_used"]}
        plain, recorded, sizes = [], [], []
        for k in range(args.repeats):
            plain.append(_process([*demo, "--out", str(root / f"p{k}")]))
            rec = root / f"r{k}.rrd"
            recorded.append(_process([*demo, "--out", str(root / f"r{k}"), "--record", str(rec)]))
            sizes.append(rec.stat().st_size)
    km = loop["distance_m"] / 1000.0
    share = statistics.median(recorded) / statistics.median(plain) - 1.0
    mb_per_km = statistics.median(sizes) / 1e6 / km
    floors = {"round trip position RMSE": verdict(100 * max(t["rmse_m"] for t in tracks.values()), "<=",
                                                  100 * FLOOR_RMSE_M, "cm"),
              "round trip position max": verdict(100 * max(t["max_m"] for t in tracks.values()), "<=",
                                                 100 * FLOOR_MAX_M, "cm"),
              "track real-time factor": verdict(min(t["real_time_factor"] for t in tracks.values()), ">=",
                                                FLOOR_REAL_TIME, "x"),
              "recording's added time": verdict(100 * share, "<=", 100 * FLOOR_RECORD_SHARE, "%"),
              "recording per km": verdict(mb_per_km, "<=", FLOOR_RECORD_MB_PER_KM, "MB")}
    return {"map": args.map, "distance_m": loop["distance_m"],
            "closed_loop": {"rmse_m": loop["estimate_rmse_m"], "max_m": loop["estimate_max_m"]},
            "track": tracks, "demo_s": plain, "demo_record_s": recorded, "record_share": share,
            "record_mb_per_km": mb_per_km, "bytecode_written": not os.environ.get("PYTHONDONTWRITEBYTECODE"),
            "floors": floors}


def format_table(r: dict) -> str:
    m = r.get("machine", {})
    lines = [f"agvsim bench replay: the demo's drive on {r['map']} ({r['distance_m']:.0f} m); machine: "
             f"{m.get('cpu_model', '?')} ({m.get('vector_extensions', '?')}), {m.get('cpu_count', '?')} CPUs",
             f"  closed loop (the peer): position RMSE {100 * r['closed_loop']['rmse_m']:.2f} cm, "
             f"max {100 * r['closed_loop']['max_m']:.2f} cm"]
    for fmt, t in r["track"].items():
        lines.append(f"  track on the {fmt}: RMSE {100 * t['rmse_m']:.2f} cm, max {100 * t['max_m']:.2f} cm; "
                     f"{t['frames']} frames, {t['duration_s']:.0f} s of drive in {t['wall_s']:.1f} s "
                     f"({t['real_time_factor']:.0f}x real time)")
    lines.append(f"  demo {statistics.median(r['demo_s']):.1f} s, with --record "
                 f"{statistics.median(r['demo_record_s']):.1f} s (medians of {len(r['demo_s'])}, interleaved)")
    if not r.get("bytecode_written", True):
        lines.append("  (PYTHONDONTWRITEBYTECODE is set: each process, the recording's too, compiles its Python source "
                     "anew, which most installs do not; unset it to measure as they run)")
    lines += [floor_line(what, floor, ".2f" if floor["unit"] == "cm" else ".0f") for what, floor in r["floors"].items()]
    return "\n".join(lines)
