"""``agvsim map``: list the shipped maps, or check a map file.

    agvsim map list [--json]
    agvsim map check PATH_OR_NAME [--json]

``check`` validates the map and prints its counts, bounds, routes and
whether the default route sees every target; a bad map prints the error
(file, field, value, expectation) and exits with status 2.
"""
from __future__ import annotations

import argparse
import sys
from typing import Any

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
