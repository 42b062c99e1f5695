"""Plane geometry for maps: points, segments, polylines and polygons.

Pure numpy, no state. Points are ``(2,)`` arrays (or anything
``np.asarray`` turns into one); collections of segments are ``(M, 2, 2)``
arrays whose ``[:, 0]`` and ``[:, 1]`` are the end points. All lengths are in
the caller's units (metres in maps); angles in radians.

Functions taking a *batch* of segments return one value per segment, so a
map check is one vectorised call rather than a Python loop.
"""
from __future__ import annotations

import math

import numpy as np

#: Distances at or below this (m) count as touching.
EPS = 1e-9


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """z component of the cross product of 2-vectors (broadcasts)."""
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def point_segment_distance(p, seg_a, seg_b) -> np.ndarray:
    """Distance from point(s) ``p`` to segment(s) ``seg_a``-``seg_b``.

    Args:
        p: ``(..., 2)`` point(s).
        seg_a, seg_b: ``(..., 2)`` segment end points; broadcast against ``p``.

    Returns:
        ``(...)`` distances. A degenerate segment is treated as a point.
    """
    p = np.asarray(p, dtype=float)
    a = np.asarray(seg_a, dtype=float)
    b = np.asarray(seg_b, dtype=float)
    ab = b - a
    denom = np.sum(ab * ab, axis=-1)
    t = np.sum((p - a) * ab, axis=-1) / np.where(denom > 0.0, denom, 1.0)
    t = np.clip(np.where(denom > 0.0, t, 0.0), 0.0, 1.0)
    closest = a + t[..., None] * ab
    return np.linalg.norm(p - closest, axis=-1)


def segments_cross(p0, p1, seg_a, seg_b) -> np.ndarray:
    """Whether segment ``p0``-``p1`` properly crosses each of ``seg_a``-``seg_b``.

    *Properly* means the interiors cross at a single point (each segment has
    its end points strictly on opposite sides of the other's line). Touching
    and collinear overlap are not crossings here; :func:`segment_segment_distance`
    reports those as distance 0 instead.
    """
    p0 = np.asarray(p0, dtype=float)
    p1 = np.asarray(p1, dtype=float)
    a = np.asarray(seg_a, dtype=float)
    b = np.asarray(seg_b, dtype=float)
    d = p1 - p0
    e = b - a
    o1 = _cross(d, a - p0)
    o2 = _cross(d, b - p0)
    o3 = _cross(e, p0 - a)
    o4 = _cross(e, p1 - a)
    return (o1 * o2 < 0.0) & (o3 * o4 < 0.0)


def segment_segment_distance(p0, p1, seg_a, seg_b) -> np.ndarray:
    """Shortest distance between segment ``p0``-``p1`` and each ``seg_a``-``seg_b``.

    Args:
        p0, p1: ``(2,)`` ends of one segment (or ``(..., 2)``, broadcast).
        seg_a, seg_b: ``(M, 2)`` ends of M segments.

    Returns:
        ``(M,)`` distances; 0 where the segments cross or touch.
    """
    candidates = np.stack([
        point_segment_distance(p0, seg_a, seg_b),
        point_segment_distance(p1, seg_a, seg_b),
        point_segment_distance(seg_a, p0, p1),
        point_segment_distance(seg_b, p0, p1),
    ])
    dist = candidates.min(axis=0)
    return np.where(segments_cross(p0, p1, seg_a, seg_b), 0.0, dist)


def _point_segment_distance_xy(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> float:
    """:func:`point_segment_distance` of one point and one segment, on floats, operation for
    operation as numpy does it (so the same to the bit)."""
    abx, aby = bx - ax, by - ay
    denom = abx * abx + aby * aby
    if denom > 0.0:
        t = ((px - ax) * abx + (py - ay) * aby) / denom
        t = t if t > 0.0 else 0.0  # np.clip(t, 0, 1) (numpy's max/min order)
        t = t if t < 1.0 else 1.0
    else:
        t = 0.0
    dx = px - (ax + t * abx)
    dy = py - (ay + t * aby)
    return math.sqrt(dx * dx + dy * dy)


def segment_segment_distances_xy(p0, p1, segments) -> list[float]:
    """:func:`segment_segment_distance` of segment ``p0``-``p1`` and each ``segments``
    ``((ax, ay), (bx, by))``, on floats: the same values to the bit, without numpy's
    per-call overhead (for a few segments; a long batch is faster vectorised)."""
    (x0, y0), (x1, y1) = p0, p1
    dx, dy = x1 - x0, y1 - y0
    out = []
    for (ax, ay), (bx, by) in segments:
        dist = min(_point_segment_distance_xy(x0, y0, ax, ay, bx, by),
                   _point_segment_distance_xy(x1, y1, ax, ay, bx, by),
                   _point_segment_distance_xy(ax, ay, x0, y0, x1, y1),
                   _point_segment_distance_xy(bx, by, x0, y0, x1, y1))
        ex, ey = bx - ax, by - ay
        o1 = dx * (ay - y0) - dy * (ax - x0)
        o2 = dx * (by - y0) - dy * (bx - x0)
        o3 = ex * (y0 - ay) - ey * (x0 - ax)
        o4 = ex * (y1 - ay) - ey * (x1 - ax)
        out.append(0.0 if (o1 * o2 < 0.0 and o3 * o4 < 0.0) else dist)
    return out


def polyline_segments(points) -> np.ndarray:
    """``(N, 2)`` polyline vertices -> ``(N-1, 2, 2)`` segments."""
    pts = np.asarray(points, dtype=float)
    return np.stack([pts[:-1], pts[1:]], axis=1)


def polygon_edges(polygon) -> np.ndarray:
    """``(K, 2)`` polygon vertices (not repeated at the end) -> ``(K, 2, 2)`` edges."""
    pts = np.asarray(polygon, dtype=float)
    return np.stack([pts, np.roll(pts, -1, axis=0)], axis=1)


def polyline_cumulative_length(points) -> np.ndarray:
    """``(N,)`` arc length at each vertex of a polyline, starting at 0."""
    pts = np.asarray(points, dtype=float)
    lengths = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(lengths)])


