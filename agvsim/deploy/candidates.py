"""Where a target could hang: candidate placements on the map's wall faces.

Every straight piece of every wall, on both faces, gets a candidate every ``step`` metres
(the target's face whole on the piece, as the map loader requires), at the camera's height
(a level camera sees a target best at its own height: thesis §3.5), facing away from the wall.
Left out: walls whose surface is not a place for a target (:data:`NO_TARGET_SURFACES`: doors,
glass, posters), faces the user forbids (``WALL`` or ``WALL:left|right``), places with an
obstacle or another wall in front of the face (:data:`FRONT_DEPTH`), and places within
``min_spacing`` of a target kept from the map.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from agvsim.world import geometry as geo
from agvsim.world.map import MapTarget
from localizer.model.target import TargetSpec

__all__ = ["FRONT_CLEARANCE", "FRONT_DEPTH", "NO_TARGET_SURFACES", "SIDES", "Face", "candidate_targets", "parse_faces"]

#: wall surfaces no target is hung on (a door opens, glass is seen through, a poster covers)
NO_TARGET_SURFACES: tuple[str, ...] = ("door", "glass", "poster")
#: the faces of a wall, as the map's ``side``
SIDES: tuple[str, ...] = ("left", "right")
#: a point this far in front of a candidate's face (m) ...
FRONT_DEPTH = 0.6
#: ... must be at least this far from every wall surface and obstacle (m): nothing in front of it
FRONT_CLEARANCE = 0.45


@dataclass(frozen=True)
class Face:
    """A wall face: ``wall`` id and ``side`` (None: both)."""

    wall: str
    side: str | None = None

    def covers(self, wall: str, side: str) -> bool:
        return self.wall == wall and (self.side is None or self.side == side)


def parse_faces(items, world_map, flag: str = "--forbid") -> tuple[Face, ...]:
    """``WALL`` or ``WALL:left|right`` strings as faces of ``world_map``'s walls.

    Raises:
        ValueError: one line naming ``flag``, the item and what was expected.
    """
    from localizer.numeric import check_choice

    out = []
    walls = [w.id for w in world_map.walls]
    for item in items or ():
        wall, _, side = str(item).partition(":")
        check_choice(f"{flag} {item!r}: wall", wall, walls)
        if side:
            check_choice(f"{flag} {item!r}: side", side, SIDES)
        out.append(Face(wall, side or None))
    return tuple(out)


def _place(wall, at: float, side: str, height: float, spec: TargetSpec, tid: str) -> MapTarget:
    """A target on ``wall`` at ``at`` m along it, facing ``side`` (as the map loader places one)."""
    centre, tangent = wall.point_at(at)
    normal = geo.left_normal(tangent)
    if side == "right":
        normal = 0.0 - normal
    position = centre + normal * (0.5 * wall.thickness)
    position.flags.writeable = False
    normal.flags.writeable = False
    return MapTarget(id=tid, wall=wall.id, at=float(at), side=side, height=float(height), polarity="positive",
                     spec=spec, position=position, normal=normal)


def candidate_targets(world_map, height: float, step: float = 0.5, spec: TargetSpec = TargetSpec(),
                      forbid: tuple[Face, ...] = (), keep: tuple[MapTarget, ...] = (),
                      min_spacing: float = 2.0) -> list[MapTarget]:
    """The candidate placements (module docstring), ids ``C0000``, ``C0001``, ... in wall order.

    Args:
        world_map: the map. height: centre height (m). step: spacing along a face (m).
        spec: the target's geometry. forbid: faces not allowed. keep: targets staying (m).
        min_spacing: least distance between a candidate and a kept target's centre (m).
    """
    half = 0.5 * spec.outer_width
    out: list[MapTarget] = []
    kept = np.array([t.position for t in keep]).reshape(-1, 2)
    for wall in world_map.walls:
        if wall.surface in NO_TARGET_SURFACES:
            continue
        cum = geo.polyline_cumulative_length(wall.points)
        for k in range(len(cum) - 1):
            lo, hi = cum[k] + half, cum[k + 1] - half
            if hi < lo:
                continue
            n = int(math.floor((hi - lo) / step)) + 1
            first = lo + 0.5 * ((hi - lo) - (n - 1) * step)  # (centred on the piece)
            for j in range(n):
                at = first + j * step
                for side in SIDES:
                    if any(f.covers(wall.id, side) for f in forbid):
                        continue
                    t = _place(wall, at, side, height, spec, f"C{len(out):04d}")
                    front = t.position + FRONT_DEPTH * t.normal
                    if world_map.clearance(float(front[0]), float(front[1])) < FRONT_CLEARANCE:
                        continue
                    if len(kept) and np.min(np.hypot(*(kept - t.position).T)) < min_spacing:
                        continue
                    out.append(t)
    return [MapTarget(id=f"C{i:04d}", wall=t.wall, at=t.at, side=t.side, height=t.height, polarity=t.polarity,
                      spec=t.spec, position=t.position, normal=t.normal) for i, t in enumerate(out)]
