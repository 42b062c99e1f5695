"""The column raycaster's compiled kernels (numba, :data:`localizer._jit.jit`).

With a level camera (horizontal optical axis, level rows: thesis §3.5) and a world of
vertical faces standing on a horizontal floor, the image column at ``x`` sees exactly what
lies along one ray of the floor plan: a height profile ``h(Z)`` made of convex prisms
(walls, obstacles). Walking that profile front to back gives, for the column, a list of
*spans* (rows ``y0 .. y1`` in continuous image coordinates, pixel ``i`` covering
``i - 0.5 .. i + 0.5``): vertical faces where the profile rises, flat surfaces (floor,
tops lower than the lens) between, the background above what is left. Nearer spans hide
farther ones because the open part of a column is always the rows above everything drawn
so far (everything stands on the floor).

Anti-aliasing is by area:

* vertically, each pixel row integrates the face's texture exactly over the heights it
  covers (summed-area tables of the piecewise-constant texels, :func:`box_average`);
* horizontally, a column whose two edge rays see the same spans is drawn once from the
  mean of their spans (the span edges are straight across the column), integrating the
  texture over the column's footprint on each face; a column a silhouette crosses is cut
  into ``View.subcolumns`` sub-columns, each drawn from its own centre ray over its own
  footprint.

Depth is along the optical axis; the ray spacing is even on the image plane. A ray is
clipped against each prism's half-planes (Cyrus-Beck), so it cannot pass between two
faces that share an edge: grazing a corner gives an empty interval, not a leak.
"""
from __future__ import annotations

import math

import numpy as np

from agvsim.sensors.render.kernel_jit import kernel, span_helper

__all__ = ["FAR", "MAX_HITS", "MAX_SPANS", "bin_solids", "cast_ray", "lamp_irradiance", "raster_lookup", "same_spans"]

MAX_SPANS = 96  # spans per ray (a column crossing every rack of a plant sees ~20)
MAX_HITS = 96  # prisms crossed per ray
_FACE, _FLAT, _BACKGROUND = 0, 1, 2  # agvsim.sensors.render.ray_records.SpanKind
FAR = 1.0e4  # m, depth of the horizon for flat spans that run to infinity


# ------------------------------------------------------------------ lighting
@span_helper
def lamp_irradiance(light, px, py, pz, nx, ny, nz):
    """Irradiance from the 3 x 3 ceiling lamps nearest ``(px, py, pz)`` on a surface of unit
    normal ``n`` (:meth:`agvsim.sensors.render.lighting.Illumination.lamp_irradiance`)."""
    s = light.spacing
    i0 = math.floor((px - light.lamp_x0) / s + 0.5)
    j0 = math.floor((py - light.lamp_y0) / s + 0.5)
    dz = light.lamp_z - pz
    if dz <= 0.0:
        return 0.0
    total = 0.0
    for di in range(-1, 2):
        dx = (light.lamp_x0 + (i0 + di) * s) - px
        for dj in range(-1, 2):
            dy = (light.lamp_y0 + (j0 + dj) * s) - py
            r2 = dx * dx + dy * dy + dz * dz
            c = dx * nx + dy * ny + dz * nz
            if c > 0.0:
                total += c * dz / (r2 * r2)
    return total * light.gain


@span_helper
def raster_lookup(light, raster, x, y):
    """Bilinear value of a lighting raster at map point ``(x, y)`` (edges replicated)."""
    mx = (x - light.raster_x0) / light.raster_res
    my = (y - light.raster_y0) / light.raster_res
    rows, cols = raster.shape
    j = int(math.floor(mx))
    i = int(math.floor(my))
    fj = mx - j
    fi = my - i
    j0 = min(max(j, 0), cols - 1)
    j1 = min(max(j + 1, 0), cols - 1)
    i0 = min(max(i, 0), rows - 1)
    i1 = min(max(i + 1, 0), rows - 1)
    return ((raster[i0, j0] * (1.0 - fj) + raster[i0, j1] * fj) * (1.0 - fi)
            + (raster[i1, j0] * (1.0 - fj) + raster[i1, j1] * fj) * fi)


# ------------------------------------------------------------------ rays
@span_helper
def _ray_hits(view, solids, dx, dy, cands, c0, n_cand, hits):
    """The prisms among ``cands[c0:c0 + n_cand]`` that the ray from the lens along ``(dx, dy)``
    (floor plan, per metre of depth) crosses beyond the near plane, into ``hits``
    (:class:`~agvsim.sensors.render.ray_records.Hits`) by entry depth; returns their number."""
    ox = view.cam_x
    oy = view.cam_y
    near = view.near
    hit_in = hits.t_in
    hit_out = hits.t_out
    hit_solid = hits.solid
    hit_edge = hits.edge
    n = 0
    for c in range(n_cand):
        p = cands[c0 + c]
        t_in = -1e300
        t_out = 1e300
        e_in = -1
        for e in range(solids.start[p], solids.start[p + 1]):
            den = solids.edge_nx[e] * dx + solids.edge_ny[e] * dy
            num = solids.edge_nx[e] * (ox - solids.edge_x[e]) + solids.edge_ny[e] * (oy - solids.edge_y[e])
            if den < 0.0:
                t = -num / den
                if t > t_in:
                    t_in = t
                    e_in = e
            elif den > 0.0:
                t = -num / den
                if t < t_out:
                    t_out = t
            elif num > 0.0:
                t_out = -1e300
                break
        if t_out > t_in and t_out > near and n < MAX_HITS:
            # insertion by entry depth
            k = n
            while k > 0 and hit_in[k - 1] > t_in:
                hit_in[k] = hit_in[k - 1]
                hit_out[k] = hit_out[k - 1]
                hit_solid[k] = hit_solid[k - 1]
                hit_edge[k] = hit_edge[k - 1]
                k -= 1
            hit_in[k] = t_in
            hit_out[k] = t_out
            hit_solid[k] = p
            hit_edge[k] = e_in
            n += 1
    return n


