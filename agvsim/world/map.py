"""Plant-floor maps: the data model and the YAML loader.

Conventions: SI units (metres, radians). Map frame: x east, y north,
θ counter-clockwise from +x. The YAML schema is documented field by field
in ``maps/README.md``.

    >>> from agvsim.world.map import load_map
    >>> m = load_map("corridor")            # a shipped map, or a path to a .yaml file
    >>> m.route()[0].pose                   # first station of the default route
    >>> m.target("C01").position, m.target("C01").yaw

:func:`load_map` reads and checks everything; every problem is a
:class:`MapError` naming the file, the field (``targets[3].height``), the bad
value and what was expected. The geometric checks live in
:mod:`agvsim.world.checks`.
"""
from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from agvsim.world import checks
from agvsim.world import fields as f
from agvsim.world import geometry as geo
from agvsim.world.fields import MapError
from agvsim.world.spatial import Solids
from localizer.target import POLARITIES, TargetSpec

__all__ = [
    "LightingZone", "Map", "MapError", "MapTarget", "Obstacle", "Station", "Wall",
    "load_map", "map_from_dict", "maps_dir", "shipped_maps",
]

#: Target sides: "left"/"right" of the wall's direction of travel (first point -> last).
SIDES: tuple[str, ...] = ("left", "right")
DEFAULT_WALL_HEIGHT = 3.0  # m
DEFAULT_SURFACE = "painted"
MAP_SUFFIXES: tuple[str, ...] = (".yaml", ".yml")


# ====================================================================== model

