"""``agvsim demo``: drive the default route of the default map and show how
dead reckoning drifts, and what the camera sees.

The vehicle follows the route with pure pursuit steering on its *true* pose
(the camera and the filter come later), with ``typical`` odometry. It prints
a progress bar, a table of dead-reckoning error against distance, and writes
a top-down picture, an error plot and a strip of rendered camera frames
along the route with the targets the localizer found.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

from agvsim.commands._output import add_json_flag, emit_json, log

DEFAULT_MAP = "plant_floor"


def register(sub) -> None:
    p = sub.add_parser("demo", help="drive the default route and report dead-reckoning drift",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("--map", default=DEFAULT_MAP, help="map name or YAML path (default: %(default)s)")
    p.add_argument("--route", default="default", help="route name (default: %(default)s)")
    p.add_argument("--odometry", default="typical", choices=("ideal", "typical", "worn"),
                   help="odometry error preset (default: %(default)s)")
    p.add_argument("--laps", type=float, default=1.0, help="passes of a loop route (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder (default: %(default)s)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--frames", type=int, default=8,
                   help="camera frames in the strip along the route, 0 for none (default: %(default)s)")
    add_json_flag(p)
    p.set_defaults(func=run)


def drift_table(distance, error, heading_error, rows: int = 10) -> list[dict[str, float]]:
    """Dead-reckoning error at ``rows`` evenly spaced distances (SI units)."""
    import numpy as np

    total = float(distance[-1]) if len(distance) else 0.0
    table = []
    for k in range(1, rows + 1):
        d = total * k / rows
        i = min(int(np.searchsorted(distance, d)), len(distance) - 1)
        table.append({"distance_m": float(distance[i]), "position_error_m": float(error[i]),
                      "error_share_of_distance": float(error[i] / max(distance[i], 1e-9)),
                      "heading_error_rad": float(heading_error[i])})
    return table


def format_table(table: list[dict[str, float]]) -> str:
    lines = [f"{'distance (m)':>13} {'position error (m)':>19} {'% of distance':>14} {'heading error (deg)':>20}"]
    for row in table:
        lines.append(f"{row['distance_m']:13.1f} {row['position_error_m']:19.3f} "
                     f"{100 * row['error_share_of_distance']:14.2f} {math.degrees(row['heading_error_rad']):20.2f}")
    return "\n".join(lines)


def run(args) -> int:
    import numpy as np
    from tqdm import tqdm

    from agvsim.control.pure_pursuit import RoutePath
    from agvsim.plots import error_vs_distance
    from agvsim.runner import drive_route
    from agvsim.simulation import SimConfig
    from agvsim.vehicle.encoders import OdometryErrorModel
    from agvsim.views import TopDownView, Trajectory
    from agvsim.world.map import load_map

    world_map = load_map(args.map)
    if not math.isfinite(args.laps) or args.laps <= 0:
        raise ValueError(f"--laps must be a positive number, got {args.laps}")
    path = RoutePath.from_route(world_map, args.route)
    total = path.length * (args.laps if path.loop else 1.0)
    config = SimConfig(odometry=OdometryErrorModel.preset(args.odometry))
    rng = np.random.default_rng(args.seed)
    log(f"agvsim demo: map {world_map.name!r}, route {args.route!r} ({total:.0f} m), "
        f"odometry {args.odometry!r}, seed {args.seed}")
    bar = tqdm(total=round(total), unit="m", desc="driving", disable=args.no_progress, leave=False)
    last = [0]

    def progress(s: float) -> None:
        step = int(s) - last[0]
        if step > 0:
            bar.update(step)
            last[0] += step

    started = time.perf_counter()
    run_log = drive_route(world_map, rng, route=args.route, config=config, laps=args.laps, progress=progress)
    wall = time.perf_counter() - started
    bar.close()
    if len(run_log.time) == 0:
        raise ValueError("the run produced no steps")
    error = run_log.odometry_error()
    heading = run_log.odometry_heading_error()
    table = drift_table(run_log.distance, error, heading)

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    view = TopDownView(world_map)
    image = view.render((Trajectory(run_log.true_pose, (30, 150, 40), "true"),
                         Trajectory(run_log.odometry_pose, (210, 40, 40), "dead reckoning")),
                        vehicle_pose=tuple(run_log.true_pose[-1]))
    topdown = TopDownView.save_png(image, out / "topdown.png")
    plot = error_vs_distance(out / "error_vs_distance.png", run_log.distance,
                             {f"dead reckoning ({args.odometry})": error},
                             title=f"{world_map.name}: dead-reckoning error, seed {args.seed}")
    files = {"topdown": str(topdown), "error_plot": str(plot)}
    strip = None
    if args.frames > 0:
        from agvsim.render.mount import CameraMount
        from agvsim.render.strip import route_poses, save_camera_strip

        mount = CameraMount.side_looking("right")  # the route circles counter-clockwise: targets on the right
        strip = save_camera_strip(world_map, route_poses(world_map, args.frames, route=args.route, mount=mount),
                                  out / "camera_strip.png", mount=mount, rng=rng)
        files["camera_strip"] = str(strip["path"])
    result = {
        "map": world_map.name, "route": args.route, "odometry": args.odometry, "seed": args.seed,
        "completed": bool(run_log.completed), "distance_m": float(run_log.distance[-1]),
        "simulated_time_s": float(run_log.time[-1]), "wall_time_s": wall,
        "final_position_error_m": float(error[-1]),
        "final_error_share_of_distance": float(error[-1] / run_log.distance[-1]),
        "max_position_error_m": float(error.max()),
        "final_heading_error_rad": float(heading[-1]),
        "collisions": run_log.collisions,
        "stations_reached": len(run_log.arrivals),
        "table": table,
        "files": files,
    }
    if strip is not None:
        result["camera_frames"] = strip["frames"]
    if args.json:
        emit_json(result)
        return 0
    print(f"Drove {result['distance_m']:.1f} m of route {args.route!r} on {world_map.name!r} in "
          f"{result['simulated_time_s']:.0f} s simulated ({wall:.1f} s wall clock), "
          f"{result['stations_reached']} stations, {run_log.collisions} collisions.")
    print(f"Dead reckoning ({args.odometry}) against truth:")
    print(format_table(table))
    print(f"Wrote the top-down view to {topdown}")
    print(f"Wrote the error plot to   {plot}")
    if strip is not None:
        found = sum(len(f["found"]) for f in strip["frames"])
        visible = sum(len(f["visible"]) for f in strip["frames"])
        print(f"Wrote {len(strip['frames'])} camera frames to {strip['path']} "
              f"(localizer found {found} targets; {visible} visible in the frames)")
    return 0
