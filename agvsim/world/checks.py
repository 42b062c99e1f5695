"""Whole-map checks: can the floor be built, driven and seen as described?

Run by the loader after every field has been read. Each check raises a
:class:`~agvsim.world.fields.MapError` pointing at the field to fix. The
vehicle is the 1.0 x 0.7 m AGV; its half-diagonal is 0.61 m, so
stations and route legs keep :data:`VEHICLE_CLEARANCE` from every solid.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from agvsim.world.fields import Context

if TYPE_CHECKING:  # pragma: no cover
    from agvsim.world.map import Map

#: Free space (m) a target needs straight in front of its face.
TARGET_FACING_CLEARANCE = 0.5
#: Least distance (m) between two stations.
STATION_SPACING = 1.0
#: Least free distance (m) from a station or a route leg to a wall surface or obstacle.
VEHICLE_CLEARANCE = 0.6


def check_map(ctx: Context, world: "Map") -> None:
    """Run every whole-map check, in file order of the sections they concern."""
    check_targets(ctx, world)
    check_stations(ctx, world)
    check_routes(ctx, world)


# ---------------------------------------------------------------- targets

def check_targets(ctx: Context, world: "Map") -> None:
    """Each target fits its wall, faces free floor, and overlaps no other target."""
    for i, target in enumerate(world.targets):
        path = f"targets[{i}]"
        _check_target_height(ctx, path, target, world.wall(target.wall))
        _check_target_facing(ctx, path, target, world)
        for j, other in enumerate(world.targets[:i]):
            if _overlap(target, other):
                raise ctx.error(f"{path}.at", f"target overlaps targets[{j}] ({other.id!r}) "
                                f"on wall {target.wall!r}", target.at,
                                "targets on the same face of a wall not to overlap")


def _check_target_height(ctx: Context, path: str, target, wall) -> None:
    half = 0.5 * target.spec.outer_height
    if target.height + half > wall.height + 1e-9:
        raise ctx.error(f"{path}.height", f"target taller than its wall: its top would be at "
                        f"{target.height + half:.3f} m on wall {wall.id!r} ({wall.height:.3f} m high)",
                        target.height, f"<= {wall.height - half:.3f} m (wall height - half the target)")
    if target.height - half < -1e-9:
        raise ctx.error(f"{path}.height", "target reaches below the floor", target.height,
                        f">= {half:.3f} m (half the target's {target.spec.outer_height:.3f} m height)")


def _check_target_facing(ctx: Context, path: str, target, world: "Map") -> None:
    """Free space for :data:`TARGET_FACING_CLEARANCE` in front, and a floor beyond."""
    start = np.asarray(target.position, dtype=float)
    normal = np.asarray(target.normal, dtype=float)
    near = world.solids.blocker(start, start + TARGET_FACING_CLEARANCE * normal)
    if near is not None:
        raise ctx.error(f"{path}.side", f"target faces into {near!r}: it is within "
                        f"{TARGET_FACING_CLEARANCE} m in front of the target", target.side,
                        f"a side facing at least {TARGET_FACING_CLEARANCE} m of free floor")
    xmin, ymin, xmax, ymax = world.bounds
    reach = float(np.hypot(xmax - xmin, ymax - ymin)) + 1.0
    if world.solids.blocker(start, start + reach * normal) is None:
        raise ctx.error(f"{path}.side", "target faces out of the floor: straight ahead of it "
                        "there is no wall or obstacle before the map's edge", target.side,
                        "the side of the wall that faces the floor")


def _overlap(a, b) -> bool:
    """Whether two targets on the same wall face overlap (along the wall and in height)."""
    if a.wall != b.wall or a.side != b.side:
        return False
    along = abs(a.at - b.at) < 0.5 * (a.spec.outer_width + b.spec.outer_width)
    up = abs(a.height - b.height) < 0.5 * (a.spec.outer_height + b.spec.outer_height)
    return along and up


# ---------------------------------------------------------------- stations

def check_stations(ctx: Context, world: "Map") -> None:
    """Stations are apart from each other and leave room for the vehicle."""
    positions = [s.position for s in world.stations]
    for i, station in enumerate(world.stations):
        path = f"stations[{i}].pose"
        for j in range(i):
            gap = float(np.linalg.norm(positions[i] - positions[j]))
            if gap < STATION_SPACING:
                raise ctx.error(path, f"overlapping stations: {gap:.3f} m from stations[{j}] "
                                f"({world.stations[j].id!r})", list(station.pose),
                                f"stations at least {STATION_SPACING} m apart")
        clearance, solid = world.solids.point_clearance(positions[i])
        if clearance < VEHICLE_CLEARANCE:
            where = f"inside {solid!r}" if clearance < 0 else f"{clearance:.3f} m from {solid!r}"
            raise ctx.error(path, f"station too close for the vehicle: {where}", list(station.pose),
                            f">= {VEHICLE_CLEARANCE} m from every wall surface and obstacle")


# ---------------------------------------------------------------- routes

def check_routes(ctx: Context, world: "Map") -> None:
    """Every straight leg between consecutive stations leaves room for the vehicle."""
    for name, ids in world.routes.items():
        for k in range(1, len(ids)):
            a = world.station(ids[k - 1]).position
            b = world.station(ids[k]).position
            clearance, solid = world.solids.segment_clearance(a, b)
            if clearance < VEHICLE_CLEARANCE:
                how = f"crosses {solid!r}" if clearance <= 0.0 else f"passes {clearance:.3f} m from {solid!r}"
                raise ctx.error(f"routes.{name}[{k}]", f"route leg {ids[k - 1]} -> {ids[k]} {how}", ids[k],
                                f"legs at least {VEHICLE_CLEARANCE} m from every wall surface and obstacle "
                                "(add a station to go around)")


# ---------------------------------------------------------------- sightings

#: A camera on the AGV sees a target from this range of distances (m) ...
SIGHT_RANGE = (1.5, 8.0)
#: ... and within this angle (rad) of the target's normal (55°).
SIGHT_HALF_ANGLE = np.deg2rad(55.0)


def route_points(world: "Map", route: str = "default", step: float = 0.1) -> np.ndarray:
    """``(P, 2)`` points along a route's straight legs, about ``step`` m apart (m)."""
    stations = np.array([s.position for s in world.route(route)])
    pieces = []
    for a, b in zip(stations[:-1], stations[1:]):
        n = max(int(np.ceil(np.linalg.norm(b - a) / step)), 1)
        pieces.append(a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a))
    return np.concatenate(pieces)


def route_sightings(world: "Map", route: str = "default", step: float = 0.1) -> dict[str, float | None]:
    """For each target, how close the route comes to seeing it well.

    A route point *sees* a target when it lies :data:`SIGHT_RANGE` in front
    of the target's face, within :data:`SIGHT_HALF_ANGLE` of its normal, with
    no wall or obstacle crossing the line between them.

    Returns:
        target id -> distance (m) from the target to the nearest route point
        that sees it, or None if no point does.
    """
    pts = route_points(world, route, step)
    seen: dict[str, float | None] = {}
    for target in world.targets:
        offsets = pts - target.position
        dist = np.linalg.norm(offsets, axis=1)
        cos = (offsets @ target.normal) / np.maximum(dist, 1e-12)
        ok = (dist >= SIGHT_RANGE[0]) & (dist <= SIGHT_RANGE[1]) & (cos >= np.cos(SIGHT_HALF_ANGLE))
        seen[target.id] = None
        for i in np.nonzero(ok)[0][np.argsort(dist[ok])]:
            if world.solids.blocker(target.position, pts[i]) is None:
                seen[target.id] = float(dist[i])
                break
    return seen