@span_helper
def _floor_interval(floor, ox, oy, dx, dy):
    """``(f_in, f_out)``: the depths (m) between which the ray from ``(ox, oy)`` along ``(dx, dy)``
    is over the floor rectangle (``f_out < f_in``: never)."""
    f_in = -1e300
    f_out = 1e300
    if dx != 0.0:
        a = (floor.x0 - ox) / dx
        b = (floor.x1 - ox) / dx
        f_in = max(f_in, min(a, b))
        f_out = min(f_out, max(a, b))
    elif not floor.x0 <= ox <= floor.x1:
        f_out = -1e300
    if dy != 0.0:
        a = (floor.y0 - oy) / dy
        b = (floor.y1 - oy) / dy
        f_in = max(f_in, min(a, b))
        f_out = min(f_out, max(a, b))
    elif not floor.y0 <= oy <= floor.y1:
        f_out = -1e300
    return f_in, f_out


@span_helper
def _put_span(spans, at, y0, y1, kind, sid, val):
    """Span ``at`` of ``spans`` (:class:`~agvsim.sensors.render.ray_records.SpanBuffer`)."""
    spans.y0[at] = y0
    spans.y1[at] = y1
    spans.kind[at] = kind
    spans.id[at] = sid
    spans.val[at] = val


@span_helper
def cast_ray(view, scene, x, cands, c0, n_cand, hits, spans, so):
    """The spans of the column ray at image ``x``, front to back.

    Args:
        scene: :class:`~agvsim.sensors.render.ray_records.Scene` (its solids and floor read).
        cands[c0:c0 + n_cand]: the solids that may cross this ray.
        hits: :class:`~agvsim.sensors.render.ray_records.Hits` scratch.
        spans: :class:`~agvsim.sensors.render.ray_records.SpanBuffer`, out from ``so`` on
            (``MAX_SPANS`` of them at most). (An offset, not a view: a view per ray costs two
            atomic reference counts.)
    Returns:
        the number of spans (they cover ``-0.5 .. height - 0.5`` from the bottom up).
    """
    solids = scene.solids
    xn = (x - view.cx) / view.fx
    dx = view.fwd_x + xn * view.right_x
    dy = view.fwd_y + xn * view.right_y
    n = _ray_hits(view, solids, dx, dy, cands, c0, n_cand, hits)
    f_in, f_out = _floor_interval(scene.floor, view.cam_x, view.cam_y, dx, dy)
    return _walk_profile(view, solids, hits, n, f_in, f_out, spans, so)


@span_helper
def _next_event(hits, n, cursor, z_a, f_in, f_out):
    """``(z_b, cursor)``: the next depth after ``z_a`` where the ray enters or leaves a prism or
    the floor (1e300: none), and the first hit entered after ``z_a``."""
    z_b = 1e300
    while cursor < n and hits.t_in[cursor] <= z_a:
        cursor += 1
    if cursor < n:
        z_b = hits.t_in[cursor]
    for k in range(n):
        if z_a < hits.t_out[k] < z_b:
            z_b = hits.t_out[k]
    if z_a < f_in < z_b:
        z_b = f_in
    if z_a < f_out < z_b:
        z_b = f_out
    return z_b, cursor


