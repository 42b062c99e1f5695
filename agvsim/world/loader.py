"""Reading plant-floor maps from YAML: :func:`load_map`, :func:`map_from_dict`.

:func:`load_map` reads and checks everything; every problem is a
:class:`MapError` naming the file, the field (``targets[3].height``), the bad
value and what was expected. The geometric checks live in
:mod:`agvsim.world.checks`; the data model in :mod:`agvsim.world.map`.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from agvsim.world import checks
from agvsim.world import fields as f
from agvsim.world import geometry as geo
from agvsim.world.fields import MapError
from agvsim.world.files import MAP_SUFFIXES, maps_dir, resolve_map_path, shipped_maps
from agvsim.world.map import DEFAULT_SURFACE, DEFAULT_WALL_HEIGHT, LightingZone, Map, MapTarget, Obstacle, Station, Wall
from localizer.model.mount import CameraMount
from localizer.model.target import POLARITIES, TargetSpec

__all__ = ["MAP_SUFFIXES", "MapError", "load_map", "map_from_dict", "maps_dir", "resolve_map_path", "shipped_maps"]

#: Target sides: "left"/"right" of the wall's direction of travel (first point -> last).
SIDES: tuple[str, ...] = ("left", "right")


def load_map(name_or_path: str | os.PathLike) -> Map:
    """Read and check a map: a shipped name (``"plant_floor"``) or a path to a YAML file.

    Raises:
        FileNotFoundError: no such map.
        MapError: the file is malformed or describes an impossible floor.
    """
    path = resolve_map_path(name_or_path)
    ctx = f.Context(str(path))
    data = f.parse_yaml(ctx, f.read_map_file(ctx, path))
    return _build(ctx, data, default_name=path.stem, source=path)



def map_from_dict(data: Any, *, name: str = "map", source: str | None = None) -> Map:
    """Build and check a map from already-parsed YAML data (same schema as the files).

    Args:
        data: the mapping a map file would parse to.
        name: the map's name if ``data`` has none.
        source: label used as the file in error messages (default ``"<map>"``).
    """
    ctx = f.Context(source or "<map>")
    return _build(ctx, data, default_name=name, source=Path(source) if source else None)


# ====================================================================== schema
# Each reader checks one raw YAML value at a field path. `f.expects` records
# what a missing required key should have been, for the error message.

@f.expects("a finite number, m")
def _signed_length(ctx, path, raw):
    return f.number(ctx, path, raw, "m")


@f.expects("a number >= 0, rad")
def _non_negative_angle(ctx, path, raw):
    return f.number(ctx, path, raw, "rad", non_negative=True)


@f.expects("a positive number, m")
def _length(ctx, path, raw):
    return f.number(ctx, path, raw, "m", positive=True)


@f.expects("a number >= 0, m")
def _distance(ctx, path, raw):
    return f.number(ctx, path, raw, "m", non_negative=True)


@f.expects("a positive number (relative illumination, 1.0 = normal)")
def _level(ctx, path, raw):
    return f.number(ctx, path, raw, "relative illumination, 1.0 = normal", positive=True)


@f.expects("a string id")
def _id(ctx, path, raw):
    return f.identifier(ctx, path, raw)


@f.expects("a word such as painted, concrete, brick, door, poster, glass")
def _surface(ctx, path, raw):
    return f.identifier(ctx, path, raw)


@f.expects("a word such as rack, machine, pillar, pallet")
def _kind(ctx, path, raw):
    return f.identifier(ctx, path, raw)


@f.expects("a string")
def _text(ctx, path, raw):
    return f.text(ctx, path, raw)


@f.expects("a list of at least 2 points [x, y] in m")
def _polyline(ctx, path, raw):
    pts = f.points(ctx, path, raw, 2, "a list of at least 2 points [x, y] in m")
    steps = pts[1:] - pts[:-1]
    repeats = np.flatnonzero(np.hypot(steps[:, 0], steps[:, 1]) <= geo.EPS)
    if repeats.size:
        i = int(repeats[0])
        raise ctx.error(f.join(path, i + 1), "repeats the previous point", raw[i + 1],
                        "consecutive points at different places")
    return f.readonly(pts)


@f.expects("a list of at least 3 points [x, y] in m")
def _polygon(ctx, path, raw):
    pts = f.points(ctx, path, raw, 3, "a list of at least 3 points [x, y] in m")
    crossing = geo.polygon_self_intersection(pts)
    if crossing is not None:
        i, j = crossing
        raise ctx.error(path, f"self-intersecting polygon: edge {i} meets edge {j}", raw,
                        "a simple polygon (edges meet only at shared corners)")
    if abs(geo.polygon_signed_area(pts)) <= geo.EPS:
        raise ctx.error(path, "polygon has no area", raw, "at least 3 points not on one line")
    if geo.polygon_signed_area(pts) < 0.0:
        pts = pts[::-1].copy()  # store counter-clockwise
    return f.readonly(pts)


@f.expects("{center: [x, y], size: [w, d], yaw: rad}")
def _box(ctx, path, raw):
    box = f.mapping(ctx, path, raw, _BOX_READERS, required=("center", "size"),
                    what="a mapping {center: [x, y], size: [w, d], yaw: rad}")
    poly = geo.box_polygon(box["center"], box["size"], box.get("yaw", 0.0))
    return f.readonly(poly)


@f.expects("[x, y] in m")
def _center(ctx, path, raw):
    return f.point(ctx, path, raw)


@f.expects("[w, d]: positive sizes in m along the box's own x and y")
def _size(ctx, path, raw):
    size = f.vector(ctx, path, raw, 2, "[w, d] in m", "m")
    for i, v in enumerate(size):
        if v <= 0.0:
            raise ctx.error(f.join(path, i), "must be positive", raw[i], "a positive size, m")
    return size


@f.expects("an angle in rad (CCW from +x)")
def _angle(ctx, path, raw):
    return f.number(ctx, path, raw, "rad")


@f.expects("[x, y, theta]: m, m, rad")
def _pose(ctx, path, raw):
    return tuple(float(v) for v in f.vector(ctx, path, raw, 3, "[x, y, theta] in m, m, rad"))


@f.expects("'left' or 'right'")
def _side(ctx, path, raw):
    return f.choice(ctx, path, raw, SIDES)


@f.expects("'positive' or 'negative'")
def _polarity(ctx, path, raw):
    return f.choice(ctx, path, raw, POLARITIES)


@f.expects("{bar_width: m} (thesis proportions), optionally bar_height and margin in m")
def _target_size(ctx, path, raw):
    size = f.mapping(ctx, path, raw, _SIZE_READERS, required=("bar_width",),
                     what="a mapping {bar_width: m, bar_height: m, margin: m}")
    spec = TargetSpec.from_bar_width(size["bar_width"])
    return TargetSpec(bar_width=spec.bar_width,
                      bar_height=size.get("bar_height", spec.bar_height),
                      margin=size.get("margin", spec.margin))


@f.expects("a list of station ids (at least 2)")
def _station_ids(ctx, path, raw):
    items = f.sequence(ctx, path, raw, "a list of station ids", min_len=2)
    return tuple(f.identifier(ctx, f.join(path, i), s) for i, s in enumerate(items))


_BOX_READERS = {"center": _center, "size": _size, "yaw": _angle}
_SIZE_READERS = {"bar_width": _length, "bar_height": _length, "margin": _distance}
_WALL_READERS = {"id": _id, "points": _polyline, "thickness": _length, "height": _length,
                 "surface": _surface}
_OBSTACLE_READERS = {"id": _id, "kind": _kind, "box": _box, "polygon": _polygon, "height": _length}
_STATION_READERS = {"id": _id, "pose": _pose}
_ZONE_READERS = {"id": _id, "box": _box, "polygon": _polygon, "level": _level}
_TARGET_READERS = {"id": _id, "wall": _id, "at": _distance, "side": _side, "height": _length,
                   "polarity": _polarity, "size": _target_size}

#: Keys a `defaults:` block may set for each section.
_DEFAULTABLE = {
    "wall": ("thickness", "height", "surface"),
    "obstacle": ("kind", "height"),
    "target": ("side", "height", "polarity", "size"),
}
_SECTION_READERS = {"wall": _WALL_READERS, "obstacle": _OBSTACLE_READERS, "target": _TARGET_READERS}


def _ignore(ctx, path, raw):
    return raw


_MOUNT_READERS = {"forward": _signed_length, "lateral": _signed_length, "height": _length, "yaw": _angle,
                  "pitch_sigma": _non_negative_angle, "roll_sigma": _non_negative_angle}


@f.expects("a mapping with keys forward, lateral, height, yaw (m, m, m, rad)")
def _camera_mount(ctx, path, raw):
    fields_ = f.mapping(ctx, path, raw, _MOUNT_READERS, required=("forward", "lateral", "height", "yaw"),
                        what="a mapping with keys forward, lateral, height, yaw (m, m, m, rad)")
    return CameraMount(**fields_)


_TOP_KEYS = {"name": _id, "description": _text, "defaults": _ignore, "walls": _ignore,
             "obstacles": _ignore, "stations": _ignore, "routes": _ignore, "lighting": _ignore,
             "targets": _ignore, "camera_mount": _camera_mount}


# ====================================================================== building

def _build(ctx: f.Context, data: Any, *, default_name: str, source: Path | None) -> Map:
    """Raw YAML data -> a checked Map."""
    if data is None:
        raise ctx.error("", "empty map: the file has no content", expected="a mapping with at least `walls:`")
    top = f.mapping(ctx, "", data, _TOP_KEYS, what="a mapping with keys walls, obstacles, stations, ...")
    defaults = _read_defaults(ctx, data.get("defaults") or {})
    walls = _read_walls(ctx, data.get("walls"), defaults["wall"])
    obstacles = _read_obstacles(ctx, data.get("obstacles"), defaults["obstacle"])
    stations = _read_stations(ctx, data.get("stations"))
    lighting_default, zones = _read_lighting(ctx, data.get("lighting") or {})
    target_fields = _read_target_fields(ctx, data.get("targets"), defaults["target"])
    _check_unique_ids(ctx, walls, obstacles, stations, zones, target_fields)
    targets = tuple(_make_target(ctx, f"targets[{i}]", t, walls) for i, t in enumerate(target_fields))
    routes = _read_routes(ctx, data.get("routes") or {}, stations)
    world = Map(
        name=top.get("name", default_name),
        source=source,
        description=top.get("description", ""),
        walls=walls,
        obstacles=obstacles,
        stations=stations,
        routes=routes,
        lighting_default=lighting_default,
        lighting_zones=zones,
        targets=targets,
        bounds=_bounds(ctx, walls, obstacles),
        camera_mount=top.get("camera_mount", CameraMount()),
    )
    checks.check_map(ctx, world)
    return world


def _read_list(ctx: f.Context, path: str, raw: Any, read_item) -> list:
    """Read an optional YAML list section with ``read_item(path, raw_item)``."""
    if raw is None:
        return []
    items = f.sequence(ctx, path, raw, f"a list of {path}")
    return [read_item(f.join(path, i), item) for i, item in enumerate(items)]


def _merged(defaults: dict[str, Any], raw: Any) -> Any:
    """An item's raw mapping with the section's defaults under it (non-mappings untouched)."""
    return {**defaults, **raw} if isinstance(raw, dict) else raw


def _read_defaults(ctx: f.Context, raw: Any) -> dict[str, dict[str, Any]]:
    """The `defaults:` block: section -> raw key -> value, each value checked here."""
    f.mapping(ctx, "defaults", raw, {section: _ignore for section in _DEFAULTABLE},
              what="a mapping {wall: ..., obstacle: ..., target: ...}")
    result: dict[str, dict[str, Any]] = {}
    for section, keys in _DEFAULTABLE.items():
        block = raw.get(section) or {}
        allowed = {k: _SECTION_READERS[section][k] for k in keys}
        f.mapping(ctx, f"defaults.{section}", block, allowed, what=f"a mapping of {', '.join(keys)}")
        result[section] = dict(block)
    return result


def _read_walls(ctx: f.Context, raw: Any, defaults: dict[str, Any]) -> tuple[Wall, ...]:
    if raw is None or raw == []:
        raise ctx.error("walls", "empty map: no walls", raw if raw is not None else f.MISSING,
                        "a list of at least one wall")

    def read(path, item):
        d = f.mapping(ctx, path, _merged(defaults, item), _WALL_READERS,
                      required=("id", "points", "thickness"),
                      what="a mapping {id, points, thickness, height, surface}")
        return Wall(id=d["id"], points=d["points"], thickness=d["thickness"],
                    height=d.get("height", DEFAULT_WALL_HEIGHT), surface=d.get("surface", DEFAULT_SURFACE))

    return tuple(_read_list(ctx, "walls", raw, read))


def _shape(ctx: f.Context, path: str, d: dict[str, Any], raw: Any) -> np.ndarray:
    """The polygon of an item given as exactly one of `box:` or `polygon:`."""
    given = [k for k in ("box", "polygon") if k in d]
    if len(given) != 1:
        raise ctx.error(path, "needs exactly one shape" if given else "missing shape",
                        {k: raw[k] for k in given} if given else f.MISSING,
                        "exactly one of `box: {center, size, yaw}` or `polygon: [[x, y], ...]`")
    return d[given[0]]


def _read_obstacles(ctx: f.Context, raw: Any, defaults: dict[str, Any]) -> tuple[Obstacle, ...]:
    def read(path, item):
        merged = _merged(defaults, item)
        d = f.mapping(ctx, path, merged, _OBSTACLE_READERS, required=("id", "kind", "height"),
                      what="a mapping {id, kind, box or polygon, height}")
        return Obstacle(id=d["id"], kind=d["kind"], polygon=_shape(ctx, path, d, merged), height=d["height"])

    return tuple(_read_list(ctx, "obstacles", raw, read))


def _read_stations(ctx: f.Context, raw: Any) -> tuple[Station, ...]:
    return tuple(_read_list(ctx, "stations", raw, lambda path, item: _read_station(ctx, path, item)))


def _read_target_fields(ctx: f.Context, raw: Any, defaults: dict[str, Any]) -> list[dict[str, Any]]:
    """Each target's checked fields; placing it on its wall comes later (:func:`_make_target`)."""
    def read(path, item):
        return f.mapping(ctx, path, _merged(defaults, item), _TARGET_READERS,
                         required=("id", "wall", "at", "side", "height", "polarity"),
                         what="a mapping {id, wall, at, side, height, polarity}")

    return _read_list(ctx, "targets", raw, read)


