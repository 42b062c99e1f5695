"""``agvsim render``: one camera frame of a map at a vehicle pose, and its ground truth."""
from __future__ import annotations

import argparse

from agvsim.commands._args import add_backend_flag, check_pose_on_map, image_writer, number, parse_mount, write_image
from agvsim.commands._output import add_json_flag, clean_json, emit_json, log


MAX_DEFOCUS_PX = 50.0  # px, blur sigma: beyond it no target survives, and the kernel grows with it


def _lighting(text: str):
    try:
        return float(text)
    except ValueError:
        return text


def register(sub) -> None:
    p = sub.add_parser("render", help="render a camera frame of a map (raycaster or pyrender, headless)",
                       description="Render what the vehicle's camera sees at a pose (map frame: x east, "
                                   "y north, theta CCW from +x; metres and radians) and optionally write "
                                   "the ground truth of every target as JSON.")
    p.add_argument("--map", default="plant_floor", help="map name or path (default: %(default)s)")
    p.add_argument("--pose", nargs=3, type=number(), required=True, metavar=("X", "Y", "THETA"),
                   help="vehicle pose: x (m), y (m), theta (rad)")
    p.add_argument("--lens", type=number(0.0, low_open=True, unit="mm"), default=16.0, metavar="MM",
                   help="thesis camera with this focal length in mm (16 or 50; default 16)")
    p.add_argument("--lighting", type=_lighting, default=None, metavar="LEVEL",
                   help="override the map's lighting zones: dim, normal, bright, or a relative level "
                        "(default: the map's zones)")
    p.add_argument("--seed", type=number(0, integer=True), default=0, help="sensor noise / jitter seed (default 0)")
    p.add_argument("--out", required=True, metavar="FRAME.png", help="where to write the frame")
    p.add_argument("--truth", metavar="TRUTH.json",
                   help="write the camera intrinsics and every target's truth (id, visible, distance, alpha, "
                        "beta, polarity, bbox, corners) here")
    p.add_argument("--mount", default="forward", metavar="MOUNT",
                   help="where the camera sits: forward, left, right (looking out of that side), map (the "
                        "map's recommended mount) or forward=F,lateral=L,height=H,yaw=Y in m and rad "
                        "(default forward)")
    p.add_argument("--camera-height", type=number(0.0, low_open=True, unit="m"), default=1.2, metavar="M",
                   help="lens height above the floor for forward/left/right, m (default 1.2)")
    p.add_argument("--exposure", type=number(0.0, low_open=True), default=1.0, help="relative exposure (default 1)")
    p.add_argument("--defocus", type=number(0.0, MAX_DEFOCUS_PX, unit="px"), default=0.0, metavar="PX", help="optical blur sigma, px (default 0)")
    p.add_argument("--focus", type=number(0.0, low_open=True, unit="m"), default=None, metavar="M",
                   help="focus distance (m): thin-lens defocus grows away from it (default: all in focus)")
    p.add_argument("--velocity", type=number(), nargs=2, default=(0.0, 0.0), metavar=("V", "OMEGA"),
                   help="vehicle speed (m/s) and yaw rate (rad/s) during the exposure, for motion blur (default: 0 0, "
                        "standing still)")
    p.add_argument("--no-noise", action="store_true", help="no sensor noise")
    p.add_argument("--rgb", action="store_true", help="write a 3-channel image instead of grey")
    add_backend_flag(p)
    add_json_flag(p)
    p.set_defaults(func=run)


def render_frame(args: argparse.Namespace) -> dict:
    import json
    from pathlib import Path

    import numpy as np

    from localizer import Camera
    from agvsim.sensors.render.renderer import CameraRenderer, RenderConditions
    from agvsim.world import load_map

    world_map = load_map(args.map)
    pose = check_pose_on_map(world_map, args.pose)
    if not world_map.is_free(pose[0], pose[1]):
        log(f"agvsim render: warning: --pose {pose[0]:g} {pose[1]:g}: inside a wall or an obstacle of map "
            f"{world_map.name!r} (the frame shows it from inside)")
    out = image_writer(args.out, "--out")  # (before the work: a name OpenCV cannot write fails at once)
    try:
        mount = parse_mount(args.mount, height=args.camera_height) or world_map.camera_mount
    except argparse.ArgumentTypeError as exc:
        raise ValueError(f"--mount: {exc}") from None
    renderer = CameraRenderer(world_map, Camera.thesis(args.lens), mount, backend=args.backend)
    conditions = RenderConditions(lighting=args.lighting, exposure=args.exposure, defocus_px=args.defocus,
                                  focus_distance=args.focus,
                                  velocity=tuple(args.velocity), noise=not args.no_noise, rgb=args.rgb)
    image, truth = renderer.render(pose, conditions, np.random.default_rng(args.seed))
    write_image(out, image[..., ::-1] if image.ndim == 3 else image, "--out")
    record = truth.to_dict()
    record.update({"map": world_map.name, "lens_mm": args.lens, "seed": args.seed, "image": str(out),
                   "mount": {"forward": mount.forward, "lateral": mount.lateral, "height": mount.height,
                             "yaw": mount.yaw}})
    if args.truth:
        tpath = Path(args.truth)
        tpath.parent.mkdir(parents=True, exist_ok=True)
        tpath.write_text(json.dumps(clean_json(record), indent=2) + "\n", encoding="utf-8")
    return record


def run(args: argparse.Namespace) -> int:
    import math

    record = render_frame(args)
    visible = [t for t in record["targets"] if t["visible"]]
    summary = {"image": record["image"], "truth": args.truth, "map": record["map"],
               "vehicle_pose": record["vehicle_pose"], "visible": visible}
    if args.json:
        emit_json(summary)
        return 0
    log(f"wrote {record['image']}" + (f" and {args.truth}" if args.truth else ""))
    if not visible:
        print("no target visible")
    for t in visible:
        print(f"{t['id']:>6} {t['polarity']:>8}  d {t['distance']:7.3f} m  alpha {math.degrees(t['alpha']):6.1f} deg"
              f"  beta {math.degrees(t['beta']):6.1f} deg  bbox {[round(v, 1) for v in t['bbox']]}")
    return 0
