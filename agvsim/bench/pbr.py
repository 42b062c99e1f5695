"""``agvsim bench pbr``: the localizer on physically based frames it had no part in making.

The frames are a versioned set on disk (:mod:`agvsim.bench.pbr_dataset`, shipped in
``tests/data/pbr``): the sheet ``agvsim target print`` lays out, rasterised, hung on a textured
wall (paint, stains, a dark band, posters), lit by a lamp, a ceiling panel and the room, seen
through a thin lens by Mitsuba 3's renderer, then a colour camera's sensor (shot and read
noise, Bayer, demosaicing, a response curve, JPEG) written apart from the project's own. The
benchmark never renders: it reads the set (``--generate`` makes the frames a folder lacks,
which takes Mitsuba, the ``pbr`` extra, and about 8 s a frame on 2 cores).

The report is on the **held-out** split unless ``--split`` says otherwise: the ``tune`` split is
the one to look at while changing the localizer. Per size, the conditions of :data:`CONDITIONS`
(a frame counts in every one it meets; the floors hold over in-spec frames: the narrower bar
>= 5 px wide, the shorter >= 16 rows, blur sd <= 3 px, all at 512 x 480 and scaled, noise sd
<= 8 grey levels), the same figures and floors as ``agvsim bench envelope``
(:mod:`agvsim.bench.tally`), and the false detections on the set's target-free frames. The
localizer runs with its defaults (``response="auto"``: it is not told each frame's curve).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Callable, NamedTuple

from agvsim.bench.envelope import format_table as _envelope_table
from agvsim.bench.envelope_conditions import ALPHA_MIN_ROWS, GATE_BETA
from agvsim.bench.floors import verdict
from agvsim.bench.pbr_dataset import DEFAULT_DIR, SPLITS, read_set
from agvsim.bench.pbr_scene import camera_for
from agvsim.bench.tally import KEEP_FRAMES, Tally, summary_floors
from agvsim.commands._args import number

__all__ = ["CONDITIONS", "add_arguments", "format_table", "run"]


class Condition(NamedTuple):
    """A group of frames the report has a row for: ``test(record) -> bool`` on an in-spec frame."""

    name: str
    help: str
    test: Callable[[dict], bool]


def _scale(r: dict) -> float:
    return r["scene"]["width"] / 512.0


#: the report's rows, in order (each over in-spec frames with a target)
CONDITIONS: tuple[Condition, ...] = (
    Condition("all", "every in-spec frame", lambda r: True),
    Condition("lens16", "the 16 mm lens's view", lambda r: r["scene"]["focal_mm"] == 16.0),
    Condition("lens50", "the 50 mm lens's view", lambda r: r["scene"]["focal_mm"] == 50.0),
    Condition("steep", "|alpha| >= 45 deg", lambda r: abs(r["attributes"]["alpha_deg"]) >= 45.0),
    Condition("blurred", "defocus sd >= 1.5 px (scaled)", lambda r: r["attributes"]["blur_sd_px"] >= 1.5 * _scale(r)),
    Condition("noisy", "noise sd >= 4 grey levels", lambda r: r["attributes"]["noise_grey"] >= 4.0),
    Condition("encoded", "gamma or sRGB response", lambda r: r["sensor"]["response"] != "linear"),
    Condition("encoded_blur", "encoded and defocus sd >= 1.5 px",
              lambda r: r["sensor"]["response"] != "linear" and r["attributes"]["blur_sd_px"] >= 1.5 * _scale(r)),
    Condition("jpeg", "stored as JPEG", lambda r: r["sensor"]["jpeg_quality"] > 0),
    Condition("dark_band", "a dark band of the wall crosses the sheet", lambda r: r["attributes"]["dark_band_on_face"]),
    Condition("negative", "white bars on black", lambda r: r["scene"]["polarity"] == "negative"),
    Condition("sheet", "the whole page hangs (text, crop marks)", lambda r: not r["scene"]["cut"]),
)
NAMES = tuple(c.name for c in CONDITIONS)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dataset", type=Path, default=DEFAULT_DIR, metavar="DIR",
                   help="the frame set (default: the shipped one, tests/data/pbr)")
    p.add_argument("--split", choices=(*SPLITS, "all"), default="held-out",
                   help="the frames reported on (default held-out; tune: the frames to tune on)")
    p.add_argument("--method", choices=("exact", "thesis"), default="exact", help="localizer method (default exact)")
    p.add_argument("--generate", action="store_true",
                   help="first render the frames DIR lacks (Mitsuba 3: pip install 'agvsim[pbr]'; ~8 s a frame); "
                        "an interrupted run resumes")
    p.add_argument("--seed", type=number(0, integer=True), default=0,
                   help="the set's seed, for --generate into a new folder (default 0: the shipped set)")


def _scene(record: dict):
    from agvsim.bench.pbr_scene import PbrScene

    return PbrScene.from_dict(record["scene"])


def _read(record: dict):
    import cv2

    image = cv2.imread(record["path"], cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise ValueError(f"{record['path']}: not a readable image of the set")
    return image


def run(args) -> dict:
    from localizer import detect_targets

    if args.generate:
        _generate(args)
    t_start = time.perf_counter()
    records = [r for r in read_set(args.dataset) if args.split == "all" or r["split"] == args.split]
    if not records:
        raise ValueError(f"--dataset {str(args.dataset)!r}: no frames of the {args.split!r} split")
    tallies: dict[tuple[str, str], Tally] = {}
    free: dict[str, dict] = {}
    out_of_spec = {"frames": 0, "found": 0}
    warmed = set()
    for record in records:
        scene = _scene(record)
        camera, size = camera_for(scene.width, scene.height, scene.focal_mm), record["attributes"]["size"]
        image = _read(record)
        if size not in warmed:  # kernel load and first-size caches: not timed
            detect_targets(image, camera, method=args.method)
            warmed.add(size)
        t0 = time.perf_counter()
        obs = detect_targets(image, camera, method=args.method)
        seconds = time.perf_counter() - t0
        if not record["scene"]["has_target"]:
            f = free.setdefault(size, {"frames": 0, "false_detections": 0, "false_frames": []})
            f["frames"] += 1
            f["false_detections"] += len(obs)
            if obs and len(f["false_frames"]) < KEEP_FRAMES:
                f["false_frames"].append({"frame": record["index"], "detections": len(obs)})
            continue
        if not record["attributes"]["in_spec"]:
            out_of_spec["frames"] += 1
            out_of_spec["found"] += any(abs(o.beta - scene.beta) < GATE_BETA for o in obs)
            continue
        w, h = (int(x) for x in size.split("x"))
        for c in CONDITIONS:
            if c.test(record):
                key = (size, c.name)
                if key not in tallies:
                    tallies[key] = Tally(c.name, c.help, (w, h), {"split": args.split}, ALPHA_MIN_ROWS * h / 480.0)
                tallies[key].add(record["index"], scene.pose, obs, seconds, record["attributes"]["bar_rows"])
    for f in free.values():
        f["floor"] = verdict(f["false_detections"], "<=", 0.0)
    conditions = [tallies[k].report() for k in sorted(tallies, key=lambda k: (k[0] != "512x480", k[0],
                                                                              NAMES.index(k[1])))]
    for c in conditions:
        c["name"] = f"{c['name']}" if c["size"] == "512x480" else f"{c['name']}@{c['size'].split('x')[0]}"
    return {"title": f"localizer on physically based frames ({args.split} split of {Path(args.dataset).name}, "
                     f"{len(records)} frames)", "method": args.method, "seed": args.seed, "split": args.split,
            "conditions": conditions, "target_free": free, "out_of_spec": out_of_spec,
            "floors": summary_floors(conditions, free), "seconds": time.perf_counter() - t_start}


def _generate(args) -> None:
    import sys

    from tqdm import tqdm

    from agvsim.bench.pbr_dataset import generate

    made = generate(args.dataset, args.seed, lambda todo: tqdm(todo, desc="pbr frames", unit="frame", file=sys.stderr))
    print(f"agvsim bench pbr: {made} frames rendered into {args.dataset}", file=sys.stderr)


def format_table(r: dict) -> str:
    o = r["out_of_spec"]
    return _envelope_table(r) + (f"\nout-of-spec frames (no floor): target found in {o['found']} of {o['frames']}"
                                 if o["frames"] else "")
