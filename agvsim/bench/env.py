"""``agvsim bench env``: Gymnasium environment throughput, memory and where the time goes.

Each configuration runs in a fresh process (``spawn``), so its peak resident
memory is that of one env process: reset, then a fixed number of steps with
a fixed pseudo-random policy, timed after a short warm-up. Reported: policy
steps per second on one core, the real-time factor (simulated over wall
seconds), the peak RSS of the process (its own: ``VmHWM``, see :func:`peak_rss_mb`) with
what of its resident memory at the end is private (anonymous) and what is mapped library
files (shared by every process that maps them), how many kernels it had to compile (a cold
numba cache: the peak then includes the compiler's), and a breakdown of the wall time per
simulated second:

    physics   ``Simulation.step``: pymunk, encoders, dead reckoning
    render    drawing camera frames (the source's ``timing["render"]``)
    localize  the rest of the source's ``observe``: finding the targets in the frames
              (the detector; for ``geometric`` the whole geometric sensor model)
    filter    odometry into the EKF, predict, associate, update
    rest      everything else: the env adapter, the task, observations and info, Gymnasium's
              wrappers, Python glue (the total minus the parts above)

The parts come from :attr:`agvsim.loop.closed_loop.ClosedLoop.timings`
(``time.perf_counter`` at the seams, summed over the episodes of the run).
"""
from __future__ import annotations

import multiprocessing as mp

from agvsim.commands._args import number
from agvsim.bench.floors import floor_line, verdict
from agvsim.loop.modes import LOCALIZATION_MODES
from agvsim.sensors.registry import SOURCES

#: the floor on the peak memory of one env process (rendered observations, raycast backend), MB
FLOOR_PEAK_RSS_MB = 300.0
#: the floor on the policy steps per second of one env process on one core
FLOOR_STEPS_PER_SECOND = 500.0

CONFIGS = {
    "state": {"observe_image": False},
    "image": {"observe_image": True},
}

#: the breakdown's parts, in report order; "rest" is the total minus the others
PARTS = ("physics", "render", "localize", "filter", "rest")
#: part -> ClosedLoop.timings key
_LOOP_KEYS = {"physics": "sim", "render": "render", "localize": "localize", "filter": "filter"}


def add_arguments(parser) -> None:
    parser.add_argument("--env-id", default="agvsim/PlantFloor-v2")
    parser.add_argument("--steps", type=number(1, integer=True), default=600, help="timed policy steps (default: %(default)s)")
    parser.add_argument("--localization", default="ekf", choices=LOCALIZATION_MODES)
    parser.add_argument("--observations", default=None, choices=SOURCES,
                        help="observation source (default: the env's, rendered); the image config "
                             "is skipped for a source that draws no frames")
    parser.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))


def measure(env_id: str, kwargs: dict, steps: int, warmup: int = 20) -> dict:
    """Run ``env_id`` with ``kwargs`` for ``warmup`` + ``steps`` policy steps (fixed actions, seed 0)
    in this process; the figures of the timed ``steps``, with the breakdown (seconds, ms per
    simulated second, % of wall)."""
    import time

    import gymnasium as gym
    import numpy as np

    import envs  # noqa: F401

    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = np.clip(rng.normal([0.6, 0.0], [0.3, 0.5], (steps + warmup, 2)), -1, 1).astype(np.float32)
    for a in actions[:warmup]:  # warm-up (first frame starts the renderer)
        env.step(a)
    unwrapped = env.unwrapped
    keys = tuple(_LOOP_KEYS.values())
    spent = {k: -unwrapped.loop.timings[k] for k in keys}  # the warm-up's share of the current episode
    t0 = time.perf_counter()
    for a in actions[warmup:]:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            for k in keys:  # the episode's loop goes with the reset
                spent[k] += unwrapped.loop.timings[k]
            env.reset()
    wall = time.perf_counter() - t0
    for k in keys:
        spent[k] += unwrapped.loop.timings[k]
    dt = 1.0 / unwrapped.config.policy_rate
    observations = unwrapped.config.observations
    env.close()
    seconds = {part: spent[key] for part, key in _LOOP_KEYS.items()}
    seconds["rest"] = wall - sum(seconds.values())
    simulated = steps * dt
    breakdown = {part: {"seconds": s, "ms_per_sim_second": 1e3 * s / simulated, "percent_of_wall": 100.0 * s / wall}
                 for part, s in seconds.items()}
    breakdown["total"] = {"seconds": wall, "ms_per_sim_second": 1e3 * wall / simulated, "percent_of_wall": 100.0}
    return {"observations": observations, "steps": steps, "wall_seconds": wall, "steps_per_second": steps / wall,
            "real_time_factor": simulated / wall, "breakdown": breakdown}


