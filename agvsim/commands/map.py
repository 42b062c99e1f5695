"""``agvsim map``: list the shipped maps, or check a map file.

    agvsim map list [--json]
    agvsim map check PATH_OR_NAME [--json]
    agvsim map mounts PATH_OR_NAME [--route R] [--step M] [--top N] [--json]

``check`` validates the map and prints its counts, bounds, routes and
whether the default route sees every target; a bad map prints the error
(file, field, value, expectation) and exits with status 2. ``mounts`` scans
camera mounts (yaw -90..90° in 10° steps, lens 0.3 m left, centred or 0.3 m
right) along a route and ranks them by the longest stretch with no target in
view (:mod:`agvsim.analysis.mount_scan`), beside the map's recommended mount.
"""
from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from agvsim.commands._args import check_route, number
from agvsim.commands._output import add_json_flag, emit_json

EXIT_BAD_MAP = 2


def register(sub) -> None:
    """Add the ``map`` command and its ``list``/``check`` subcommands."""
    parser = sub.add_parser("map", help="list the shipped maps or check a map file",
                            description="List the shipped maps, or check a map file.")
    map_sub = parser.add_subparsers(dest="map_command", metavar="ACTION", required=True)

    p_list = map_sub.add_parser("list", help="the shipped maps with a one-line summary",
                                description="List the shipped maps (from maps/, or $AGVSIM_MAPS_DIR).")
    add_json_flag(p_list)
    p_list.set_defaults(func=run_list)

    p_check = map_sub.add_parser(
        "check", help="validate a map and summarise it",
        description="Validate a map (a shipped name or a path to a .yaml file) and print a summary. "
                    "Exits 2 with the error on a bad map.")
    p_check.add_argument("map", metavar="PATH_OR_NAME", help="shipped map name or path to a .yaml file")
    add_json_flag(p_check)
    p_check.set_defaults(func=run_check)

    p_mounts = map_sub.add_parser(
        "mounts", help="rank camera mounts by how well they see the targets along a route",
        description="Scan camera mounts along a route and rank them by the longest stretch with no target "
                    "in view, then by the share of the route with one; the map's recommended mount beside.")
    p_mounts.add_argument("map", metavar="PATH_OR_NAME", help="shipped map name or path to a .yaml file")
    p_mounts.add_argument("--route", default="default", help="route name (default: %(default)s)")
    p_mounts.add_argument("--step", type=number(0.0, low_open=True, unit="m"), default=0.25, metavar="M",
                          help="sample spacing along the route, m (default: %(default)s)")
    p_mounts.add_argument("--top", type=number(1, integer=True), default=8, help="mounts listed (default: %(default)s)")
    add_json_flag(p_mounts)
    p_mounts.set_defaults(func=run_mounts)


# ---------------------------------------------------------------- list

def run_list(args: argparse.Namespace) -> int:
    from agvsim.world import MapError, load_map, maps_dir, shipped_maps

    rows = []
    for name in shipped_maps():
        try:
            summary = load_map(name).summary()
            rows.append({"name": name, "ok": True, **_brief(summary)})
        except (MapError, FileNotFoundError) as exc:
            rows.append({"name": name, "ok": False, "error": str(exc)})
    if args.json:
        emit_json({"maps_dir": str(maps_dir()), "maps": rows})
        return 0
    if not rows:
        print(f"no maps in {maps_dir()}")
    width = max((len(r["name"]) for r in rows), default=0)
    for row in rows:
        print(f"{row['name']:<{width}}  {_one_line(row)}")
    return 0


def _brief(summary: dict[str, Any]) -> dict[str, Any]:
    return {
        "size": summary["size"],
        "walls": summary["walls"],
        "obstacles": summary["obstacles"],
        "stations": summary["stations"],
        "targets": summary["targets"]["total"],
        "default_route_length": summary["routes"].get("default", {}).get("length"),
        "description": summary["description"],
    }


def _one_line(row: dict[str, Any]) -> str:
    if not row["ok"]:
        return f"BROKEN: {row['error']}"
    w, d = row["size"]
    route = row["default_route_length"]
    route_text = f", default route {route:.0f} m" if route is not None else ""
    return (f"{w:.1f} x {d:.1f} m, {row['walls']} walls, {row['obstacles']} obstacles, "
            f"{row['stations']} stations, {row['targets']} targets{route_text}")


# ---------------------------------------------------------------- check

