"""Plant-floor maps: the data model (read with :func:`agvsim.world.loader.load_map`).

Conventions: SI units (metres, radians). Map frame: x east, y north,
θ counter-clockwise from +x. The YAML schema is documented field by field
in ``maps/README.md``.

    >>> from agvsim.world import load_map
    >>> m = load_map("corridor")            # a shipped map, or a path to a .yaml file
    >>> m.route()[0].pose                   # first station of the default route
    >>> m.target("C01").position, m.target("C01").yaw
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from agvsim.world import geometry as geo
from agvsim.world.spatial import Solids
from localizer.model.mount import CameraMount
from localizer.numeric import check_number
from localizer.model.target import POLARITIES, TargetSpec

__all__ = ["DEFAULT_SURFACE", "DEFAULT_WALL_HEIGHT", "LightingZone", "Map", "MapTarget", "Obstacle", "Station",
           "Wall"]

DEFAULT_WALL_HEIGHT = 3.0  # m
DEFAULT_SURFACE = "painted"

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
        camera_mount: the camera mount recommended for this floor (the YAML's
            ``camera_mount``; a forward-looking :class:`~localizer.model.mount.CameraMount` if absent).
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
    camera_mount: CameraMount = field(default_factory=CameraMount)
    solids: Solids = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "routes", MappingProxyType(dict(self.routes)))
        object.__setattr__(self, "solids", Solids.build(self.walls, self.obstacles))

    def without_targets(self, every: int, offset: int = 0) -> "Map":
        """A copy without every ``every``-th target (indices ``offset, offset + every, ...``):
        sparser target layouts for drift studies."""
        if isinstance(every, bool) or not isinstance(every, int) or every < 2:
            raise ValueError(f"without_targets: every must be a whole number >= 2, got {every!r}")
        keep = tuple(t for i, t in enumerate(self.targets) if (i - offset) % every != 0)
        return replace(self, targets=keep)

    def with_lighting_scaled(self, scale: float) -> "Map":
        """A copy with every illumination level (the default and each zone's) times ``scale``
        (> 0): the same plant, brighter or dimmer, for lighting studies."""
        check_number("with_lighting_scaled: scale", scale, low=0.0, low_open=True)
        zones = tuple(replace(z, level=z.level * scale) for z in self.lighting_zones)
        return replace(self, lighting_default=self.lighting_default * scale, lighting_zones=zones)

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

    def is_free(self, x: float, y: float, margin: float = 0.0) -> bool:
        """Whether ``(x, y)`` (m) is inside :attr:`bounds` and more than ``margin`` (m) from every
        wall surface and obstacle: where a vehicle's reference point can be (the filter's
        ``free_space``)."""
        xmin, ymin, xmax, ymax = self.bounds
        if not (xmin <= x <= xmax and ymin <= y <= ymax):
            return False
        return self.clearance(x, y) > margin

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
            # a loop's list ends at its start again: its stations are counted once (as the
            # follower's arrivals and the envs count them)
            "routes": {name: {"stations": len(set(ids)), "length": self.route_length(name),
                              "loop": ids[0] == ids[-1]} for name, ids in self.routes.items()},
            "targets": {"total": len(self.targets), **polarity},
            "lighting": {"default": self.lighting_default,
                         "zones": {z.id: z.level for z in self.lighting_zones}},
            "camera_mount": {"forward": self.camera_mount.forward, "lateral": self.camera_mount.lateral,
                             "height": self.camera_mount.height, "yaw": self.camera_mount.yaw},
        }


def _by_id(items, item_id: str, what: str):
    for item in items:
        if item.id == item_id:
            return item
    raise KeyError(f"no {what} {item_id!r}")