@dataclass(frozen=True, eq=False)
class Wall:
    """A wall: a polyline centreline thickened by ``thickness``.

    Attributes:
        id: unique id.
        points: ``(N, 2)`` polyline vertices (m), N >= 2, read-only.
        thickness: full thickness (m); the wall extends ``thickness / 2`` each side.
        height: height above the floor (m).
        surface: how it looks: painted, concrete, brick, poster, door, glass, ...
    """

    id: str
    points: np.ndarray
    thickness: float
    height: float = DEFAULT_WALL_HEIGHT
    surface: str = DEFAULT_SURFACE

    @property
    def length(self) -> float:
        """Length of the centreline polyline (m)."""
        return float(geo.polyline_cumulative_length(self.points)[-1])

    def segments(self) -> np.ndarray:
        """``(N-1, 2, 2)`` centreline segments."""
        return geo.polyline_segments(self.points)

    def point_at(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        """The centreline point ``s`` metres from the first vertex, and the unit tangent there.

        At an interior vertex the tangent is that of the segment starting
        there (at the last vertex, of the last segment).

        Raises:
            ValueError: ``s`` outside ``[0, length]``.
        """
        cum = geo.polyline_cumulative_length(self.points)
        if not (0.0 <= s <= cum[-1]):
            raise ValueError(f"wall {self.id!r}: s={s!r} m is outside [0, {cum[-1]:.3f}] m")
        i = min(int(np.searchsorted(cum, s, side="right")) - 1, len(self.points) - 2)
        a, b = self.points[i], self.points[i + 1]
        tangent = (b - a) / (cum[i + 1] - cum[i])
        return a + tangent * (s - cum[i]), tangent


@dataclass(frozen=True, eq=False)
class Obstacle:
    """A static obstacle: a filled polygon with a height.

    Attributes:
        id: unique id.
        kind: what it is: rack, machine, pillar, pallet, bench, cabinet, ...
        polygon: ``(K, 2)`` vertices (m), counter-clockwise, read-only.
        height: height above the floor (m).
    """

    id: str
    kind: str
    polygon: np.ndarray
    height: float


@dataclass(frozen=True)
class Station:
    """A named pose: a dock, a pick-up point, or a route junction.

    Attributes:
        id: unique id.
        pose: ``(x m, y m, θ rad)``; θ is the heading to stand at.
    """

    id: str
    pose: tuple[float, float, float]

    @property
    def position(self) -> np.ndarray:
        """``(2,)`` x, y (m)."""
        return np.array(self.pose[:2], dtype=float)


@dataclass(frozen=True, eq=False)
class LightingZone:
    """An area lit differently from the rest of the floor.

    Attributes:
        id: unique id.
        polygon: ``(K, 2)`` vertices (m), counter-clockwise, read-only.
        level: relative illumination: 1.0 normal, < 1 dim, > 1 bright.
    """

    id: str
    polygon: np.ndarray
    level: float


@dataclass(frozen=True, eq=False, kw_only=True)
class MapTarget:
    """A printed two-bar target on a wall, with its derived world pose.

    Attributes:
        id: unique id.
        wall: id of the wall it hangs on.
        at: distance along the wall's centreline polyline from its first point to
            the target's centre (m).
        side: ``"left"`` or ``"right"`` of the wall's direction of travel: the
            side it faces.
        height: height of the target's centre above the floor (m).
        polarity: ``"positive"`` (black bars on white) or ``"negative"``.
        spec: the target's geometry (default: the thesis target).
        position: ``(2,)`` centre of the target's face, on the wall's surface
            (``thickness / 2`` from the centreline along ``normal``) (m).
        normal: ``(2,)`` unit vector the target faces (into free space).
    """

    id: str
    wall: str
    at: float
    side: str
    height: float
    polarity: str
    spec: TargetSpec = field(default_factory=TargetSpec)
    position: np.ndarray
    normal: np.ndarray

    @property
    def yaw(self) -> float:
        """Direction the target faces (rad, CCW from +x): ``atan2(normal[1], normal[0])``."""
        return math.atan2(float(self.normal[1]), float(self.normal[0]))

    @property
    def center_3d(self) -> np.ndarray:
        """``(3,)`` centre of the face: x, y on the wall surface, z = height (m)."""
        return np.array([self.position[0], self.position[1], self.height])


@dataclass(frozen=True, eq=False)
class Map:
    """A plant floor. Build one with :func:`load_map`.

    Attributes:
        name: map name (the file's ``name:``, else the file stem).
        source: the file it was read from, or None.
        description: free text.
        walls, obstacles, stations, lighting_zones, targets: in file order.
        routes: read-only route name -> station ids in driving order (a loop
            repeats its first station at the end).
        lighting_default: illumination level outside every zone.
        bounds: ``(xmin, ymin, xmax, ymax)`` (m) over walls (including their
            thickness) and obstacles.
    """

    name: str
    source: Path | None
    description: str
    walls: tuple[Wall, ...]
    obstacles: tuple[Obstacle, ...]
    stations: tuple[Station, ...]
    routes: Mapping[str, tuple[str, ...]]
    lighting_default: float
    lighting_zones: tuple[LightingZone, ...]
    targets: tuple[MapTarget, ...]
    bounds: tuple[float, float, float, float]
    solids: Solids = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "routes", MappingProxyType(dict(self.routes)))
        object.__setattr__(self, "solids", Solids.build(self.walls, self.obstacles))

    # ------------------------------------------------------------ lookups

    def station(self, station_id: str) -> Station:
        """The station with this id (KeyError if none)."""
        return _by_id(self.stations, station_id, "station")

    def wall(self, wall_id: str) -> Wall:
        """The wall with this id (KeyError if none)."""
        return _by_id(self.walls, wall_id, "wall")

    def obstacle(self, obstacle_id: str) -> Obstacle:
        """The obstacle with this id (KeyError if none)."""
        return _by_id(self.obstacles, obstacle_id, "obstacle")

    def target(self, target_id: str) -> MapTarget:
        """The target with this id (KeyError if none)."""
        return _by_id(self.targets, target_id, "target")

    def route(self, name: str = "default") -> tuple[Station, ...]:
        """The stations of route ``name``, in driving order (KeyError if none)."""
        if name not in self.routes:
            raise KeyError(f"map {self.name!r} has no route {name!r} (routes: {', '.join(self.routes) or 'none'})")
        return tuple(self.station(s) for s in self.routes[name])

    def route_length(self, name: str = "default") -> float:
        """Length of route ``name`` as straight legs between its stations (m)."""
        pts = np.array([s.position for s in self.route(name)])
        return float(geo.polyline_cumulative_length(pts)[-1])

    def lighting_at(self, x: float, y: float) -> float:
        """Illumination level at ``(x, y)``: the last zone containing it wins, else the default."""
        level = self.lighting_default
        for zone in self.lighting_zones:
            if geo.points_in_polygon((x, y), zone.polygon)[0]:
                level = zone.level
        return level

    # ------------------------------------------------------------ geometry

    @property
    def size(self) -> tuple[float, float]:
        """``(width, depth)`` of :attr:`bounds` (m)."""
        xmin, ymin, xmax, ymax = self.bounds
        return xmax - xmin, ymax - ymin

    def clearance(self, x: float, y: float) -> float:
        """Free distance (m) from ``(x, y)`` to the nearest wall surface or obstacle (< 0 inside)."""
        return self.solids.point_clearance((x, y))[0]

    def line_of_sight(self, a, b) -> bool:
        """Whether the straight segment ``a``-``b`` (``(2,)`` m) crosses no wall or obstacle."""
        return self.solids.blocker(a, b) is None

    def summary(self) -> dict[str, Any]:
        """Counts, bounds and route lengths, as plain JSON-ready data."""
        polarity = {p: sum(t.polarity == p for t in self.targets) for p in POLARITIES}
        return {
            "name": self.name,
            "source": str(self.source) if self.source else None,
            "description": self.description,
            "bounds": list(self.bounds),
            "size": list(self.size),
            "walls": len(self.walls),
            "obstacles": len(self.obstacles),
            "stations": len(self.stations),
            "routes": {name: {"stations": len(ids), "length": self.route_length(name),
                              "loop": ids[0] == ids[-1]} for name, ids in self.routes.items()},
            "targets": {"total": len(self.targets), **polarity},
            "lighting": {"default": self.lighting_default,
                         "zones": {z.id: z.level for z in self.lighting_zones}},
        }


