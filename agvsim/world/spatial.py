"""Spatial queries against a map's solids (walls and obstacles).

A wall is its centreline polyline thickened by ``thickness / 2`` on each
side; an obstacle is its filled polygon. :class:`Solids` packs them into
arrays once so clearance and line-of-sight queries are vectorised.
Distances are metres in the map frame.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Sequence

import numpy as np

from agvsim.world import geometry as geo

#: Slack (m) when deciding whether a segment enters a wall: a target's face
#: lies exactly on its wall's surface and must not count as inside it.
SURFACE_TOLERANCE = 1e-6


@dataclass(frozen=True, eq=False)
class Solids:
    """Walls and obstacles as flat arrays.

    Attributes:
        wall_segments: ``(M, 2, 2)`` centreline segments of every wall.
        wall_radius: ``(M,)`` half thickness of each segment's wall (m).
        wall_owner: ``(M,)`` index into ``wall_ids``.
        wall_ids: id of each wall.
        edges: ``(E, 2, 2)`` edges of every obstacle polygon.
        edge_owner: ``(E,)`` index into ``obstacle_ids``.
        obstacle_ids: id of each obstacle.
        polygons: each obstacle's ``(K, 2)`` polygon.
        boxes: ``(N, 4)`` each polygon's ``xmin, ymin, xmax, ymax``.
    """

    wall_segments: np.ndarray
    wall_radius: np.ndarray
    wall_owner: np.ndarray
    wall_ids: tuple[str, ...]
    edges: np.ndarray
    edge_owner: np.ndarray
    obstacle_ids: tuple[str, ...]
    polygons: tuple[np.ndarray, ...]
    boxes: np.ndarray

    @classmethod
    def build(cls, walls: Sequence, obstacles: Sequence) -> "Solids":
        """From objects with ``id``, ``points``, ``thickness`` (walls) and ``id``, ``polygon`` (obstacles)."""
        segs = [geo.polyline_segments(w.points) for w in walls]
        radius = [np.full(len(s), 0.5 * w.thickness) for s, w in zip(segs, walls)]
        owner = [np.full(len(s), i) for i, s in enumerate(segs)]
        polygons = tuple(np.asarray(o.polygon, dtype=float) for o in obstacles)
        edges = [geo.polygon_edges(p) for p in polygons]
        edge_owner = [np.full(len(e), i) for i, e in enumerate(edges)]
        boxes = np.array([[*p.min(axis=0), *p.max(axis=0)] for p in polygons]).reshape(-1, 4)
        return cls(
            wall_segments=_concat(segs, (0, 2, 2)),
            wall_radius=_concat(radius, (0,)),
            wall_owner=_concat(owner, (0,)).astype(int),
            wall_ids=tuple(w.id for w in walls),
            edges=_concat(edges, (0, 2, 2)),
            edge_owner=_concat(edge_owner, (0,)).astype(int),
            obstacle_ids=tuple(o.id for o in obstacles),
            polygons=polygons,
            boxes=boxes,
        )

    # ------------------------------------------------------------ helpers

    @cached_property
    def _wall_boxes(self) -> np.ndarray:
        """``(M, 4)`` each wall segment's bounding box grown by its radius: xmin, ymin, xmax, ymax."""
        s, r = self.wall_segments, self.wall_radius[:, None]
        return np.concatenate([np.minimum(s[:, 0], s[:, 1]) - r, np.maximum(s[:, 0], s[:, 1]) + r], axis=1)

    @cached_property
    def _edge_boxes(self) -> np.ndarray:
        """``(E, 4)`` each obstacle edge's bounding box: xmin, ymin, xmax, ymax."""
        e = self.edges
        return np.concatenate([np.minimum(e[:, 0], e[:, 1]), np.maximum(e[:, 0], e[:, 1])], axis=1)

    @staticmethod
    def _distances(a: np.ndarray, b: np.ndarray, segments: np.ndarray) -> np.ndarray:
        """:func:`geo.segment_segment_distance` of a-b to ``segments`` (K, 2, 2): on floats for a
        few (the usual line of sight: numpy's per-call overhead dominates), vectorised for many."""
        if len(segments) <= 8:
            return np.array(geo.segment_segment_distances_xy(a.tolist(), b.tolist(), segments.tolist()))
        return geo.segment_segment_distance(a, b, segments[:, 0], segments[:, 1])

    @staticmethod
    def _near(boxes: np.ndarray, a: np.ndarray, b: np.ndarray, margin: float) -> np.ndarray:
        """Indices of the boxes within ``margin`` of segment a-b's bounding box (a superset of
        the pieces the segment can come that close to: its distance to a piece is at least the
        gap between their boxes)."""
        (x0, y0), (x1, y1) = a.tolist(), b.tolist()
        return np.nonzero((boxes[:, 0] <= max(x0, x1) + margin) & (boxes[:, 2] >= min(x0, x1) - margin)
                          & (boxes[:, 1] <= max(y0, y1) + margin) & (boxes[:, 3] >= min(y0, y1) - margin))[0]

    def _wall_distances(self, a, b=None) -> np.ndarray:
        """Free distance from a point (or segment a-b) to each wall segment (m)."""
        s0, s1 = self.wall_segments[:, 0], self.wall_segments[:, 1]
        if b is None:
            d = geo.point_segment_distance(a, s0, s1)
        else:
            d = geo.segment_segment_distance(a, b, s0, s1)
        return d - self.wall_radius

    def _containing(self, p) -> int | None:
        """Index of an obstacle strictly containing point ``p``, else None."""
        p = np.asarray(p, dtype=float)
        near = (self.boxes[:, 0] <= p[0]) & (p[0] <= self.boxes[:, 2]) & \
               (self.boxes[:, 1] <= p[1]) & (p[1] <= self.boxes[:, 3])
        for i in np.nonzero(near)[0]:
            if geo.points_in_polygon(p, self.polygons[i])[0]:
                return int(i)
        return None

    def _entered(self, a, b, touching_edges: np.ndarray) -> int | None:
        """Index of an obstacle segment a-b enters, given which edges it touches."""
        for i in np.unique(self.edge_owner[touching_edges]):
            if geo.segment_enters_polygon(a, b, self.polygons[i]):
                return int(i)
        return self._containing(a)

    # ------------------------------------------------------------ queries

    def point_clearance(self, p) -> tuple[float, str | None]:
        """Free distance (m) from point ``p`` to the nearest solid, and its id.

        Negative when ``p`` is inside a wall (minus the depth) or inside an
        obstacle (minus the distance to its boundary). ``(inf, None)`` for
        a map with no solids.
        """
        best, best_id = np.inf, None
        if len(self.wall_segments):
            d = self._wall_distances(p)
            i = int(np.argmin(d))
            best, best_id = float(d[i]), self.wall_ids[self.wall_owner[i]]
        if len(self.edges):
            d = geo.point_segment_distance(p, self.edges[:, 0], self.edges[:, 1])
            i = int(np.argmin(d))
            inside = self._containing(p)
            if inside is not None:
                mine = self.edge_owner == inside
                return -float(d[mine].min()), self.obstacle_ids[inside]
            if d[i] < best:
                best, best_id = float(d[i]), self.obstacle_ids[self.edge_owner[i]]
        return best, best_id

    def segment_clearance(self, a, b) -> tuple[float, str | None]:
        """Smallest free distance (m) from segment ``a``-``b`` to any solid, and its id.

        0 or negative when the segment touches or enters a solid.
        """
        best, best_id = np.inf, None
        if len(self.wall_segments):
            d = self._wall_distances(a, b)
            i = int(np.argmin(d))
            best, best_id = float(d[i]), self.wall_ids[self.wall_owner[i]]
        if len(self.edges):
            d = geo.segment_segment_distance(a, b, self.edges[:, 0], self.edges[:, 1])
            inside = self._entered(a, b, np.nonzero(d <= geo.EPS)[0])
            if inside is not None:
                return 0.0, self.obstacle_ids[inside]
            i = int(np.argmin(d))
            if d[i] < best:
                best, best_id = float(d[i]), self.obstacle_ids[self.edge_owner[i]]
        return best, best_id

    def blocker(self, a, b) -> str | None:
        """Id of a solid that segment ``a``-``b`` passes through, else None.

        Grazing a wall's surface (within :data:`SURFACE_TOLERANCE`) or an
        obstacle's edge or corner does not block.
        """
        a = np.asarray(a, dtype=float)
        b = np.asarray(b, dtype=float)
        # only the pieces near the segment's bounding box can block it; the distances of those
        # are computed as for all (element by element, so the same to the bit)
        if len(self.wall_segments):
            near = self._near(self._wall_boxes, a, b, 1e-6)
            if len(near):
                d = self._distances(a, b, self.wall_segments[near]) - self.wall_radius[near]
                hit = near[d < -SURFACE_TOLERANCE]
                if len(hit):
                    return self.wall_ids[self.wall_owner[hit[0]]]
        if len(self.edges):
            near = self._near(self._edge_boxes, a, b, 1e-6)
            touching = near
            if len(near):
                touching = near[self._distances(a, b, self.edges[near]) <= geo.EPS]
            inside = self._entered(a, b, touching)
            if inside is not None:
                return self.obstacle_ids[inside]
        return None


def _concat(arrays: list[np.ndarray], empty_shape: tuple[int, ...]) -> np.ndarray:
    return np.concatenate(arrays) if arrays else np.zeros(empty_shape)
