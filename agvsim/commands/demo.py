"""agvsim demo: drive the default route of the default map with the
camera correcting the drifting odometry.

The vehicle follows the route with pure pursuit steering on its *estimated*
pose: ``typical`` odometry, a camera rendering frames at 4 Hz, the localizer
measuring the targets in them and the EKF fusing both. It prints a progress
bar, a table of dead-reckoning and estimate errors against distance and the
filter's losses (times lost, seconds lost, recoveries by re-localization), and
writes a top-down picture (true, dead-reckoned and estimated trajectories),
an error plot and a strip of camera frames with the targets the localizer
found. ``--no-vision`` steers on the true pose instead and shows dead
reckoning alone.
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from agvsim.commands._args import add_backend_flag, add_mount_flag, check_route, number
from agvsim.commands.capture import add_capture_flags, captures, check_capture_flags
from agvsim.commands._output import DistanceBar, add_json_flag, emit_json, log
from agvsim.sensors.registry import SOURCES
from agvsim.vehicle.encoders import PRESETS
from localizer.numeric import wrap_angle

DEFAULT_MAP = "plant_floor"


def register(sub) -> None:
    p = sub.add_parser("demo", help="drive the default route, camera and EKF correcting dead-reckoning drift",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("--map", default=DEFAULT_MAP, help="map name or YAML path (default: %(default)s)")
    p.add_argument("--route", default="default", help="route name (default: %(default)s)")
    p.add_argument("--odometry", default="typical", choices=PRESETS,
                   help="odometry error preset (default: %(default)s)")
    p.add_argument("--laps", type=number(0.0, low_open=True), default=1.0, help="passes of a loop route (default: %(default)s)")
    p.add_argument("--seed", type=number(0, integer=True), default=0, help="random seed (default: %(default)s)")
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder (default: %(default)s)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-vision", action="store_true",
                   help="no camera or filter: steer on the true pose and show dead reckoning alone")
    add_backend_flag(p)
    p.add_argument("--observations", default="rendered", choices=SOURCES,
                   help="what the camera reports (default: %(default)s, the renderer + localizer)")
    add_mount_flag(p)
    p.add_argument("--frames", type=number(0, integer=True), default=8,
                   help="camera frames in the strip along the route, 0 for none (default: %(default)s)")
    add_capture_flags(p, exports=True)
    add_json_flag(p)
    p.set_defaults(func=run)


def drift_table(distance, error, heading_error, estimate_error=None, rows: int = 10) -> list[dict[str, float]]:
    """Dead-reckoning (and estimate) error at ``rows`` evenly spaced distances (SI units)."""
    total = float(distance[-1]) if len(distance) else 0.0
    table = []
    for k in range(1, rows + 1):
        d = total * k / rows
        i = min(int(np.searchsorted(distance, d)), len(distance) - 1)
        row = {"distance_m": float(distance[i]), "position_error_m": float(error[i]),
               "error_share_of_distance": float(error[i] / max(distance[i], 1e-9)),
               "heading_error_rad": float(heading_error[i])}
        if estimate_error is not None:
            row["estimate_error_m"] = float(estimate_error[i])
        table.append(row)
    return table


def format_table(table: list[dict[str, float]]) -> str:
    with_estimate = "estimate_error_m" in table[0]
    head = f"{'distance (m)':>13} {'dead reckoning (m)':>19} {'% of distance':>14} {'heading error (deg)':>20}"
    lines = [head + (f" {'EKF estimate (m)':>17}" if with_estimate else "")]
    for row in table:
        line = (f"{row['distance_m']:13.1f} {row['position_error_m']:19.3f} "
                f"{100 * row['error_share_of_distance']:14.2f} {math.degrees(row['heading_error_rad']):20.2f}")
        if with_estimate:
            line += f" {row['estimate_error_m']:17.3f}"
        lines.append(line)
    return "\n".join(lines)


def run(args) -> int:
    from agvsim.world import load_map

    check_capture_flags(args)
    if args.no_vision and (args.record or args.export_log or args.export_bag):
        raise ValueError("--record, --export-log and --export-bag keep the camera's run: not with --no-vision")
    world_map = load_map(args.map)
    drive = _drive(args, world_map)
    files, strip = _pictures(args, world_map, drive)
    for flag in ("record", "export_log", "export_bag"):
        if getattr(args, flag) is not None:
            files[flag] = str(getattr(args, flag))
    result = _summary(args, world_map, drive, files, strip)
    if args.json:
        emit_json(result)
        return 0
    _print_summary(args, world_map, result, drive, strip)
    return 0


class _Drive(NamedTuple):
    """One demo drive: its log, the vision config, the errors against truth (m, rad: arrays over
    the log's steps; ``estimate_error`` None without vision) and the wall seconds it took."""

    log: object  # MissionLog
    vision: object  # VisionConfig
    error: np.ndarray  # (N,) dead reckoning's position error, m
    heading: np.ndarray  # (N,) dead reckoning's heading error, rad in [-pi, pi)
    estimate_error: np.ndarray | None  # (N,) the estimate's position error, m
    table: list  # drift_table's rows
    wall: float  # s
    rng: np.random.Generator  # the run's generator, after the drive (the camera strip draws on)


def _drive(args, world_map) -> _Drive:
    """The route driven as the flags say, with a progress bar in metres."""
    from agvsim.loop.mission import MissionConfig, run_mission
    from agvsim.loop.pure_pursuit import RoutePath
    from agvsim.sensors import VisionConfig, make_source
    from agvsim.vehicle.encoders import OdometryErrorModel
    from agvsim.vehicle.simulation import SimConfig

    path = RoutePath.from_route(world_map, check_route(world_map, args.route))
    total = path.length * (args.laps if path.loop else 1.0)
    config = SimConfig(odometry=OdometryErrorModel.preset(args.odometry))
    rng = np.random.default_rng(args.seed)
    log(f"agvsim demo: map {world_map.name!r}, route {args.route!r} ({total:.0f} m), "
        f"odometry {args.odometry!r}, seed {args.seed}")
    bar = DistanceBar(total, disable=args.no_progress)
    started = time.perf_counter()
    vision = VisionConfig(mount=args.camera_mount).for_map(world_map)
    estimate_error = None
    if args.no_vision:
        mission = MissionConfig(route=args.route, laps=args.laps, sim=config, vision_config=vision,
                                vision=False, steer_on="truth")
        run_log = run_mission(world_map, None, rng, mission, progress=bar.to)
    else:
        mission = MissionConfig(route=args.route, laps=args.laps, sim=config, vision_config=vision)
        options = {"backend": args.backend} if args.observations == "rendered" else {}
        source = make_source(args.observations, world_map, vision, **options)
        start = world_map.route(args.route)[0].pose
        with captures(args, world_map, start, f"seed-{args.seed}") as observer:
            run_log = run_mission(world_map, source, rng, mission, progress=bar.to, observer=observer)
        estimate_error = np.linalg.norm(run_log.estimate[:, :2] - run_log.true_pose[:, :2], axis=1)
    wall = time.perf_counter() - started
    if len(run_log.time) == 0:
        bar.finish(0.0)
        raise ValueError("the run produced no steps")
    bar.finish(float(run_log.distance[-1]))  # ends at the metres driven (the summary's "Drove ... m")
    error = np.linalg.norm(run_log.odometry_pose[:, :2] - run_log.true_pose[:, :2], axis=1)
    heading = wrap_angle(run_log.odometry_pose[:, 2] - run_log.true_pose[:, 2])
    table = drift_table(run_log.distance, error, heading, estimate_error)
    return _Drive(run_log, vision, error, heading, estimate_error, table, wall, rng)


def _pictures(args, world_map, drive: _Drive) -> tuple[dict, dict | None]:
    """The top-down view, the error plot and the camera strip written to ``args.out``: their
    paths by name, and the strip's record (None without frames)."""
    from agvsim.analysis.plots import error_vs_distance
    from agvsim.analysis.topdown import TopDownView, Trajectory

    run_log = drive.log
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    trajectories = [Trajectory(run_log.true_pose, (30, 150, 40), "true"),
                    Trajectory(run_log.odometry_pose, (210, 40, 40), "dead reckoning")]
    ellipses = ()
    series = {f"dead reckoning ({args.odometry})": drive.error}
    bound = None
    if drive.estimate_error is not None:
        estimate = run_log.estimate
        trajectories.append(Trajectory(estimate, (40, 90, 220), "EKF estimate"))
        every = max(1, len(estimate) // 40)
        ellipses = tuple((estimate[i, :2], 400.0 * run_log.covariance[i, :2, :2], (40, 90, 220))
                         for i in range(0, len(estimate), every))
        series["EKF estimate"] = drive.estimate_error
        bound = 2.0 * np.sqrt(np.clip(run_log.covariance[:, 0, 0] + run_log.covariance[:, 1, 1], 0, None))
    view = TopDownView(world_map)
    image = view.render(tuple(trajectories), vehicle_pose=tuple(run_log.true_pose[-1]), ellipses=ellipses,
                        ellipse_label="2σ position ellipse (x20)")
    topdown = TopDownView.save_png(image, out / "topdown.png")
    plot = error_vs_distance(out / "error_vs_distance.png", run_log.distance, series,
                             title=f"{world_map.name}: position error, {args.odometry} odometry, seed {args.seed}",
                             bound=bound)
    files = {"topdown": str(topdown), "error_plot": str(plot)}
    strip = None
    if args.frames > 0:
        from agvsim.sensors.render.strip import route_poses, save_camera_strip

        mount = drive.vision.mount  # the closed loop's camera
        strip = save_camera_strip(world_map, route_poses(world_map, args.frames, route=args.route, mount=mount),
                                  out / "camera_strip.png", mount=mount, rng=drive.rng)
        files["camera_strip"] = str(strip["path"])
    return files, strip


def _summary(args, world_map, drive: _Drive, files: dict, strip: dict | None) -> dict:
    """The run's figures (SI units), as ``--json`` prints them."""
    run_log, error, heading, estimate_error = drive.log, drive.error, drive.heading, drive.estimate_error
    result = {
        "map": world_map.name, "route": args.route, "odometry": args.odometry, "seed": args.seed,
        "completed": bool(run_log.completed), "distance_m": float(run_log.distance[-1]),
        "simulated_time_s": float(run_log.time[-1]), "wall_time_s": drive.wall,
        "final_position_error_m": float(error[-1]),
        "final_error_share_of_distance": float(error[-1] / run_log.distance[-1]),
        "max_position_error_m": float(error.max()),
        "final_heading_error_rad": float(heading[-1]),
        "collisions": run_log.collisions,
        "vision": not args.no_vision,
        "stations_reached": len(run_log.arrivals),
        "table": drive.table,
        "files": files,
    }
    if strip is not None:
        result["camera_frames"] = strip["frames"]
    if estimate_error is not None:
        result.update({
            "estimate_rmse_m": float(np.sqrt(np.mean(estimate_error ** 2))),
            "estimate_max_m": float(estimate_error.max()),
            "final_estimate_error_m": float(estimate_error[-1]),
            "frames": len(run_log.frames),
            "frames_with_accepted_observation": float(np.mean([f.accepted > 0 for f in run_log.frames]))
            if run_log.frames else 0.0,
            "lost_events": int(run_log.lost_events),
            "time_lost_s": run_log.time_lost(),
            "recoveries": int(run_log.relocalizations),
        })
    return result


def _print_summary(args, world_map, result: dict, drive: _Drive, strip: dict | None) -> None:
    """The summary a person reads (degrees and centimetres only here)."""
    print(f"Drove {result['distance_m']:.1f} m of route {args.route!r} on {world_map.name!r} in "
          f"{result['simulated_time_s']:.0f} s simulated ({drive.wall:.1f} s wall clock), "
          f"{result['stations_reached']} stations, {drive.log.collisions} collisions.")
    if drive.estimate_error is not None:
        print(f"Camera: {result['frames']} frames ({args.observations}), "
              f"{100 * result['frames_with_accepted_observation']:.0f} % with a target fused; "
              f"EKF estimate error RMSE {100 * result['estimate_rmse_m']:.1f} cm, "
              f"max {100 * result['estimate_max_m']:.1f} cm (ellipses: 2σ magnified 20x).")
        print(f"Localization: lost {result['lost_events']} times for {result['time_lost_s']:.1f} s in all, "
              f"recovered {result['recoveries']} times (re-localizations).")
    print(f"Dead reckoning ({args.odometry}) against truth:")
    print(format_table(drive.table))
    print(f"Wrote the top-down view to {result['files']['topdown']}")
    print(f"Wrote the error plot to   {result['files']['error_plot']}")
    if strip is not None:
        found = sum(len(f["found"]) for f in strip["frames"])
        visible = sum(len(f["visible"]) for f in strip["frames"])
        print(f"Wrote {len(strip['frames'])} camera frames to {strip['path']} "
              f"(localizer found {found} targets; {visible} visible in the frames)")