def _by_id(items, item_id: str, what: str):
    for item in items:
        if item.id == item_id:
            return item
    raise KeyError(f"no {what} {item_id!r}")


# ====================================================================== files

def maps_dir() -> Path:
    """The folder of shipped maps: ``$AGVSIM_MAPS_DIR`` if set, else the repo's
    ``maps/`` (editable install), else ``<prefix>/share/agvsim/maps`` (wheel)."""
    override = os.environ.get("AGVSIM_MAPS_DIR")
    if override:
        return Path(override)
    repo = Path(__file__).resolve().parents[2] / "maps"
    if repo.is_dir():
        return repo
    # a non-editable install ships the maps as data files under the prefix
    return Path(sys.prefix) / "share" / "agvsim" / "maps"


def shipped_maps() -> list[str]:
    """Names of the maps in :func:`maps_dir`, sorted."""
    folder = maps_dir()
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.iterdir() if p.suffix in MAP_SUFFIXES and p.is_file())


def resolve_map_path(name_or_path: str | os.PathLike) -> Path:
    """A shipped map name (``"corridor"``) or a path -> the file's path.

    Anything with a directory part or a ``.yaml``/``.yml`` suffix is a path.

    Raises:
        FileNotFoundError: no such file or shipped map.
    """
    text = os.fspath(name_or_path)
    looks_like_path = (isinstance(name_or_path, os.PathLike) or os.sep in text or "/" in text
                       or text.endswith(MAP_SUFFIXES))
    if looks_like_path:
        path = Path(text)
        if path.is_file():
            return path
        shipped = maps_dir() / path.name
        if path.name == text and shipped.is_file():  # "corridor.yaml" from any directory
            return shipped
        raise FileNotFoundError(f"no map file {text!r}")
    for suffix in MAP_SUFFIXES:
        candidate = maps_dir() / f"{text}{suffix}"
        if candidate.is_file():
            return candidate
    shipped = ", ".join(shipped_maps()) or "none found"
    raise FileNotFoundError(
        f"no shipped map {text!r} in {maps_dir()} (shipped: {shipped}; or give a path to a .yaml file)")


def load_map(name_or_path: str | os.PathLike) -> Map:
    """Read and check a map: a shipped name (``"plant_floor"``) or a path to a YAML file.

    Raises:
        FileNotFoundError: no such map.
        MapError: the file is malformed or describes an impossible floor.
    """
    path = resolve_map_path(name_or_path)
    ctx = f.Context(str(path))
    data = f.parse_yaml(ctx, path.read_text(encoding="utf-8"))
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
    for i, gap in enumerate(np.linalg.norm(np.diff(pts, axis=0), axis=1)):
        if gap <= geo.EPS:
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
    size = f.vector(ctx, path, raw, 2, "[w, d] in m")
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


_TOP_KEYS = {"name": _id, "description": _text, "defaults": _ignore, "walls": _ignore,
             "obstacles": _ignore, "stations": _ignore, "routes": _ignore, "lighting": _ignore,
             "targets": _ignore}


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
        bounds=_bounds(walls, obstacles),
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


def _bounds(walls, obstacles) -> tuple[float, float, float, float]:
    """xmin, ymin, xmax, ymax (m) over walls (with thickness) and obstacles."""
    lo = [w.points.min(axis=0) - 0.5 * w.thickness for w in walls]
    hi = [w.points.max(axis=0) + 0.5 * w.thickness for w in walls]
    lo += [o.polygon.min(axis=0) for o in obstacles]
    hi += [o.polygon.max(axis=0) for o in obstacles]
    xmin, ymin = np.min(lo, axis=0)
    xmax, ymax = np.max(hi, axis=0)
    return tuple(round(float(v), 9) for v in (xmin, ymin, xmax, ymax))  # type: ignore[return-value]