def _read_station(ctx: f.Context, path: str, raw: Any) -> Station:
    d = f.mapping(ctx, path, raw, _STATION_READERS, required=("id", "pose"),
                  what="a mapping {id, pose: [x, y, theta]}")
    return Station(id=d["id"], pose=d["pose"])


def _read_lighting(ctx: f.Context, raw: Any) -> tuple[float, tuple[LightingZone, ...]]:
    d = f.mapping(ctx, "lighting", raw or {}, {"default": _level, "zones": _ignore},
                  what="a mapping {default: level, zones: [...]}")

    def read_zone(path, item):
        z = f.mapping(ctx, path, item, _ZONE_READERS, required=("id", "level"),
                      what="a mapping {id, box or polygon, level}")
        return LightingZone(id=z["id"], polygon=_shape(ctx, path, z, item), level=z["level"])

    zones = tuple(_read_list(ctx, "lighting.zones", (raw or {}).get("zones"), read_zone))
    return d.get("default", 1.0), zones


def _read_routes(ctx: f.Context, raw: Any, stations: tuple[Station, ...]) -> dict[str, tuple[str, ...]]:
    """Route name -> station ids, each id known and no station repeated back to back."""
    if not isinstance(raw, dict):
        raise ctx.error("routes", "wrong type", raw, "a mapping route name -> [station ids]")
    known = [s.id for s in stations]
    routes: dict[str, tuple[str, ...]] = {}
    for name, ids in raw.items():
        path = f"routes.{f.identifier(ctx, f'routes.{name}', name)}"
        ids = _station_ids(ctx, path, ids)
        for k, sid in enumerate(ids):
            if sid not in known:
                raise _unknown_ref(ctx, f.join(path, k), sid, known, "station")
            if k and sid == ids[k - 1]:
                raise ctx.error(f.join(path, k), "station repeated back to back (a zero-length leg)",
                                sid, "a different station from the previous one")
        routes[name] = ids
    return routes


