"""The static pymunk world built from a map, and contact monitoring.

Walls become :class:`pymunk.Segment` shapes with radius = thickness / 2;
obstacles become :class:`pymunk.Poly` shapes. ``collision_slop`` is kept
small (1 mm): with pymunk's default 0.1 a box driven by its velocity each
step tunnelled through thin walls.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import pymunk

COLLISION_VEHICLE = 1
COLLISION_WALL = 2
COLLISION_OBSTACLE = 3


@dataclass
class ContactMonitor:
    """Counts the vehicle's contacts; pymunk callbacks update it.

    Attributes:
        touching: ids of the walls/obstacles currently in contact (updated in place, never
            replaced: the vehicle's hot loop holds on to it).
        events: number of contact begins since the monitor was created.
        since_reset: ids touched since the last :meth:`reset_window`.
    """

    touching: dict[str, int] = field(default_factory=dict)
    events: int = 0
    since_reset: set[str] = field(default_factory=set)

    @property
    def in_contact(self) -> bool:
        return bool(self.touching)

    def reset_window(self) -> None:
        self.since_reset = set(self.touching)

    def _begin(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> None:
        other = _other_shape(arbiter)
        name = getattr(other, "label", "?")
        self.touching[name] = self.touching.get(name, 0) + 1
        self.since_reset.add(name)
        self.events += 1

    def _separate(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> None:
        other = _other_shape(arbiter)
        name = getattr(other, "label", "?")
        count = self.touching.get(name, 0) - 1
        if count <= 0:
            self.touching.pop(name, None)
        else:
            self.touching[name] = count


def _other_shape(arbiter: pymunk.Arbiter) -> pymunk.Shape:
    a, b = arbiter.shapes
    return b if a.collision_type == COLLISION_VEHICLE else a


class _LabelledSegment(pymunk.Segment):
    label: str = ""


class _LabelledPoly(pymunk.Poly):
    label: str = ""


def convex_parts(polygon) -> list[list[tuple[float, float]]]:
    """Split a simple polygon (K, 2) into convex pieces for :class:`pymunk.Poly`
    (which would otherwise collide as the polygon's convex hull)."""
    import pymunk.autogeometry

    pts = [(float(x), float(y)) for x, y in polygon]
    if _is_convex(pts):
        return [pts]
    area2 = sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(pts, pts[1:] + pts[:1]))
    if area2 < 0:  # make it counter-clockwise
        pts = pts[::-1]
    closed = pts + [pts[0]]
    parts = pymunk.autogeometry.convex_decomposition(closed, 0.0)
    return [[(p.x, p.y) for p in part[:-1]] for part in parts]


def _is_convex(pts: list[tuple[float, float]]) -> bool:
    n = len(pts)
    signs = set()
    for i in range(n):
        (x0, y0), (x1, y1), (x2, y2) = pts[i], pts[(i + 1) % n], pts[(i + 2) % n]
        cross = (x1 - x0) * (y2 - y1) - (y1 - y0) * (x2 - x1)
        if abs(cross) > 1e-12:
            signs.add(cross > 0)
    return len(signs) <= 1


def build_space(world_map) -> tuple[pymunk.Space, ContactMonitor]:
    """A pymunk space with the map's walls and obstacles as static shapes.

    Args:
        world_map: an :class:`agvsim.world.map.Map`.

    Returns:
        (space, contacts): the space (no gravity, 1 mm collision slop) and the
        monitor that records vehicle contacts.
    """
    space = pymunk.Space()
    space.gravity = (0.0, 0.0)
    space.collision_slop = 0.001  # m
    space.iterations = 10
    static = space.static_body
    shapes: list[pymunk.Shape] = []
    for wall in world_map.walls:
        pts = wall.points
        for i in range(len(pts) - 1):
            seg = _LabelledSegment(static, tuple(pts[i]), tuple(pts[i + 1]), 0.5 * wall.thickness)
            seg.label = wall.id
            seg.collision_type = COLLISION_WALL
            seg.friction = 0.5
            shapes.append(seg)
    for obstacle in world_map.obstacles:
        for part in convex_parts(obstacle.polygon):
            poly = _LabelledPoly(static, part)
            poly.label = obstacle.id
            poly.collision_type = COLLISION_OBSTACLE
            poly.friction = 0.5
            shapes.append(poly)
    space.add(*shapes)
    monitor = ContactMonitor()
    for other in (COLLISION_WALL, COLLISION_OBSTACLE):
        space.on_collision(COLLISION_VEHICLE, other, begin=monitor._begin, separate=monitor._separate)
    return space, monitor
