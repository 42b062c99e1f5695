"""``agvsim localize IMAGE...``: find two-bar targets in image files and print d, α, β."""
from __future__ import annotations

import argparse

from agvsim.commands._args import number
from agvsim.commands._output import add_json_flag, emit_json, log
from localizer.params import METHODS


def register(sub) -> None:
    p = sub.add_parser("localize", help="localize two-bar targets in image files",
                       description="Find the thesis's two-bar targets in image files and print the "
                                   "distance d, orientation alpha and bearing beta of each.")
    p.add_argument("images", nargs="+", metavar="IMAGE",
                   help="image files (PNG, JPEG, ...); one that cannot be read is reported and the others "
                        "localized (exit status 2)")
    cam = p.add_mutually_exclusive_group()
    cam.add_argument("--lens", type=number(0.0, low_open=True, unit="mm"), default=16.0, metavar="MM",
                     help="thesis camera with this focal length in mm (default 16)")
    cam.add_argument("--camera", metavar="CALIB.yaml", help="OpenCV calibration file (camera_matrix, "
                     "distortion_coefficients, image_width, image_height)")
    p.add_argument("--method", choices=METHODS, default="exact",
                   help="thesis: the thesis's pipeline; exact: subpixel edges + exact pose (default)")
    p.add_argument("--bar-width", type=number(0.0, low_open=True, unit="m"), default=0.075, metavar="M",
                   help="bar width b in metres (thesis proportions H=2b, s=b/2; default 0.075)")
    p.add_argument("--annotate", metavar="OUT.png",
                   help="write the image with edges and numbers marked (OUT_<n>.png for several images)")
    add_json_flag(p)
    p.set_defaults(func=run)


def _annotate_path(out: str, index: int, count: int) -> str:
    if count == 1:
        return out
    from pathlib import Path

    path = Path(out)
    return str(path.with_name(f"{path.stem}_{index}{path.suffix or '.png'}"))


def run(args: argparse.Namespace) -> int:
    import math
    import statistics
    import time

    from agvsim.commands._args import image_writer, write_image
    from localizer import Camera, TargetSpec, annotate, detect_targets
    from localizer.io import read_image_grey

    target = TargetSpec.from_bar_width(args.bar_width)
    if args.camera:
        try:
            base = Camera.from_opencv_yaml(args.camera)
        except (ValueError, FileNotFoundError) as exc:
            raise ValueError(f"--camera {exc}") from None
    else:
        base = Camera.thesis(args.lens)
    if args.annotate:  # a name OpenCV cannot write fails before any work
        image_writer(_annotate_path(args.annotate, 0, len(args.images)), "--annotate")
    results = []
    failed = 0
    for i, name in enumerate(args.images):
        try:
            img = read_image_grey(name)  # (the size checked from the header before decoding)
            camera = base
            if img.shape != base.shape:
                if args.camera:
                    raise ValueError(f"{name}: image is {img.shape[1]}x{img.shape[0]} but the calibration is "
                                     f"for {base.width}x{base.height}")
                camera = base.scaled(img.shape[1], img.shape[0])
                log(f"{name}: {img.shape[1]}x{img.shape[0]} image, thesis sensor scaled to it")
        except ValueError as exc:  # this image only: the others are still localized
            failed += 1
            log(f"agvsim localize: error: {exc}")
            results.append({"image": name, "error": str(exc), "targets": []})
            continue
        obs = detect_targets(img, camera, target, method=args.method)
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            detect_targets(img, camera, target, method=args.method)
            times.append(time.perf_counter() - t0)
        ms = 1000.0 * statistics.median(times)
        results.append({"image": name, "ms_per_frame": ms, "targets": [o.to_dict() for o in obs]})
        if args.annotate:
            out = write_image(_annotate_path(args.annotate, i, len(args.images)), annotate(img, obs), "--annotate")
            log(f"wrote {out}")
    status = 2 if failed else 0  # (a user's mistake, as a bad flag or map)
    if args.json:
        emit_json({"ok": not failed, "method": args.method,
                   "camera": {"fx": base.fx, "fy": base.fy, "cx": base.cx, "cy": base.cy,
                              "width": base.width, "height": base.height, "dist": list(base.dist)},
                   "results": results})
        return status
    print(f"{'image':<28} {'#':>2} {'d (m)':>8} {'alpha':>7} {'beta':>7} {'sd d':>7} {'sd a':>6} "
          f"{'polarity':>9} {'ms':>6}")
    for r in results:
        if "error" in r:
            print(f"{r['image'][-28:]:<28} {'-':>2} error: {r['error']}")
            continue
        if not r["targets"]:
            print(f"{r['image'][-28:]:<28} {'-':>2} {'no target':>8} {'':>7} {'':>7} {'':>7} {'':>6} {'':>9} "
                  f"{r['ms_per_frame']:6.2f}")
        for k, t in enumerate(r["targets"]):
            print(f"{r['image'][-28:]:<28} {k + 1:>2} {t['distance_m']:8.3f} {t['alpha_deg']:7.2f} "
                  f"{t['beta_deg']:7.2f} {t['sigma']['distance_m']:7.3f} "
                  f"{math.degrees(t['sigma']['alpha_rad']):6.2f} {t['polarity']:>9} {r['ms_per_frame']:6.2f}")
    if failed:
        log(f"agvsim localize: {failed} of {len(args.images)} images could not be read")
    return status
