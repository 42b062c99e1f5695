"""``agvsim bench localizer``: speed against ArUco+solvePnP and AprilTag 3, and accuracy over the envelope.

Speed frames (512 x 480 unless scaled) each hold one two-bar target, one
ArUco DICT_4X4_50 marker and one AprilTag tag36h11, on a real-photo
background; every detector runs on the same frames, one thread (OpenCV's
thread count is set to 1 for the run), after a
warm-up call (the localizer's first call loads or compiles its numba kernels;
its duration is reported separately). Two timings of the 512 x 480 frames:
``speed`` runs each contender ``--repeats`` times in a row on a frame (warm caches);
``speed_interleaved`` runs the contenders in turn, call by call, so each call finds the
caches as the others left them, as in a pipeline that does other work between frames.
``blank_frames``: ms per call on the all-black and all-white frames, where there is nothing
to find and the localizer must give up at once (floor 5 ms; formerly asserted by a test).

AprilTag 3 is timed only when ``pupil-apriltags`` is installed (``make bench``, or
``pip install pupil-apriltags``); without it the report says so instead of a zero.
"""
from __future__ import annotations

import argparse
import math
import statistics
import time

from agvsim.commands._args import number
from agvsim.bench.floors import floor_line, verdict
from agvsim.bench.peers import APRILTAG_INSTALL, marker_images, one_opencv_thread, peer_detectors

#: the floor on a blank frame (nothing to find), ms per call of the default localizer
FLOOR_BLANK_MS = 5.0
def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", type=number(1, integer=True), default=40, help="speed frames per configuration (default 40)")
    p.add_argument("--repeats", type=number(1, integer=True), default=5, help="timed repeats per frame (default 5)")
    p.add_argument("--samples", type=number(1, integer=True), default=600, help="accuracy frames over the envelope (default 600)")
    p.add_argument("--seed", type=number(0, integer=True), default=0)
    p.add_argument("--skip-peers", action="store_true", help="time only the localizer")


def _paste(refl, tag, x, y, size):
    import cv2
    import numpy as np

    t = cv2.resize(tag, (size, size), interpolation=cv2.INTER_NEAREST).astype(float) / 255.0
    q = int(size * 0.25)  # white quiet zone
    refl[y - q:y + size + q, x - q:x + size + q] = 0.9
    refl[y:y + size, x:x + size] = np.where(t > 0.5, 0.9, 0.06)


