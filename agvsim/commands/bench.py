"""``agvsim bench TARGET``: performance benchmarks (results go to BENCHMARKS.md).

Each benchmark lives in :mod:`agvsim.bench.<name>` (``-`` in a name is ``_`` in the module) and exposes
``add_arguments(parser)`` and ``run(args) -> dict`` (the JSON figures) and
``format_table(result) -> str`` for the human-readable report.
"""
from __future__ import annotations

import importlib
import platform

from agvsim.commands._output import add_json_flag, doc_help, emit_json

#: name -> one-line help
BENCHMARKS: dict[str, str] = {
    "sim": "physics + odometry steps per second on one core (no rendering)",
    "localizer": "localizer ms per frame, against ArUco+solvePnP and AprilTag 3",
    "env": "Gymnasium env steps per second, real-time factor and peak memory",
    "render": "camera frames: ms per 512x480 frame, raycaster and pyrender (EGL/llvmpipe) on the same poses",
    "localization-integrity": "does the estimate lie? random agents, kidnapping, unknown starts, wall pushes",
    "availability": "the pose filter under an agent's driving (random, forward-biased, into a wall): tracking, "
                    "honesty, false losses, recovery",
    "fuzz": "localizer on random target-free frames: 0 crashes, 0 false detections, p99 ms per frame",
    "filter-soak": "the pose filter under 10^6 odometry increments and hostile frames: P sane, no wrong relocalization",
    "envelope": "localizer accuracy and speed per camera condition (blur, defocus, motion, sRGB, vignetting, "
                "JPEG, Bayer, noise, resolution) on independently rendered frames",
    "pbr": "localizer accuracy and speed on physically based frames (Mitsuba 3: a printed sheet on a lit, "
           "textured wall, a thin lens, a colour camera's sensor), reported on the held-out split",
    "sweep": "one drift study (30 rendered runs) on the local pool and on a local Ray, 1 and 2 workers",
    "replay": "logged drives: agvsim track on the demo's exported log and bag (round trip, real-time factor) "
              "and the cost of --record",
}


def machine_info() -> dict[str, object]:
    import os

    info: dict[str, object] = {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "processor": platform.processor() or None,
        "cpu_count": os.cpu_count(),
    }
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    info.setdefault("cpu_model", line.split(":", 1)[1].strip())
                elif line.startswith("flags"):
                    flags = line.split(":", 1)[1].split()
                    info["vector_extensions"] = ("avx512f" in flags and "AVX-512") or ("avx2" in flags and "AVX2") or "other"
                    break
    except OSError:
        pass
    return info


def register(sub) -> None:
    parser = sub.add_parser("bench", help="run a performance benchmark",
                            description=doc_help(__doc__))
    bench_sub = parser.add_subparsers(dest="benchmark", metavar="BENCHMARK", required=True)
    for name, help_text in BENCHMARKS.items():
        try:
            module = importlib.import_module(f"agvsim.bench.{name.replace('-', '_')}")
        except ModuleNotFoundError as exc:
            if exc.name == f"agvsim.bench.{name.replace('-', '_')}":
                continue
            raise
        p = bench_sub.add_parser(name, help=help_text, description=help_text)
        module.add_arguments(p)
        add_json_flag(p)
        p.set_defaults(func=_make_runner(module))


def _make_runner(module):
    def run(args) -> int:
        result = module.run(args)
        result = {"machine": machine_info(), **result}
        if args.json:
            emit_json(result)
        else:
            print(module.format_table(result))
        return 0

    return run