def _unknown_ref(ctx: f.Context, path: str, ref: str, known: list[str], what: str) -> MapError:
    import difflib

    close = difflib.get_close_matches(ref, known, n=1, cutoff=0.6)
    hint = f", did you mean {close[0]!r}?" if close else ""
    shown = ", ".join(known[:12]) + (", ..." if len(known) > 12 else "")
    return ctx.error(path, f"unknown {what}{hint}", ref, f"the id of a {what} in this map ({shown})")


def _check_unique_ids(ctx: f.Context, walls, obstacles, stations, zones, raw_targets) -> None:
    """Every id in the map is distinct, across all sections."""
    first: dict[str, str] = {}
    sections = [("walls", [w.id for w in walls]), ("obstacles", [o.id for o in obstacles]),
                ("stations", [s.id for s in stations]), ("lighting.zones", [z.id for z in zones]),
                ("targets", [t["id"] for t in raw_targets])]
    for section, ids in sections:
        for i, item_id in enumerate(ids):
            path = f"{section}[{i}].id"
            if item_id in first:
                raise ctx.error(path, f"duplicate id, already used by {first[item_id]}", item_id,
                                "an id used nowhere else in the map")
            first[item_id] = f"{section}[{i}]"


def _make_target(ctx: f.Context, path: str, t: dict[str, Any], walls: tuple[Wall, ...]) -> MapTarget:
    """Place a target on its wall: the face centre and the direction it faces."""
    by_id = {w.id: w for w in walls}
    if t["wall"] not in by_id:
        raise _unknown_ref(ctx, f"{path}.wall", t["wall"], list(by_id), "wall")
    wall = by_id[t["wall"]]
    spec: TargetSpec = t.get("size", TargetSpec())
    half = 0.5 * spec.outer_width
    at = t["at"]
    cum = geo.polyline_cumulative_length(wall.points)
    if at - half < -geo.EPS or at + half > cum[-1] + geo.EPS:
        raise ctx.error(f"{path}.at", f"target not on any wall: its {spec.outer_width:.3f} m face would "
                        f"run off the ends of wall {wall.id!r} ({cum[-1]:.3f} m long)", at,
                        f"{half:.3f} <= at <= {cum[-1] - half:.3f} m")
    seg = min(int(np.searchsorted(cum, at, side="right")) - 1, len(cum) - 2)
    if at - half < cum[seg] - geo.EPS or at + half > cum[seg + 1] + geo.EPS:
        corner = cum[seg] if at - half < cum[seg] else cum[seg + 1]
        raise ctx.error(f"{path}.at", f"target straddles the corner of wall {wall.id!r} at "
                        f"{corner:.3f} m", at,
                        f"a place where its {spec.outer_width:.3f} m face lies on one straight piece")
    centre, tangent = wall.point_at(at)
    normal = geo.left_normal(tangent)
    if t["side"] == "right":
        normal = 0.0 - normal  # (0.0 - x avoids negative zeros)
    return MapTarget(id=t["id"], wall=wall.id, at=at, side=t["side"], height=t["height"],
                     polarity=t["polarity"], spec=spec,
                     position=f.readonly(centre + normal * (0.5 * wall.thickness)),
                     normal=f.readonly(normal))


