"""agvsim plan: where to hang targets so that the predicted position error stays within a budget.

``agvsim plan MAP --max-error 0.10 --out NEW_MAP.yaml`` proposes target placements on the map's
walls (position along the wall, centre height, polarity) with as few targets as it can, so
that the filter's predicted position error bound (3σ) stays within ``--max-error`` along the
route (prediction without rendering: :mod:`agvsim.deploy.predict`; greedy selection then
pruning: :mod:`agvsim.deploy.planner`). By default the map's targets are replaced;
``--keep-targets`` keeps them and adds to them. Writes the new map (its targets marked
``# planned``), a picture of the floor with the route coloured by the predicted 3σ
(``NEW_MAP.png``) and a report (``NEW_MAP.plan.json``). ``--verify`` then drives the new map
as ``agvsim drift`` does and prints the predicted bound beside the measured errors.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

from agvsim.commands._args import check_route, number
from agvsim.commands._output import add_json_flag, doc_help, emit_json, log, plural
from agvsim.files import write_json
from agvsim.vehicle.encoders import PRESETS

__all__ = ["register", "run"]


def register(sub) -> None:
    p = sub.add_parser("plan", help="propose where to hang targets for a position-error budget",
                       description=doc_help(__doc__))
    p.add_argument("map", metavar="MAP", help="map name or YAML path")
    p.add_argument("--route", default="default", help="route name (default: %(default)s)")
    p.add_argument("--odometry", default="typical", choices=PRESETS, help="odometry error preset (default: %(default)s)")
    p.add_argument("--max-error", type=number(0.0, low_open=True, unit="m"), default=0.10,
                   help="budget on the predicted position error bound 3σ along the route, m (default: %(default)s)")
    p.add_argument("--keep-targets", action="store_true", help="keep the map's targets and add to them")
    p.add_argument("--forbid", nargs="+", default=(), metavar="WALL[:SIDE]",
                   help="wall faces where no target may hang: a wall id, or WALL:left / WALL:right (default: none)")
    p.add_argument("--min-spacing", type=number(0.0, unit="m"), default=2.0,
                   help="least distance between two targets, m (default: %(default)s)")
    p.add_argument("--step", type=number(0.05, 10.0, unit="m"), default=0.5,
                   help="spacing of the candidate places along a wall, m (default: %(default)s)")
    p.add_argument("--camera-rate", type=number(0.0, 100.0, low_open=True, unit="Hz"), default=4.0,
                   help="camera frames per second (default: %(default)s)")
    p.add_argument("--out", type=Path, required=True, help="the new map (YAML); the picture and report go beside it")
    p.add_argument("--verify", action="store_true", help="drive the new map (as agvsim drift) and print measured beside predicted")
    p.add_argument("--verify-seeds", type=number(1, integer=True), default=10, help="--verify: seeds (default: %(default)s)")
    p.add_argument("--verify-distance", type=number(0.0, low_open=True, unit="m"), default=1000.0,
                   help="--verify: metres per seed (default: %(default)s)")
    p.add_argument("--workers", type=number(1, integer=True), default=None, help="--verify: worker processes (default: the cores)")
    add_json_flag(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from agvsim.deploy.candidates import candidate_targets, parse_faces
    from agvsim.deploy.layout_files import draw_plan, write_map
    from agvsim.deploy.planner import plan_targets
    from agvsim.deploy.predict import RouteModel
    from agvsim.world import load_map

    if args.out.suffix not in (".yaml", ".yml"):
        raise ValueError(f"--out {str(args.out)!r}: expected a .yaml file name")
    world_map = load_map(args.map)
    check_route(world_map, args.route)
    forbid = parse_faces(args.forbid, world_map)
    started = time.perf_counter()
    model = RouteModel(world_map, args.route, args.odometry, camera_rate=args.camera_rate)
    keep = tuple(world_map.targets) if args.keep_targets else ()
    candidates = candidate_targets(world_map, height=model.vision.mount.height, step=args.step, forbid=forbid,
                                   keep=keep, min_spacing=args.min_spacing)
    log(f"agvsim plan: map {world_map.name!r}, route {args.route!r} ({model.path.length:.0f} m, a frame every "
        f"{model.step:.2f} m), {args.odometry} odometry, budget 3σ <= {100 * args.max_error:g} cm; "
        f"{plural(len(candidates), 'candidate place')}, {plural(len(keep), 'target')} kept")
    plan = plan_targets(model, candidates, keep=keep, budget=args.max_error, min_spacing=args.min_spacing,
                        progress=lambda r, w: log(f"  round {r}: worst predicted 3σ {100 * w:.1f} cm"))
    seconds = time.perf_counter() - started
    picture = args.out.with_suffix(".png")
    report_path = args.out.with_suffix(".plan.json")
    header = (f"{args.out.stem}: {world_map.name} with targets placed by `agvsim plan` ({len(plan.placed)} placed, "
              f"{len(keep)} kept);\nbudget: predicted 3σ <= {100 * args.max_error:g} cm along route "
              f"{args.route!r} with {args.odometry} odometry; predicted worst 3σ {100 * plan.worst_bound:.1f} cm.")
    write_map(world_map, plan.targets, set(plan.placed), args.out, header)
    new_map = load_map(str(args.out))
    draw_plan(picture, new_map, plan, model,
              f"{new_map.name}: {len(plan.targets)} targets ({len(plan.placed)} placed), predicted worst 3σ "
              f"{100 * plan.worst_bound:.1f} cm (budget {100 * args.max_error:g} cm), {args.odometry} odometry")
    report = {"map": str(args.out), "source_map": world_map.name, "route": args.route, "odometry": args.odometry,
              "budget_m": args.max_error, "met": plan.met, "targets": len(plan.targets), "placed": len(plan.placed),
              "kept": len(keep), "placed_ids": list(plan.placed),
              "predicted_worst_3sigma_m": plan.worst_bound, "predicted_max_sigma_m": float(plan.sigma.max()),
              "predicted_mean_sigma_m": float(plan.sigma.mean()), "longest_blind_m": plan.longest_blind,
              "candidates_seen": plan.candidates, "rounds": plan.rounds, "planning_s": seconds,
              "picture": str(picture)}
    if not plan.met:
        log(f"agvsim plan: the budget of {100 * args.max_error:g} cm is out of reach here: the closest is a "
            f"predicted worst 3σ of {100 * plan.worst_bound:.1f} cm with {plural(len(plan.targets), 'target')} "
            "(the map written has that layout)")
    if args.verify:
        report["verify"] = _verify(args, plan)
    write_json(report_path, report)
    report["report"] = str(report_path)
    if args.json:
        emit_json(report)
    else:
        print(f"{len(plan.targets)} targets ({len(plan.placed)} placed, {len(keep)} kept); predicted 3σ worst "
              f"{100 * plan.worst_bound:.1f} cm (budget {100 * args.max_error:g} cm: {'met' if plan.met else 'NOT met'}), "
              f"mean σ {100 * plan.sigma.mean():.2f} cm; longest blind stretch {plan.longest_blind:.1f} m; "
              f"planned in {seconds:.1f} s")
        if "verify" in report:
            v = report["verify"]
            print(f"verify ({v['seeds']} seeds x {v['distance_m']:g} m, {v['observations']}): measured max error "
                  f"{100 * v['measured_max_m']:.1f} cm, RMSE {100 * v['measured_rmse_m']:.2f} cm; predicted worst 3σ "
                  f"{100 * plan.worst_bound:.1f} cm (ratio {v['predicted_over_measured']:.2f})")
        print(f"files: {args.out}, {picture}, {report_path}")
    return 0 if plan.met else 1


def _verify(args, plan) -> dict:
    """Drive the new map for ``--verify-seeds`` seeds (the drive of ``agvsim drift``, rendered frames)."""
    import os

    import numpy as np

    from agvsim.commands.workers import run_units
    from agvsim.loop.drive import DriveSettings
    from agvsim.sweep.runs import run_unit

    settings = DriveSettings(map=str(args.out.resolve()), route=args.route, distance=args.verify_distance,
                             odometry=args.odometry, camera_rate=args.camera_rate)
    units = [{"key": f"s{seed}", "point": 0, "seed": seed, "values": {}, "settings": settings}
             for seed in range(args.verify_seeds)]
    rows: list[dict] = []
    workers = max(1, min(args.workers or os.cpu_count() or 1, len(units)))
    log(f"agvsim plan --verify: {plural(len(units), 'seed')} x {args.verify_distance:g} m on rendered frames, "
        f"{plural(workers, 'worker')}")
    run_units(run_unit, units, workers, lambda key, row: rows.append(row), lambda _: None)
    failed = [r for r in rows if r["status"] != "ok"]
    if failed:
        raise ValueError(f"--verify: {len(failed)} drives failed: {failed[0]['error']}")
    measured_max = max(r["position_max_m"] for r in rows)
    rmse = math.sqrt(np.mean([r["position_rmse_m"] ** 2 for r in rows]))
    return {"seeds": len(rows), "distance_m": args.verify_distance, "observations": "rendered",
            "measured_max_m": measured_max, "measured_rmse_m": rmse,
            "nees_in_bounds": float(np.mean([r["nees_in_bounds"] for r in rows])),
            "lost": int(sum(r["lost"] for r in rows)),
            "predicted_over_measured": plan.worst_bound / measured_max if measured_max > 0 else math.inf}