def _speed_frames(camera, n, rng, n_targets=1, with_markers=True):
    import numpy as np

    from localizer.tools.synthetic import real_photos, render_frame
    from localizer import TargetPose

    photos = list(real_photos(camera).values()) or [np.full(camera.shape, 0.5)]
    markers = marker_images()
    frames = []
    s = camera.width / 512.0
    for i in range(n):
        refl = photos[i % len(photos)].copy()
        if with_markers:
            _paste(refl, markers["aruco"], int(40 * s), int(60 * s), int(80 * s))
            _paste(refl, markers["apriltag"], int(40 * s), int(280 * s), int(80 * s))
        poses = []
        for k in range(n_targets):
            cols = n_targets if n_targets <= 4 else 4
            gx = (k % cols + 0.5) / cols
            gy = (k // cols + 0.5) / max(1, math.ceil(n_targets / cols))
            x = (0.45 + 0.5 * gx) * camera.width if n_targets == 1 else gx * camera.width
            x = 0.62 * camera.width if n_targets == 1 else x
            y = gy * camera.height
            d = rng.uniform(2.5, 4.0) if n_targets <= 2 else rng.uniform(4.5, 6.0)
            z = d
            poses.append(TargetPose(d, math.atan((x - camera.cx) / camera.fx), rng.uniform(-0.5, 0.5),
                                    (y - camera.cy) / camera.fy * z))
        frames.append(render_frame(camera, poses, lighting="normal", blur=0.6, noise=1.5, background=refl, rng=rng))
    return frames


def _time(fn, frames, repeats):
    """Median ms per frame of ``fn`` alone, ``repeats`` calls in a row per frame (warm caches)."""
    return _time_interleaved({"fn": fn}, frames, repeats)["fn"]


def _time_interleaved(fns: dict, frames, repeats) -> dict:
    """Median ms per frame of each function in ``fns`` (name -> callable on a frame): for every
    frame, ``repeats`` rounds in which each contender runs once, in turn (so a slow spell of
    the machine hits all of them alike); per frame the median of its rounds, then the median
    over frames."""
    per = {k: [] for k in fns}
    for f in frames:
        for fn in fns.values():
            fn(f)
        rounds = {k: [] for k in fns}
        for _ in range(repeats):
            for k, fn in fns.items():
                t0 = time.perf_counter()
                fn(f)
                rounds[k].append(time.perf_counter() - t0)
        for k in fns:
            per[k].append(statistics.median(rounds[k]))
    return {k: 1000.0 * statistics.median(v) for k, v in per.items()}


def run(args) -> dict:
    """The benchmark's JSON-ready result (OpenCV on one thread while it runs, as every contender)."""
    with one_opencv_thread():
        return _run(args)


def _run(args) -> dict:
    import numpy as np

    from localizer import Camera, detect_targets

    rng = np.random.default_rng(args.seed)
    cam = Camera.thesis(16.0)
    result: dict = {"speed": {}, "resolution": [], "targets": []}
    frames = _speed_frames(cam, args.frames, rng)
    # warm-up: the first call loads the localizer's numba kernels from their on-disk cache
    # (or, in a fresh environment, compiles them, ~10 s); it is timed once and never again
    for method in ("exact", "thesis"):
        t0 = time.perf_counter()
        detect_targets(frames[0], cam, method=method)
        result["speed"][f"first_call_{method}_s"] = time.perf_counter() - t0
    detect_targets(frames[0], cam, photometric="all")  # and the photometric kernels (not timed)
    found = {"exact": 0}
    for f in frames:
        found["exact"] += len(detect_targets(f, cam)) >= 1
    # block timing (each contender on each frame `repeats` times in a row: warm caches), as
    # recorded since the start, then interleaved timing (contenders in turn: each call finds the
    # caches as the others left them, closer to a pipeline that does other work between frames)
    fns = {f"localizer_{m}": (lambda f, m=m: detect_targets(f, cam, method=m)) for m in ("exact", "thesis")}
    if not args.skip_peers:
        peers = peer_detectors(cam)
        fns.update(peers)
        for name, fn in peers.items():
            found[name] = sum(len(fn(f)) >= 1 for f in frames)
        if "apriltag" not in peers:
            result["missing_peers"] = {"apriltag": APRILTAG_INSTALL}
    for k, fn in fns.items():
        result["speed"][f"{k}_ms"] = _time(fn, frames, args.repeats)
    result["speed_interleaved"] = {f"{k}_ms": v for k, v in _time_interleaved(fns, frames, args.repeats).items()}
    result["speed"]["frames"] = len(frames)
    result["speed"]["found"] = found
    for w, h in ((512, 480), (1280, 1200), (2048, 1920)):
        c = cam.scaled(w, h)
        fr = _speed_frames(c, max(3, args.frames // 8), rng)
        row = {"size": f"{w}x{h}", "localizer_exact_ms": _time(lambda f: detect_targets(f, c), fr, args.repeats),
               "found": sum(len(detect_targets(f, c)) >= 1 for f in fr) / len(fr)}
        if not args.skip_peers:
            peers = peer_detectors(c)
            for name, fn in peers.items():
                row[f"{name}_ms"] = _time(fn, fr, max(1, args.repeats // 2))
        result["resolution"].append(row)
    for n in (0, 1, 2, 4, 8):
        fr = _speed_frames(cam, max(3, args.frames // 8), rng, n_targets=n, with_markers=False)
        found_n = statistics.mean(len(detect_targets(f, cam)) for f in fr)
        result["targets"].append({"targets": n, "found_mean": found_n,
                                  "localizer_exact_ms": _time(lambda f: detect_targets(f, cam), fr, args.repeats)})
    result["accuracy"] = accuracy(args.samples, rng)
    result["false_positives"] = false_positives(rng)
    result["blank_frames"] = blank_frames(args.repeats)
    return result


def accuracy(n: int, rng) -> dict:
    """Accuracy (and, by lighting, the time of one call per frame) of the default ``exact``
    localizer, of ``exact`` from the edges alone (``photometric="off"``) and of ``thesis``.

    Random in-envelope poses: both lenses and polarities, dim/normal/saturated,
    blur 0-1 px, noise 0-3 grey levels, real-photo or flat backgrounds."""
    import numpy as np

    from localizer import Camera, detect_targets
    from localizer.tools.synthetic import random_pose, real_photos, render_frame, target_outline

    cams = {16: Camera.thesis(16.0), 50: Camera.thesis(50.0)}
    photos = list(real_photos(cams[16]).values())
    #: configurations: the default, the exact pose from the edges alone, the thesis pipeline
    configs = {"exact": ("exact", {}), "exact_edges_only": ("exact", {"photometric": "off"}),
               "thesis": ("thesis", {})}
    rows = {k: [] for k in configs}
    times: dict = {k: {} for k in configs}  # config -> lighting -> seconds per frame (one call each)
    missed = {k: 0 for k in configs}
    extra = {k: 0 for k in configs}
    for i in range(n):
        lens = 16 if i % 2 == 0 else 50
        cam = cams[lens]
        pose = random_pose(rng, cam, distance=(1.0, 10.0) if lens == 16 else (4.0, 20.0))
        lighting = ("dim", "normal", "saturated")[i % 3]
        pol = "positive" if (i // 2) % 2 == 0 else "negative"
        bg = photos[i % len(photos)] if photos and i % 4 != 3 else 0.5
        img = render_frame(cam, pose, polarities=pol, lighting=lighting, blur=rng.uniform(0, 1),
                           noise=rng.uniform(0, 3), background=bg, rng=rng)
        h_rows = float(target_outline(cam, pose)["bar_heights"].min())
        for method, (meth, kw) in configs.items():
            t0 = time.perf_counter()
            obs = detect_targets(img, cam, method=meth, **kw)
            times[method].setdefault(lighting, []).append(time.perf_counter() - t0)
            match = [o for o in obs if abs(o.beta - pose.beta) < 0.02 and abs(o.distance / pose.distance - 1) < 0.2]
            extra[method] += len(obs) - len(match[:1])
            if not match:
                missed[method] += 1
                continue
            o = match[0]
            sd = o.sigma
            rows[method].append((100 * abs(o.distance - pose.distance) / pose.distance,
                                 math.degrees(abs(o.alpha - pose.alpha)), h_rows,
                                 abs(o.distance - pose.distance) / max(sd[0], 1e-12),
                                 abs(o.alpha - pose.alpha) / max(sd[2], 1e-12), lighting))
    out = {"samples": n}
    for method, r in rows.items():
        a = np.array([x[:5] for x in r], float)
        if a.size == 0:
            out[method] = {"detection_rate": 0.0}
            continue
        big = a[:, 2] >= 60
        out[method] = {
            "detection_rate": len(r) / n, "missed": missed[method], "false_detections": extra[method],
            "d_error_pct_mean": float(a[:, 0].mean()), "d_error_pct_max": float(a[:, 0].max()),
            "alpha_error_deg_mean": float(a[:, 1].mean()), "alpha_error_deg_max": float(a[:, 1].max()),
            "alpha_error_deg_max_60rows": float(a[big, 1].max()) if big.any() else None,
            "alpha_error_deg_mean_60rows": float(a[big, 1].mean()) if big.any() else None,
            "within_3sigma_d": float((a[:, 3] <= 3).mean()), "within_3sigma_alpha": float((a[:, 4] <= 3).mean()),
            "by_lighting": {lt: {"d_error_pct_max": float(max(x[0] for x in r if x[5] == lt)),
                                 "alpha_error_deg_mean": float(np.mean([x[1] for x in r if x[5] == lt])),
                                 "ms_median": 1000.0 * float(np.median(times[method][lt])),
                                 "ms_p90": 1000.0 * float(np.percentile(times[method][lt], 90))}
                            for lt in ("dim", "normal", "saturated") if any(x[5] == lt for x in r)},
        }
    return out


def false_positives(rng) -> dict:
    from localizer import Camera, detect_targets
    from localizer.tools.synthetic import adversarial_frames, expose, real_photos

    cam = Camera.thesis(16.0)
    frames = dict(adversarial_frames(cam, rng))
    for name, refl in real_photos(cam).items():
        for lighting in ("dim", "normal", "saturated"):
            frames[f"photo:{name}:{lighting}"] = expose(refl, lighting, 0.5, 2.0, rng)
    res = {}
    for method in ("exact", "thesis"):
        res[method] = sum(len(detect_targets(f, cam, method=method)) for f in frames.values())
    res["frames"] = len(frames)
    return res


def blank_frames(repeats: int) -> dict:
    """Median ms per call of the default localizer on the all-black and all-white 512 x 480 frames.

    Uses its own random generator (the same frames as ``tests/localizer/test_false_positives.py``),
    so the figures of the other sections do not depend on it."""
    import numpy as np

    from localizer import Camera, detect_targets
    from localizer.tools.synthetic import adversarial_frames

    cam = Camera.thesis(16.0)
    frames = adversarial_frames(cam, np.random.default_rng(4))
    out = {f"{name}_ms": _time(lambda f: detect_targets(f, cam), [frames[name]], max(repeats, 20))
           for name in ("black", "white")}
    out["floor_ms"] = FLOOR_BLANK_MS
    out["floors"] = {name: verdict(out[f"{name}_ms"], "<=", FLOOR_BLANK_MS, "ms") for name in ("black", "white")}
    return out


def _pairs(d: dict, spec: str = ".4g") -> str:
    """``key value, key value`` (floats with ``spec``) for a flat dict of figures."""
    return ", ".join(f"{k} {format(v, spec) if isinstance(v, float) else v}" for k, v in d.items())


def format_table(r: dict) -> str:
    s = r["speed"]
    lines = [f"machine: {r['machine'].get('cpu_model')} ({r['machine'].get('cpu_count')} cpus), python "
             f"{r['machine'].get('python')}",
             f"speed, 512x480, median ms/frame over {s['frames']} frames (frames with a find: "
             f"{_pairs(s['found'])}):"]
    for k, v in s.items():
        if k.endswith("_ms"):
            ratio = f"  ({v / s['localizer_exact_ms']:.1f}x localizer_exact)" if not k.startswith("localizer") else ""
            lines.append(f"  {k[:-3]:<20} {v:8.3f}{ratio}")
    for name, how in r.get("missing_peers", {}).items():
        lines.append(f"  {name:<20} not timed: not installed ({how})")
    si = r.get("speed_interleaved", {})
    if si:
        lines.append("  interleaved (contenders in turn, call by call): " + ", ".join(
            f"{k[:-3]} {v:.3f}" + (f" ({v / si['localizer_exact_ms']:.1f}x)" if not k.startswith("localizer") else "")
            for k, v in si.items()))
    lines.append(f"  first call (kernel load or compile): exact {s['first_call_exact_s']:.2f} s, "
                 f"thesis {s['first_call_thesis_s']:.2f} s")
    lines.append("time vs resolution (ms/frame):")
    for row in r["resolution"]:
        lines.append("  " + ", ".join(f"{k}={v:.3f}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()))
    lines.append("time vs number of targets (512x480):")
    for row in r["targets"]:
        lines.append(f"  {row['targets']} targets: {row['localizer_exact_ms']:.3f} ms (found {row['found_mean']:.2f})")
    acc = r["accuracy"]
    lines.append(f"accuracy over the envelope ({acc['samples']} frames):")
    for m in [k for k in acc if k != "samples"]:
        a = acc[m]
        lines.append(f"  {m}: " + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                            for k, v in a.items() if k != "by_lighting"))
        for lighting, figures in a.get("by_lighting", {}).items():
            lines.append(f"    {lighting}: {_pairs(figures)}")
    fp = r["false_positives"]
    lines.append(f"false detections on {fp['frames']} target-free frames: "
                 + _pairs({k: v for k, v in fp.items() if k != "frames"}))
    b = r.get("blank_frames")
    if b:
        floors = b.get("floors") or {name: verdict(b[f"{name}_ms"], "<=", b["floor_ms"], "ms")
                                     for name in ("black", "white")}
        for name, floor in floors.items():
            lines.append(floor_line(f"{name} frame (nothing to find), ms per call", floor, ".3f"))
    return "\n".join(lines)