def peak_rss_mb() -> float:
    """This process's peak resident memory (MB): ``VmHWM`` of ``/proc/self/status``, the high-water
    mark of its own address space. Not ``getrusage``'s ``ru_maxrss``: on Linux a child started
    with ``spawn`` (vfork + exec) inherits its parent's peak into that (a parent at 500 MB gives
    every child 500 MB). Elsewhere ``ru_maxrss`` (KiB; bytes on macOS)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    import resource
    import sys

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2.0 ** 20 if sys.platform == "darwin" else peak / 1024.0


def resident_mb() -> dict[str, float]:
    """This process's resident memory now (MB, Linux; empty elsewhere): ``anon`` (private: heap,
    arrays, compiled code) and ``file`` (pages of mapped files, mostly shared libraries: shared
    with every process that maps them, and on kernels with large page-cache folios counted in
    whole folios)."""
    out = {}
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                key, _, value = line.partition(":")
                if key in ("RssAnon", "RssFile"):
                    out["anon" if key == "RssAnon" else "file"] = int(value.split()[0]) / 1024.0
    except OSError:
        pass
    return out


def kernels_compiled() -> int:
    """How many compiled kernels this process compiled rather than loaded from numba's cache
    (a fresh clone compiles them in its first process: several hundred MB more at the peak)."""
    import gc
    import sys

    if "numba" not in sys.modules:
        return 0
    from numba.core.dispatcher import Dispatcher

    # (the class's MRO, not isinstance: Dispatcher is an ABC, whose isinstance test on every live
    # object of the process touches other libraries' deprecated attributes, torch's among them)
    return sum(sum(d.stats.cache_misses.values()) for d in gc.get_objects() if Dispatcher in type(d).__mro__)


def _worker(env_id: str, kwargs: dict, steps: int, queue) -> None:
    result = measure(env_id, kwargs, steps)
    queue.put({**result, "peak_rss_mb": peak_rss_mb(), "rss_end_mb": resident_mb(),
               "kernels_compiled": kernels_compiled()})


def run(args) -> dict:
    if args.steps < 1:
        raise ValueError("--steps must be >= 1")
    from agvsim.sensors.registry import source_class

    observations = getattr(args, "observations", None)
    draws_frames = source_class(observations).draws_frames if observations else True
    ctx = mp.get_context("spawn")
    results, skipped = {}, []
    for name in args.configs:
        kwargs = {**CONFIGS[name], "localization": args.localization}
        if observations:
            kwargs["observations"] = observations
        if kwargs.get("observe_image") and not draws_frames:
            skipped.append(name)
            continue
        queue = ctx.Queue()
        proc = ctx.Process(target=_worker, args=(args.env_id, kwargs, args.steps, queue))
        proc.start()
        result = queue.get()
        proc.join()
        results[name] = {**kwargs, **result}
        results[name]["floors"] = config_floors(results[name])
    return {"benchmark": "env", "env_id": args.env_id, "configs": results, "skipped": skipped,
            "floor_peak_rss_mb": FLOOR_PEAK_RSS_MB, "floor_steps_per_second": FLOOR_STEPS_PER_SECOND}


def config_floors(figures: dict) -> dict:
    """The floors' verdicts for one configuration's figures: ``steps_per_second`` (at least
    :data:`FLOOR_STEPS_PER_SECOND`) and ``peak_rss_mb`` (at most :data:`FLOOR_PEAK_RSS_MB`)."""
    return {"steps_per_second": verdict(figures["steps_per_second"], ">=", FLOOR_STEPS_PER_SECOND, "steps/s"),
            "peak_rss_mb": verdict(figures.get("peak_rss_mb"), "<=", FLOOR_PEAK_RSS_MB, "MB")}


def format_table(result: dict) -> str:
    m = result.get("machine", {})
    machine = f"{m.get('cpu_model', '?')} ({m.get('vector_extensions', '?')}), {m.get('cpu_count', '?')} CPUs"
    lines = [f"agvsim bench env — {result['env_id']} (machine: {machine}, one process per config)", "",
             (f"{'config':8}{'observations':>14}{'localization':>14}{'steps':>7}{'steps/s':>10}"
              f"{'real-time x':>13}{'peak RSS (MB)':>15}")]
    for name, r in result["configs"].items():
        lines.append(f"{name:8}{r['observations']:>14}{r['localization']:>14}{r['steps']:7d}"
                     f"{r['steps_per_second']:10.1f}{r['real_time_factor']:13.1f}{r['peak_rss_mb']:15.0f}")
    for name in result.get("skipped", ()):
        lines.append(f"{name:8}  skipped: the source draws no frames")
    for name, r in result["configs"].items():
        if r.get("kernels_compiled"):
            lines.append(f"{name:8}  compiled {r['kernels_compiled']} kernels (numba's cache was cold): its peak RSS "
                         "includes the compiler's; run again")
    if result["configs"]:
        lines += ["", "where the wall time goes: ms per simulated second (% of wall)",
                  f"{'config':8}" + "".join(f"{p:>16}" for p in (*PARTS, "total"))]
        for name, r in result["configs"].items():
            cells = "".join(f"{b['ms_per_sim_second']:8.2f} ({b['percent_of_wall']:4.1f}%)"
                            for b in (r["breakdown"][p] for p in (*PARTS, "total")))
            lines.append(f"{name:8}{cells}")
        lines.append("physics: Simulation.step (pymunk, encoders, dead reckoning); render: drawing frames; "
                     "localize: finding the targets (the rest of the source's observe); filter: EKF "
                     "odometry, predict, associate, update; rest: env adapter, task, observations, wrappers")
    ends = [f"{name} {r['rss_end_mb']['anon']:.0f} + {r['rss_end_mb']['file']:.0f}"
            for name, r in result["configs"].items() if {"anon", "file"} <= set(r.get("rss_end_mb", ()))]
    if ends:
        lines.append("resident at the end, private + mapped library files (shared between processes), MB: "
                     + ", ".join(ends))
    for name, r in result["configs"].items():
        floors = r.get("floors") or config_floors(r)
        lines.append(f"{name:8}  " + floor_line("speed", floors["steps_per_second"], ".1f"))
        lines.append(f"{name:8}  " + floor_line("peak RSS per env process", floors["peak_rss_mb"], ".0f",
                                                "rendered observations, raycast backend"))
    return "\n".join(lines)