def run_check(args: argparse.Namespace) -> int:
    from agvsim.world.checks import route_sightings
    from agvsim.world import MapError, load_map

    try:
        world = load_map(args.map)
    except (MapError, FileNotFoundError) as exc:
        if args.json:
            emit_json({"ok": False, "map": args.map, "error": str(exc)})
        else:
            print(f"agvsim map check: error: {exc}", file=sys.stderr)
        return EXIT_BAD_MAP
    summary = world.summary()
    if "default" in world.routes:
        seen = route_sightings(world, "default")
        summary["default_route_sightings"] = {
            "seen": sum(v is not None for v in seen.values()),
            "unseen": sorted(k for k, v in seen.items() if v is None),
        }
    if args.json:
        emit_json({"ok": True, **summary})
    else:
        print(format_summary(summary))
    return 0


def format_summary(s: dict[str, Any]) -> str:
    """The human-readable report of ``agvsim map check``."""
    xmin, ymin, xmax, ymax = s["bounds"]
    t = s["targets"]
    lines = [
        f"{s['name']}: OK ({s['source']})",
        f"  bounds     x {xmin:.2f} .. {xmax:.2f} m, y {ymin:.2f} .. {ymax:.2f} m "
        f"({s['size'][0]:.1f} x {s['size'][1]:.1f} m)",
        f"  walls      {s['walls']}",
        f"  obstacles  {s['obstacles']}",
        f"  stations   {s['stations']}",
        f"  targets    {t['total']} ({t['positive']} positive, {t['negative']} negative)",
        f"  lighting   default {s['lighting']['default']:g}; zones: " +
        (", ".join(f"{k} {v:g}" for k, v in s["lighting"]["zones"].items()) or "none"),
        f"  camera     forward {s['camera_mount']['forward']:g} m, lateral {s['camera_mount']['lateral']:g} m, "
        f"height {s['camera_mount']['height']:g} m, yaw {math.degrees(s['camera_mount']['yaw']):.0f} deg "
        "(recommended mount)",
        f"  routes     {len(s['routes'])}",
    ]
    for name, r in s["routes"].items():
        kind = "loop" if r["loop"] else "one way"
        lines.append(f"    {name:<16} {r['stations']:>3} stations, {r['length']:7.1f} m, {kind}")
    sight = s.get("default_route_sightings")
    if sight is not None:
        unseen = f"; unseen: {', '.join(sight['unseen'])}" if sight["unseen"] else ""
        lines.append(f"  default route sees {sight['seen']} of {t['total']} targets{unseen}")
    return "\n".join(lines)


# ---------------------------------------------------------------- mounts

def run_mounts(args: argparse.Namespace) -> int:
    import math

    from agvsim.analysis.mount_scan import candidate_mounts, scan_mounts
    from agvsim.world import MapError, load_map
    from localizer.numeric import check_number

    check_number("--top", args.top, low=1, integer=True)
    check_number("--step", args.step, low=0.0, low_open=True, unit="m")
    try:
        world = load_map(args.map)
    except (MapError, FileNotFoundError) as exc:
        print(f"agvsim map mounts: error: {exc}", file=sys.stderr)
        return EXIT_BAD_MAP
    check_route(world, args.route)
    rec = world.camera_mount
    yaws = [math.radians(d) for d in range(-90, 91, 10)]
    ranked = scan_mounts(world, candidate_mounts(yaws, (-0.3, 0.0, 0.3), rec.forward, rec.height),
                         route=args.route, step=args.step)
    current = scan_mounts(world, [rec], route=args.route, step=args.step)[0]
    if args.json:
        emit_json({"map": world.name, "route": args.route, "step_m": args.step,
                   "recommended": current.to_dict(), "ranked": [r.to_dict() for r in ranked[:args.top]]})
        return 0
    print(f"{world.name}, route {args.route!r}: camera mounts by the longest stretch with no target in view")
    print(f"{'':13}{'yaw (deg)':>10}{'lateral (m)':>12}{'in view':>9}{'longest gap (m)':>17}{'targets':>9}")
    for label, r in [("recommended", current)] + [(f"#{k + 1}", r) for k, r in enumerate(ranked[:args.top])]:
        print(f"{label:13}{math.degrees(r.mount.yaw):10.0f}{r.mount.lateral:12.2f}{100 * r.coverage:8.0f}%"
              f"{r.longest_gap:17.1f}{r.targets_seen:9d}")
    return 0
