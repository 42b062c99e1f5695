"""``agvsim bench envelope``: the localizer over a real camera's envelope, on frames it did not make.

The frames come from :mod:`agvsim.bench.envelope_frames` (a supersampled render of a printed
target on a cluttered wall, area-averaged to the pixels) through
:mod:`agvsim.bench.envelope_sensor` (defocus and motion PSFs, vignetting, exposure, flare,
shot and read noise, clipping, sRGB, Bayer demosaicing, JPEG): none of it from
:mod:`localizer.tools.synthetic`, whose frames share the localizer's assumptions. Poses: distance
1.5-5 m, alpha within +-60 deg, the whole print in view.

Per condition (:mod:`agvsim.bench.envelope_conditions`): the target found (a detection within
2 deg of bearing and 20 % of distance of the truth), false detections, the absolute errors
of d (% of d), beta and alpha (deg; alpha over targets whose shorter bar is >= 60 rows tall
at 512 x 480, scaled with fy), the share of errors within 3 sigma of the reported covariance (per axis and
in 3-D against chi-square 3), and ms per ``detect_targets`` call (``time.perf_counter``, one
call per frame right after the frame is made, after untimed warm-up calls per condition (the
plain call and, for ``exact``, the photometric refinement's: its kernels load once per process);
``--repeats R``: the median of R calls in turn with the peers). ``--peers``: an ArUco and an
AprilTag marker hang beside each target (:func:`agvsim.bench.envelope_frames.marker_layout`)
and ArUco+solvePnP and AprilTag 3 (:mod:`agvsim.bench.peers`) are timed on the same frames,
in turn with the localizer. Plus false detections on target-free frames
(the same pipeline, clutter only) at every resolution run. Every condition of a resolution
sees the same scenes (frame ``i``'s wall, clutter and pose); a subset of conditions gives
the same frames as the whole run, so ``--conditions blur2 --frames 5`` reproduces
the first five ``blur2`` frames of any run with the same seed.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from agvsim.bench.envelope_conditions import ALPHA_MIN_ROWS, NAMES, parse_conditions
from agvsim.bench.floors import floor_line, verdict
from agvsim.bench.tally import KEEP_FRAMES, Tally, settings_dict, summary_floors, thesis_fy
from agvsim.bench.peers import APRILTAG_INSTALL, one_opencv_thread, peer_detectors
from agvsim.commands._args import number

#: the report's first line (another benchmark reporting through :func:`format_table` sets ``title``)
TITLE = "localizer over a real camera's envelope (independent frames)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", type=number(1, integer=True), default=300,
                   help="frames per 512x480 condition, and target-free frames at 512x480 (default 300)")
    p.add_argument("--hires-frames", type=number(1, integer=True), default=40,
                   help="frames per larger-sensor condition, and target-free frames at each larger size "
                        "(default 40: a 2448x2048 frame takes about a second to render)")
    p.add_argument("--conditions", type=str, default="all",
                   help=f"comma-separated conditions or all (default all): {', '.join(NAMES)}")
    p.add_argument("--seed", type=number(0, integer=True), default=0, help="run seed (default 0)")
    p.add_argument("--method", choices=("exact", "thesis"), default="exact", help="localizer method (default exact)")
    p.add_argument("--peers", action="store_true",
                   help="hang an ArUco and an AprilTag marker beside each target and time ArUco+solvePnP and "
                        "AprilTag 3 on the same frames, in turn with the localizer (the frames then differ from "
                        "a run without --peers by the markers)")
    p.add_argument("--repeats", type=number(1, integer=True), default=1,
                   help="calls per frame and contender, in turn, timed by their median (default 1: one call "
                        "right after the frame is made, as the floors are measured; more gives the time in a "
                        "loop that only detects)")
    p.add_argument("--save-frames", type=str, default=None, metavar="DIR",
                   help="write every frame (PNG) with its truth and detections (JSON) under DIR/<condition>/")


def in_turn(contenders: dict, image: np.ndarray, repeats: int) -> dict:
    """Each contender (name -> ``fn(image)``) called ``repeats`` times in turn on ``image``
    (A, B, C, A, B, C, ...: a slow spell of the machine hits them alike; after the first
    round each call finds the caches as the others left them). name -> (the first call's
    result, the median of its calls' seconds)."""
    first, seconds = {}, {k: [] for k in contenders}
    for _ in range(repeats):
        for k, fn in contenders.items():
            t0 = time.perf_counter()
            out = fn(image)
            seconds[k].append(time.perf_counter() - t0)
            first.setdefault(k, out)
    return {k: (first[k], float(np.median(seconds[k]))) for k in contenders}


def _save(folder, name: str, index: int, frame, obs) -> None:
    from pathlib import Path

    from agvsim.bench.envelope_frames import truth_dict
    from agvsim.commands._args import write_image

    d = Path(folder) / name
    write_image(d / f"{index:04d}.png", frame.image, "--save-frames")
    truth = truth_dict(frame)
    truth["detections"] = [o.to_dict() for o in obs]
    (d / f"{index:04d}.json").write_text(json.dumps(truth, indent=1, default=float), encoding="utf-8")


def _progress(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def run(args) -> dict:
    """The benchmark's JSON-ready result (OpenCV on one thread while it runs, as every contender)."""
    with one_opencv_thread():
        return _run(args)


def _run(args) -> dict:
    from localizer import detect_targets

    from agvsim.bench.envelope_frames import MARKER_SIDE, bar_rows, camera_for, expose_frame, render_scene

    conditions = parse_conditions(args.conditions)
    sizes: dict[tuple[int, int], list] = {}
    for c in conditions:
        sizes.setdefault((c.settings.width, c.settings.height), []).append(c)
    t_start = time.perf_counter()
    result: dict = {"method": args.method, "seed": args.seed, "conditions": [], "target_free": {}}
    if args.peers and "apriltag" not in peer_detectors(camera_for(512, 480)):
        result["missing_peers"] = {"apriltag": APRILTAG_INSTALL}
    reports = {}
    for (w, h), conds in sizes.items():
        n = args.frames if (w, h) == (512, 480) else args.hires_frames
        tallies = {}
        peers = peer_detectors(camera_for(w, h), MARKER_SIDE) if args.peers else {}
        for i in range(n):
            rendered = render_scene(w, h, args.seed, i, markers=args.peers)
            for c in conds:
                frame = expose_frame(c.settings, rendered)
                tally = tallies.get(c.name)
                if tally is None:  # the warm-up calls (kernel load, first-size caches): not timed
                    tally = tallies[c.name] = Tally(c.name, c.help, (w, h), settings_dict(c.settings),
                                                     ALPHA_MIN_ROWS * frame.camera.fy / thesis_fy())
                    detect_targets(frame.image, frame.camera, method=args.method)
                    if args.method == "exact":  # (and the photometric refinement's kernels, loaded once
                        # per process: else the first frame that takes it pays their load, ~30 ms)
                        detect_targets(frame.image, frame.camera, method=args.method, photometric="all")
                timed = in_turn({"localizer": lambda im, cam=frame.camera: detect_targets(im, cam, method=args.method),
                                 **peers}, frame.image, args.repeats)
                obs, dt = timed.pop("localizer")
                tally.add(i, rendered.scene.pose, obs, dt, bar_rows(rendered.scene.pose, frame.camera))
                for name, (found, dt) in timed.items():
                    tally.add_peer(name, len(found) > 0, dt)
                if args.save_frames:
                    _save(args.save_frames, c.name, i, frame, obs)
            if (i + 1) % max(1, n // 5) == 0:
                _progress(f"envelope {w}x{h}: {i + 1}/{n} frames ({time.perf_counter() - t_start:.0f} s)")
        for name, tally in tallies.items():
            reports[name] = tally.report()
        free = {"frames": 0, "false_detections": 0, "false_frames": [], "conditions": [c.name for c in conds]}
        for i in range(n):  # target-free frames, the conditions of this size in turn
            c = conds[i % len(conds)]
            frame = expose_frame(c.settings, render_scene(w, h, args.seed, i, with_target=False))
            obs = detect_targets(frame.image, frame.camera, method=args.method)
            free["frames"] += 1
            free["false_detections"] += len(obs)
            if obs and len(free["false_frames"]) < KEEP_FRAMES:
                free["false_frames"].append({"frame": i, "condition": c.name, "detections": len(obs)})
            if args.save_frames:
                _save(args.save_frames, f"target_free_{w}x{h}", i, frame, obs)
        free["floor"] = verdict(free["false_detections"], "<=", 0.0)
        result["target_free"][f"{w}x{h}"] = free
        _progress(f"envelope {w}x{h}: target-free frames done ({time.perf_counter() - t_start:.0f} s)")
    result["conditions"] = [reports[c.name] for c in conditions]
    result["floors"] = summary_floors(result["conditions"], result["target_free"])
    result["seconds"] = time.perf_counter() - t_start
    return result


def _f(x, spec: str = ".2f") -> str:
    return "-" if x is None else format(x, spec)


def format_table(r: dict) -> str:
    m = r["machine"]
    lines = [f"machine: {m.get('cpu_model')} ({m.get('cpu_count')} cpus), python {m.get('python')}",
             f"{r.get('title', TITLE)}, method {r['method']}, seed {r['seed']}, {r['seconds']:.0f} s",
             f"{'condition':<12} {'size':>9} {'found':>9} {'false':>5} {'d% mean/max':>12} {'beta deg':>12} "
             f"{'alpha deg [n]':>17} {'3sigma% d/b/a/3D':>18} {'ms med/p99':>12}"]
    for c in r["conditions"]:
        w3 = c["within_3sigma_pct"]
        lines.append(
            f"{c['name']:<12} {c['size']:>9} {c['found']:>4}/{c['frames']:<4} {c['false_detections']:>5} "
            f"{_f(c['d_error_pct_mean']):>6}/{_f(c['d_error_pct_max']):<5} "
            f"{_f(c['beta_error_deg_mean'], '.3f'):>6}/{_f(c['beta_error_deg_max'], '.3f'):<5} "
            f"{_f(c['alpha_error_deg_mean']):>6}/{_f(c['alpha_error_deg_max']):<5} [{c['alpha_frames']:>3}] "
            f"{_f(w3['d'], '.0f'):>4}/{_f(w3['beta'], '.0f'):>3}/{_f(w3['alpha'], '.0f'):>3}/"
            f"{_f(w3['mahalanobis_3d'], '.0f'):>3}  "
            f"{_f(c['ms_median']):>5}/{_f(c['ms_p99'])}")
    if any(c["peers"] for c in r["conditions"]):
        lines.append("peers on the same frames, in turn with the localizer (median ms, frames with their marker "
                     "found, times the localizer's median):")
        for c in r["conditions"]:
            lines.append(f"  {c['name']:<12} " + "   ".join(
                f"{k} {p['ms_median']:.2f} ms, {p['found']}/{c['frames']}, {_f(p['times_slower'], '.1f')}x"
                for k, p in c["peers"].items()))
    for name, how in r.get("missing_peers", {}).items():
        lines.append(f"  {name} not timed: {how}")
    for c in r["conditions"]:
        if c["missed_frames"] or c["false_frames"]:
            lines.append(f"  {c['name']}: missed frames {c['missed_frames'] or '-'}, frames with a false detection "
                         f"{c['false_frames'] or '-'} (first {KEEP_FRAMES} of each)")
    for size, f in r["target_free"].items():
        lines.append(f"target-free frames {size}: {f['false_detections']} false detections in {f['frames']} frames"
                     + (f" (e.g. frames {', '.join(str(x['frame']) for x in f['false_frames'])})"
                        if f["false_frames"] else ""))
    for key, f in r["floors"].items():
        fail = f.get("failing") or {}
        note = ("failing: " + ", ".join(f"{k} {_f(v, '.3g')}" for k, v in fail.items())) if fail else ""
        lines.append(floor_line(f"{f['what']}, worst", f, ".3g", note))
    return "\n".join(lines)
