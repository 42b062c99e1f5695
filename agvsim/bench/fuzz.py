"""``agvsim bench fuzz``: the localizer on ``--frames`` random target-free frames.

Every frame is 512 x 480 uint8 (the thesis camera) and holds NO target. Frame ``i`` of a run
is of kind ``KINDS[i % len(KINDS)]`` and is drawn from ``numpy.random.default_rng(frame_seed)``
with ``frame_seed = seed * 1_000_003 + i``, so :func:`make_frame` (kind, frame_seed) rebuilds
any frame the report names. Kinds: uniform noise, Gaussian noise on a flat or a gradient
background, random rectangles, random bars (widths, heights, contrasts), rows of equal bars
(:func:`localizer.tools.synthetic.equal_bar_frame`), stripes, checkerboards, saturated / black /
white frames, random lines, and the adversarial frames of
:func:`localizer.tools.synthetic.adversarial_frames`.

Both methods (``exact``, ``thesis``) run on every frame. A crash is any exception (its kind,
the frame's kind and seed are kept for the first few); every detection is a false one. Time
per frame (median, p99, max, ms) per method, after one warm-up frame of each kind (the
numba kernels compile there; that time is reported apart). Floors: 0 crashes and 0 false
detections. Progress goes to stderr; Ctrl-C stops the run and reports the frames done.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from agvsim.bench.floors import floor_line, verdict
from agvsim.commands._args import number

METHODS = ("exact", "thesis")
#: how many crash / false-detection cases are kept for reproduction
KEEP_CASES = 5
H, W = 480, 512


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", type=number(1, integer=True), default=10000,
                   help="target-free frames (default 10000)")
    p.add_argument("--seed", type=number(0, integer=True), default=0, help="run seed (default 0)")


# ------------------------------------------------------------------ frame kinds
def _u8(f) -> np.ndarray:
    return np.clip(np.rint(f), 0, 255).astype(np.uint8)


def _uniform_noise(rng):
    return rng.integers(0, 256, (H, W), dtype=np.uint8)


def _gauss_flat(rng):
    return _u8(rng.uniform(0, 255) + rng.normal(0, rng.uniform(1, 40), (H, W)))


def _gauss_gradient(rng):
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    a, b = rng.uniform(-0.6, 0.6, 2)
    base = rng.uniform(0, 255) + a * (xx - W / 2) + b * (yy - H / 2)
    return _u8(base + rng.normal(0, rng.uniform(0.5, 20), (H, W)))


def _rects(rng, bars: bool = False):
    img = np.full((H, W), rng.integers(0, 256), np.float32)
    for _ in range(rng.integers(1, 40)):
        if bars:  # narrow and tall, or short and wide
            w, h = int(rng.integers(1, 40)), int(rng.integers(4, H))
            if rng.random() < 0.2:
                w, h = h % W + 1, w
        else:
            w, h = int(rng.integers(2, W)), int(rng.integers(2, H))
        x, y = int(rng.integers(0, W - min(w, W - 1))), int(rng.integers(0, H - min(h, H - 1)))
        img[y:y + h, x:x + w] = rng.integers(0, 256)
    if rng.random() < 0.5:
        img += rng.normal(0, rng.uniform(0.5, 6), (H, W))
    return _u8(img)


def _random_bars(rng):
    return _rects(rng, bars=True)


def _equal_bars(rng):
    from localizer.tools.synthetic import equal_bar_frame
    from localizer import Camera

    width = int(rng.integers(1, 30))
    pitch = width + int(rng.integers(1, 3 * width + 2))
    n = int(rng.integers(1, max(2, min(12, (W - 1 - width) // pitch + 1)) + 1))
    n = max(1, min(n, (W - width) // pitch + 1))
    height = int(rng.integers(1, H))
    dark, bright = sorted(int(v) for v in rng.integers(0, 256, 2))
    x0 = int(rng.integers(0, W - (n - 1) * pitch - width + 1))
    y0 = int(rng.integers(0, H - height + 1))
    return equal_bar_frame(Camera.thesis(16.0), n, width, pitch, height, dark, bright,
                           bool(rng.random() < 0.5), x0, y0)


def _stripes(rng):
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    ang = rng.uniform(0, np.pi) if rng.random() < 0.5 else 0.0
    period = rng.uniform(2, 120)
    duty = rng.uniform(0.1, 0.9)
    u = (xx * np.cos(ang) + yy * np.sin(ang)) / period
    lo, hi = rng.integers(0, 256, 2)
    return _u8(np.where((u % 1.0) < duty, lo, hi))


def _checkerboard(rng):
    yy, xx = np.mgrid[0:H, 0:W]
    sq = int(rng.integers(2, 80))
    lo, hi = rng.integers(0, 256, 2)
    board = ((xx + rng.integers(0, sq)) // sq + (yy + rng.integers(0, sq)) // sq) % 2 == 0
    return _u8(np.where(board, lo, hi) + rng.normal(0, rng.uniform(0, 4), (H, W)))


def _flat(rng):
    level = rng.choice([0, 255, int(rng.integers(0, 256))])
    img = np.full((H, W), level, np.uint8)
    if rng.random() < 0.5:  # saturated blobs
        for _ in range(rng.integers(1, 6)):
            x, y = rng.integers(0, W), rng.integers(0, H)
            img[y:y + rng.integers(5, 200), x:x + rng.integers(5, 200)] = rng.choice([0, 255])
    return img


def _lines(rng):
    import cv2

    img = np.full((H, W), rng.integers(0, 256), np.uint8)
    for _ in range(rng.integers(1, 30)):
        p1 = (int(rng.integers(-50, W + 50)), int(rng.integers(-50, H + 50)))
        p2 = (int(rng.integers(-50, W + 50)), int(rng.integers(-50, H + 50)))
        cv2.line(img, p1, p2, int(rng.integers(0, 256)), int(rng.integers(1, 12)))
    return img


def _adversarial(rng):
    from localizer.tools.synthetic import adversarial_frames
    from localizer import Camera

    frames = adversarial_frames(Camera.thesis(16.0), rng)
    img = frames[sorted(frames)[int(rng.integers(0, len(frames)))]]
    return np.ascontiguousarray(np.roll(img, (int(rng.integers(-60, 61)), int(rng.integers(-60, 61))), (0, 1)))


#: frame kind -> its generator (a numpy Generator -> one 480 x 512 uint8 target-free frame)
GENERATORS = {
    "uniform_noise": _uniform_noise, "gauss_flat": _gauss_flat, "gauss_gradient": _gauss_gradient,
    "rectangles": _rects, "random_bars": _random_bars, "equal_bars": _equal_bars, "stripes": _stripes,
    "checkerboard": _checkerboard, "flat_saturated": _flat, "lines": _lines, "adversarial": _adversarial,
}
KINDS = tuple(GENERATORS)


def frame_seed(seed: int, index: int) -> int:
    return int(seed) * 1_000_003 + int(index)


def make_frame(kind: str, seed: int) -> np.ndarray:
    """The frame of ``kind`` drawn from ``numpy.random.default_rng(seed)`` (a frame seed)."""
    return GENERATORS[kind](np.random.default_rng(seed))


# ------------------------------------------------------------------ the run
def measure(frames: int, seed: int = 0, progress: bool = True) -> dict:
    from tqdm import tqdm

    from agvsim.commands.workers import sigint_blocked
    from localizer import Camera, detect_targets

    cam = Camera.thesis(16.0)
    t0 = time.perf_counter()
    for k, kind in enumerate(KINDS):  # warm-up: compile every kernel before timing
        f = make_frame(kind, 2**40 + k)  # outside every run's frame seeds
        for m in METHODS:
            try:
                detect_targets(f, cam, method=m)
            except Exception:  # counted when it happens in the run proper
                pass
    warmup_s = time.perf_counter() - t0
    times = {m: [] for m in METHODS}
    crashes = {m: 0 for m in METHODS}
    false = {m: 0 for m in METHODS}
    by_kind = {k: {"frames": 0, "crashes": 0, "false_detections": 0} for k in KINDS}
    crash_cases: list = []
    false_cases: list = []
    done, interrupted = 0, False
    bar = tqdm(total=frames, desc="fuzz", unit=" frames", file=sys.stderr, disable=not progress, leave=False)
    try:
        for i in range(frames):
            kind, fs = KINDS[i % len(KINDS)], frame_seed(seed, i)
            img = make_frame(kind, fs)
            if img.shape != (H, W) or img.dtype != np.uint8:
                raise AssertionError(f"generator {kind} made a {img.shape} {img.dtype} frame")
            # a Ctrl-C is raised after the frame is counted, never inside a compiled call, where numba
            # would turn it into a crash of the interpreter or a SystemError counted as the detector's
            # (agvsim.commands.workers.sigint_blocked; its signal calls fall outside the timed ones)
            with sigint_blocked():
                for m in METHODS:
                    t = time.perf_counter()
                    try:
                        obs = detect_targets(img, cam, method=m)
                    except Exception as exc:
                        times[m].append(time.perf_counter() - t)
                        crashes[m] += 1
                        by_kind[kind]["crashes"] += 1
                        if len(crash_cases) < KEEP_CASES:
                            crash_cases.append({"method": m, "kind": kind, "frame_seed": fs, "index": i,
                                                "error": type(exc).__name__, "message": str(exc)[:200]})
                        continue
                    times[m].append(time.perf_counter() - t)
                    if obs:
                        false[m] += len(obs)
                        by_kind[kind]["false_detections"] += len(obs)
                        if len(false_cases) < KEEP_CASES:
                            false_cases.append({"method": m, "kind": kind, "frame_seed": fs, "index": i,
                                                "detections": len(obs)})
                by_kind[kind]["frames"] += 1
                done += 1
            bar.update(1)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        bar.close()
    timing = {}
    for m, ts in times.items():
        ms = np.asarray(ts) * 1e3
        timing[m] = ({"median_ms": float(np.median(ms)), "p99_ms": float(np.percentile(ms, 99)),
                      "max_ms": float(ms.max())} if ms.size else
                     {"median_ms": None, "p99_ms": None, "max_ms": None})
    n_crash, n_false = sum(crashes.values()), sum(false.values())
    return {"frames_requested": frames, "frames": done, "seed": seed, "interrupted": interrupted,
            "kinds": list(KINDS), "warmup_s": warmup_s, "timing": timing,
            "crashes": n_crash, "crashes_by_method": crashes, "crash_cases": crash_cases,
            "false_detections": n_false, "false_detections_by_method": false, "false_cases": false_cases,
            "by_kind": by_kind,
            "floors": {"crashes": verdict(n_crash, "<=", 0), "false_detections": verdict(n_false, "<=", 0)},
            "reproduce": "agvsim.bench.fuzz.make_frame(kind, frame_seed)"}


def run(args) -> dict:
    return measure(args.frames, args.seed, progress=True)


def format_table(result: dict) -> str:
    lines = [f"fuzz: {result['frames']} of {result['frames_requested']} target-free 512 x 480 frames, seed "
             f"{result['seed']}, {len(result['kinds'])} kinds" + (" (INTERRUPTED)" if result["interrupted"] else ""),
             f"warm-up (one frame of each kind, kernels compile): {result['warmup_s']:.1f} s",
             f"{'method':<8} {'median ms':>10} {'p99 ms':>8} {'max ms':>8} {'crashes':>8} {'false det':>10}"]
    for m, t in result["timing"].items():
        cell = (lambda v: f"{v:.2f}" if v is not None else "-")
        lines.append(f"{m:<8} {cell(t['median_ms']):>10} {cell(t['p99_ms']):>8} {cell(t['max_ms']):>8} "
                     f"{result['crashes_by_method'][m]:>8} {result['false_detections_by_method'][m]:>10}")
    for label, key in (("crash", "crash_cases"), ("false detection", "false_cases")):
        for c in result[key]:
            lines.append(f"  {label}: {c['method']} on {c['kind']} frame_seed {c['frame_seed']} "
                         f"(frame {c['index']}) {c.get('error', '')} {c.get('message', c.get('detections', ''))}")
    if result["crash_cases"] or result["false_cases"]:
        lines.append(f"  reproduce: {result['reproduce']}")
    lines.append(floor_line("crashes", result["floors"]["crashes"], "d"))
    lines.append(floor_line("false detections", result["floors"]["false_detections"], "d"))
    return "\n".join(lines)