def polygon_signed_area(polygon) -> float:
    """Shoelace area; positive when the vertices run counter-clockwise."""
    pts = np.asarray(polygon, dtype=float)
    x, y = pts[:, 0], pts[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def polygon_self_intersection(polygon) -> tuple[int, int] | None:
    """The first pair of edges ``(i, j)`` of a polygon that cross or touch, else None.

    Edge ``i`` joins vertex ``i`` to vertex ``i+1`` (cyclically). Neighbouring
    edges share a vertex and are only reported if they fold back onto each
    other (collinear overlap). Repeated vertices give zero-length edges and
    count as touching.
    """
    edges = polygon_edges(polygon)
    k = len(edges)
    for i in range(k):
        for j in range(i + 1, k):
            adjacent = j == i + 1 or (i == 0 and j == k - 1)
            a, b = edges[i]
            c, d = edges[j]
            if adjacent:
                shared = b if j == i + 1 else a
                other_i = a if j == i + 1 else b
                other_j = d if j == i + 1 else c
                if _folds_back(shared, other_i, other_j):
                    return (i, j)
                continue
            if segment_segment_distance(a, b, c[None], d[None])[0] <= EPS:
                return (i, j)
    return None


def _folds_back(shared, end_i, end_j) -> bool:
    """Whether two edges meeting at ``shared`` overlap (point the same way, collinear)."""
    u = np.asarray(end_i) - shared
    v = np.asarray(end_j) - shared
    nu, nv = np.linalg.norm(u), np.linalg.norm(v)
    if nu <= EPS or nv <= EPS:
        return True
    return abs(_cross(u, v)) <= EPS * nu * nv and float(np.dot(u, v)) > 0.0


def points_in_polygon(points, polygon) -> np.ndarray:
    """Even-odd test: which of ``points`` ``(P, 2)`` lie strictly inside ``polygon``.

    Points exactly on an edge may go either way; callers needing a clear
    margin should also check the distance to the edges.
    """
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    poly = np.asarray(polygon, dtype=float)
    a = poly[None, :, :]
    b = np.roll(poly, -1, axis=0)[None, :, :]
    px = pts[:, None, 0]
    py = pts[:, None, 1]
    straddles = (a[..., 1] > py) != (b[..., 1] > py)
    dy = b[..., 1] - a[..., 1]
    x_at = a[..., 0] + (py - a[..., 1]) * (b[..., 0] - a[..., 0]) / np.where(dy == 0.0, 1.0, dy)
    crossings = straddles & (px < x_at)
    return (np.count_nonzero(crossings, axis=1) % 2) == 1


def point_polygon_distance(point, polygon) -> float:
    """Distance from ``point`` to a filled polygon: 0 inside, else to the nearest edge."""
    if points_in_polygon(point, polygon)[0]:
        return 0.0
    edges = polygon_edges(polygon)
    return float(point_segment_distance(point, edges[:, 0], edges[:, 1]).min())


def box_polygon(center, size, yaw: float = 0.0) -> np.ndarray:
    """Corners of a rectangle, counter-clockwise.

    Args:
        center: ``(x, y)`` of the centre.
        size: ``(w, d)``: extent along the box's own x axis and y axis.
        yaw: rotation of the box's x axis from the map's +x (rad, CCW).

    Returns:
        ``(4, 2)`` corners, counter-clockwise, starting at the box's
        (-w/2, -d/2) corner.
    """
    w, d = float(size[0]) / 2.0, float(size[1]) / 2.0
    local = np.array([[-w, -d], [w, -d], [w, d], [-w, d]])
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    return local @ rot.T + np.asarray(center, dtype=float)


def left_normal(direction) -> np.ndarray:
    """The unit vector 90° counter-clockwise from ``direction``."""
    d = np.asarray(direction, dtype=float)
    n = np.array([-d[1], d[0]]) / np.linalg.norm(d)
    return n + 0.0  # no negative zeros


def segment_enters_polygon(a, b, polygon) -> bool:
    """Whether any part of segment ``a``-``b`` lies strictly inside ``polygon``.

    The segment is cut where it meets the polygon's edges; it enters the
    polygon iff the middle of some piece is inside. Grazing a vertex or
    running along an edge is not entering.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    edges = polygon_edges(polygon)
    d = b - a
    e = edges[:, 1] - edges[:, 0]
    w = edges[:, 0] - a
    denom = _cross(d, e)
    safe = np.where(denom == 0.0, 1.0, denom)
    t = _cross(w, e) / safe
    u = _cross(w, d) / safe
    tol = 1e-12
    meets = (denom != 0.0) & (t >= -tol) & (t <= 1 + tol) & (u >= -tol) & (u <= 1 + tol)
    cuts = np.unique(np.concatenate([[0.0, 1.0], np.clip(t[meets], 0.0, 1.0)]))
    mids = 0.5 * (cuts[:-1] + cuts[1:])[np.diff(cuts) > tol]
    if len(mids) == 0:
        return False
    probes = a + mids[:, None] * d
    on_edge = np.array([point_segment_distance(q, edges[:, 0], edges[:, 1]).min() <= EPS for q in probes])
    return bool((points_in_polygon(probes, polygon) & ~on_edge).any())
