"""``agvsim bench env``: Gymnasium environment throughput and memory.

Each configuration runs in a fresh process (``spawn``), so its peak resident
memory is that of one env process: reset, then a fixed number of steps with
a fixed pseudo-random policy, timed after a short warm-up. Reported: policy
steps per second on one core, the real-time factor (simulated over wall
seconds) and the peak RSS of the process.
"""
from __future__ import annotations

import multiprocessing as mp

from agvsim.loop.modes import LOCALIZATION_MODES

CONFIGS = {
    "state": {"observe_image": False},
    "image": {"observe_image": True},
}


def add_arguments(parser) -> None:
    parser.add_argument("--env-id", default="agvsim/PlantFloor-v0")
    parser.add_argument("--steps", type=int, default=600, help="timed policy steps (default: %(default)s)")
    parser.add_argument("--localization", default="ekf", choices=LOCALIZATION_MODES)
    parser.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))


def _worker(env_id: str, kwargs: dict, steps: int, queue) -> None:
    import resource
    import time

    import gymnasium as gym
    import numpy as np

    import envs  # noqa: F401

    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = np.clip(rng.normal([0.6, 0.0], [0.3, 0.5], (steps + 20, 2)), -1, 1).astype(np.float32)
    for a in actions[:20]:  # warm-up (first frame starts the renderer)
        env.step(a)
    t0 = time.perf_counter()
    for a in actions[20:]:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    wall = time.perf_counter() - t0
    dt = 1.0 / env.unwrapped.config.policy_rate
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    env.close()
    queue.put({"steps": steps, "wall_seconds": wall, "steps_per_second": steps / wall,
               "real_time_factor": steps * dt / wall, "peak_rss_mb": peak_kib / 1024.0})


def run(args) -> dict:
    if args.steps < 1:
        raise ValueError("--steps must be >= 1")
    ctx = mp.get_context("spawn")
    results = {}
    for name in args.configs:
        queue = ctx.Queue()
        kwargs = {**CONFIGS[name], "localization": args.localization}
        proc = ctx.Process(target=_worker, args=(args.env_id, kwargs, args.steps, queue))
        proc.start()
        result = queue.get()
        proc.join()
        results[name] = {**kwargs, **result}
    return {"benchmark": "env", "env_id": args.env_id, "configs": results,
            "floor_peak_rss_mb_with_images": 500.0}


def format_table(result: dict) -> str:
    lines = [f"agvsim bench env — {result['env_id']} "
             f"(machine: {result['machine'].get('cpu_model', '?')}, one process per config)",
             f"{'config':10}{'localization':>14}{'steps/s':>10}{'real-time x':>13}{'peak RSS (MB)':>15}"]
    for name, r in result["configs"].items():
        lines.append(f"{name:10}{r['localization']:>14}{r['steps_per_second']:10.1f}"
                     f"{r['real_time_factor']:13.1f}{r['peak_rss_mb']:15.0f}")
    lines.append(f"floor: peak RSS <= {result['floor_peak_rss_mb_with_images']:.0f} MB per env process with images")
    return "\n".join(lines)