def _bounds(ctx: f.Context, walls, obstacles) -> tuple[float, float, float, float]:
    """xmin, ymin, xmax, ymax (m) over walls (with thickness) and obstacles, each
    within ±:data:`~agvsim.world.fields.WORLD_LIMIT` (a MapError naming the item otherwise)."""
    limit = f.WORLD_LIMIT
    items = [(f"walls[{i}]", w.points, 0.5 * w.thickness) for i, w in enumerate(walls)]
    items += [(f"obstacles[{i}]", o.polygon, 0.0) for i, o in enumerate(obstacles)]
    for path, pts, pad in items:
        reach = float(np.abs(pts).max()) + pad
        if reach > limit:
            raise ctx.error(path, f"reaches {reach:.1f} m from the origin, beyond the map's ±{limit:g} m",
                            expected=f"walls and obstacles within ±{limit:g} m of the origin (a map is at most "
                            f"{2 * limit / 1000:g} km across)")
    lo = [w.points.min(axis=0) - 0.5 * w.thickness for w in walls]
    hi = [w.points.max(axis=0) + 0.5 * w.thickness for w in walls]
    lo += [o.polygon.min(axis=0) for o in obstacles]
    hi += [o.polygon.max(axis=0) for o in obstacles]
    xmin, ymin = np.min(lo, axis=0)
    xmax, ymax = np.max(hi, axis=0)
    return tuple(round(float(v), 9) for v in (xmin, ymin, xmax, ymax))  # type: ignore[return-value]
