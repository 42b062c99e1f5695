"""``agvsim localize IMAGE...``: find two-bar targets in image files and print d, α, β."""
from __future__ import annotations

import argparse

from agvsim.commands._output import add_json_flag, emit_json, log
from localizer.params import METHODS


def register(sub) -> None:
    p = sub.add_parser("localize", help="localize two-bar targets in image files",
                       description="Find the thesis's two-bar targets in image files and print the "
                                   "distance d, orientation alpha and bearing beta of each.")
    p.add_argument("images", nargs="+", metavar="IMAGE", help="image files (PNG, JPEG, ...)")
    cam = p.add_mutually_exclusive_group()
    cam.add_argument("--lens", type=float, default=16.0, metavar="MM",
                     help="thesis camera with this focal length in mm (default 16)")
    cam.add_argument("--camera", metavar="CALIB.yaml", help="OpenCV calibration file (camera_matrix, "
                     "distortion_coefficients, image_width, image_height)")
    p.add_argument("--method", choices=METHODS, default="exact",
                   help="thesis: the thesis's pipeline; exact: subpixel edges + exact pose (default)")
    p.add_argument("--bar-width", type=float, default=0.075, metavar="M",
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

    import cv2

    from localizer import Camera, TargetSpec, annotate, detect_targets

    target = TargetSpec.from_bar_width(args.bar_width)
    base = Camera.from_opencv_yaml(args.camera) if args.camera else Camera.thesis(args.lens)
    results = []
    for i, name in enumerate(args.images):
        img = cv2.imread(name, cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise FileNotFoundError(f"cannot read image {name!r}")
        camera = base
        if img.shape != base.shape:
            if args.camera:
                raise ValueError(f"{name}: image is {img.shape[1]}x{img.shape[0]} but the calibration is "
                                 f"for {base.width}x{base.height}")
            camera = base.scaled(img.shape[1], img.shape[0])
            log(f"{name}: {img.shape[1]}x{img.shape[0]} image, thesis sensor scaled to it")
        obs = detect_targets(img, camera, target, method=args.method)
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            detect_targets(img, camera, target, method=args.method)
            times.append(time.perf_counter() - t0)
        ms = 1000.0 * statistics.median(times)
        results.append({"image": name, "ms_per_frame": ms, "targets": [o.to_dict() for o in obs]})
        if args.annotate:
            out = _annotate_path(args.annotate, i, len(args.images))
            cv2.imwrite(out, annotate(img, obs))
            log(f"wrote {out}")
    if args.json:
        emit_json({"method": args.method, "camera": {"fx": base.fx, "fy": base.fy, "cx": base.cx, "cy": base.cy,
                                                     "width": base.width, "height": base.height,
                                                     "dist": list(base.dist)},
                   "results": results})
        return 0
    print(f"{'image':<28} {'#':>2} {'d (m)':>8} {'alpha':>7} {'beta':>7} {'sd d':>7} {'sd a':>6} "
          f"{'polarity':>9} {'ms':>6}")
    for r in results:
        if not r["targets"]:
            print(f"{r['image'][-28:]:<28} {'-':>2} {'no target':>8} {'':>7} {'':>7} {'':>7} {'':>6} {'':>9} "
                  f"{r['ms_per_frame']:6.2f}")
        for k, t in enumerate(r["targets"]):
            print(f"{r['image'][-28:]:<28} {k + 1:>2} {t['distance_m']:8.3f} {t['alpha_deg']:7.2f} "
                  f"{t['beta_deg']:7.2f} {t['sigma']['distance_m']:7.3f} "
                  f"{math.degrees(t['sigma']['alpha_rad']):6.2f} {t['polarity']:>9} {r['ms_per_frame']:6.2f}")
    return 0