@span_helper
def _walk_profile(view, solids, hits, n, f_in, f_out, spans, so):
    """:func:`cast_ray`'s walk along the ray's height profile (the ``n`` hits, the floor over
    ``f_in .. f_out``), front to back: a face span where the profile rises, a flat span over
    each interval below the lens, the background above what is left."""
    near = view.near
    fy = view.fy
    cy = view.cy
    hc = view.cam_z
    top = view.height - 0.5  # rows above this are still open
    ns = 0
    z_a = near
    h_prev = 0.0 if f_in <= near < f_out else -1.0
    cursor = np.int64(0)
    while top > -0.5 and ns < MAX_SPANS - 2:
        z_b, cursor = _next_event(hits, n, cursor, z_a, f_in, f_out)
        z_m = 0.5 * (z_a + z_b) if z_b < 1e299 else z_a + 1.0
        # the profile's height on (z_a, z_b) and the solid that sets it
        h = 0.0 if f_in <= z_m < f_out else -1.0
        best = -1
        for k in range(n):
            if hits.t_in[k] <= z_m < hits.t_out[k] and solids.height[hits.solid[k]] > h:
                h = solids.height[hits.solid[k]]
                best = k
        if best >= 0 and h > h_prev and hits.t_in[best] >= z_a - 1e-12 and hits.t_in[best] > near:
            face = solids.edge_face[hits.edge[best]]
            z = hits.t_in[best]
            y_hi = cy + fy * (hc - h) / z
            y_lo = cy + fy * (hc - max(h_prev, 0.0)) / z
            y1 = _meet(y_lo, top)
            if face >= 0 and y_hi < y1:
                _put_span(spans, so + ns, max(y_hi, -0.5), y1, np.int64(_FACE), face, z)
                ns += 1
            top = min(top, y_hi)
        if 0.0 <= h < hc and top > -0.5:
            y_near = cy + fy * (hc - h) / z_a
            y_far = cy + fy * (hc - h) / z_b if z_b < FAR else cy + fy * (hc - h) / FAR
            y1 = _meet(y_near, top)
            if y_far < y1:
                _put_span(spans, so + ns, max(y_far, -0.5), y1, np.int64(_FLAT), hits.solid[best] if best >= 0 else np.int64(-1),
                          h)
                ns += 1
            top = min(top, y_far)
        h_prev = h
        if z_b >= 1e299:
            break
        z_a = z_b
    if top > -0.5:
        _put_span(spans, so + ns, -0.5, top, np.int64(_BACKGROUND), np.int64(-2), 0.0)
        ns += 1
    return ns


#: px: span ends closer than this are the same edge (:func:`_meet`)
_SAME_EDGE = 1e-7


@span_helper
def _meet(y, top):
    """A span's lower end ``y`` (px) against ``top``, the upper end of the span below it:
    ``min(y, top)``, and ``top`` itself when they differ by rounding only (the two are the same
    edge, computed twice; spans must share their ends exactly, or a pixel centre between the
    two would belong to neither)."""
    return top if y >= top - _SAME_EDGE else y


@kernel
def bin_solids(view, solids):
    """CSR lists ``(start (W + 1,), items)`` of the solids whose outline may cross each column."""
    w = view.width
    n_solids = solids.height.shape[0]
    lo = np.full(n_solids, -1, np.int64)
    hi = np.full(n_solids, -2, np.int64)
    counts = np.zeros(w + 1, np.int64)
    for p in range(n_solids):
        x_min = 1e300
        x_max = -1e300
        n_e = solids.start[p + 1] - solids.start[p]
        n_front = 0
        for a in range(n_e):
            e = solids.start[p] + a
            e2 = solids.start[p] + (a + 1) % n_e
            # the edge's start vertex is where its line meets the previous edge's: store both
            for q in (e, e2):
                rx = solids.edge_x[q] - view.cam_x
                ry = solids.edge_y[q] - view.cam_y
                zq = rx * view.fwd_x + ry * view.fwd_y
                if zq > view.near:
                    n_front += 1
            ax = solids.edge_x[e] - view.cam_x
            ay = solids.edge_y[e] - view.cam_y
            bx = solids.edge_x[e2] - view.cam_x
            by = solids.edge_y[e2] - view.cam_y
            za = ax * view.fwd_x + ay * view.fwd_y
            zb = bx * view.fwd_x + by * view.fwd_y
            xa = ax * view.right_x + ay * view.right_y
            xb = bx * view.right_x + by * view.right_y
            # clip the edge to the half-space in front of the near plane
            if za <= view.near and zb <= view.near:
                continue
            if za < view.near:
                t = (view.near - za) / (zb - za)
                xa = xa + t * (xb - xa)
                za = view.near
            if zb < view.near:
                t = (view.near - zb) / (za - zb)
                xb = xb + t * (xa - xb)
                zb = view.near
            for xx, zz in ((xa, za), (xb, zb)):
                ix = view.cx + view.fx * xx / zz
                x_min = min(x_min, ix)
                x_max = max(x_max, ix)
        if n_front == 0 or x_max < x_min:
            continue
        j0 = int(math.ceil(x_min - 0.01 - 0.5))
        j1 = int(math.floor(x_max + 0.01 + 0.5))
        j0 = max(j0, 0)
        j1 = min(j1, w - 1)
        if j1 < j0:
            continue
        lo[p] = j0
        hi[p] = j1
        for j in range(j0, j1 + 1):
            counts[j + 1] += 1
    start = np.cumsum(counts)
    items = np.empty(start[w], np.int64)
    fill = start[:w].copy()
    for p in range(n_solids):
        for j in range(lo[p], hi[p] + 1):
            items[fill[j]] = p
            fill[j] += 1
    return start, items


@span_helper
def same_spans(kind, ids, n_a, oa, n_b, ob):
    """Whether the ``n_a`` spans at ``oa`` and the ``n_b`` at ``ob`` of ``kind`` and ``ids`` are of
    the same kinds and ids, in order."""
    if n_a != n_b:
        return False
    for k in range(n_a):
        if kind[oa + k] != kind[ob + k] or ids[oa + k] != ids[ob + k]:
            return False
    return True
