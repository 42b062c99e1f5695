"""The raycaster's column kernels: the spans of one (sub-)column to radiance and depth.

See :mod:`agvsim.sensors.render._raycast_kernels` for the geometry. Radiance is linear
and relative (:mod:`agvsim.sensors.render.lighting`): reflectance x (ambient + lamps) x
the lighting level at the surface point, as the pyrender backend's deferred shading. Faces
are :mod:`agvsim.sensors.render._raycast_face`'s; the floor comes from the floor pass
(:mod:`agvsim.sensors.render._raycast_floor`), the pixels a span covers only in part sampled
where it does; tops and background are here.
"""
from __future__ import annotations

import math

import numpy as np

from agvsim.sensors.render._raycast_face import shade_face
from agvsim.sensors.render._raycast_floor import floor_level
from agvsim.sensors.render._raycast_kernels import FAR, lamp_irradiance, raster_lookup
from agvsim.sensors.render.kernel_jit import span_helper

__all__ = ["shade_column", "shade_flat"]

_FACE, _FLAT, _BACKGROUND = 0, 1, 2  # agvsim.sensors.render.ray_records.SpanKind


@span_helper
def _wrap(x, n, inv_n):
    """``x`` (float texel coordinate) folded into ``0 <= x < n``."""
    x = x - n * math.floor(x * inv_n)
    return x if x < n else 0.0


@span_helper
def shade_flat(view, scene, sub, sid, hh, y0, y1, acc):
    """Add the radiance of a flat span (the floor, ``sid < 0``, or the top of solid ``sid`` at
    height ``hh`` m) over rows ``y0 .. y1`` of the sub-column ``sub``
    (:class:`~agvsim.sensors.render.ray_records.SubColumn`: ``x0 .. x1``, times its weight) to
    ``acc`` ``(H,)``, each pixel sampled at the middle of the part the span covers."""
    tex = scene.tex
    light = scene.light
    floor = scene.floor
    x0 = sub.x0
    x1 = sub.x1
    weight = sub.weight
    h_img = view.height
    fy = view.fy
    cy = view.cy
    hc = view.cam_z
    xn = (0.5 * (x0 + x1) - view.cx) / view.fx
    dx = view.fwd_x + xn * view.right_x
    dy = view.fwd_y + xn * view.right_y
    span_x = (x1 - x0) / view.fx  # the footprint's width per metre of depth
    fk = floor.texture
    tex_w = tex.width[fk]
    inv_tw = 1.0 / floor.tile_w
    inv_th = 1.0 / floor.tile_h
    k = fy * (hc - hh)
    zone = light.floor_zone_irradiance if view.level < 0.0 else light.floor_irradiance
    gain = weight * (1.0 if view.level < 0.0 else view.level)
    mip = tex.mip
    i_lo = max(int(math.floor(y0 + 0.5)), 0)
    i_hi = min(int(math.floor(y1 + 0.5)), h_img - 1)
    for i in range(i_lo, i_hi + 1):
        ya = i - 0.5
        yb = i + 0.5
        if ya < y0:
            ya = y0
        if yb > y1:
            yb = y1
        cov = yb - ya
        if cov <= 0.0:
            continue
        ym = 0.5 * (ya + yb)
        zm = k / (ym - cy) if ym - cy > k / FAR else FAR
        px = view.cam_x + zm * dx
        py = view.cam_y + zm * dy
        if sid < 0:  # the floor, sampled at the footprint's scale
            za = k / (yb - cy) if yb - cy > k / FAR else FAR
            zb = k / (ya - cy) if ya - cy > k / FAR else FAR
            lv = floor_level(tex, fk, max(zb - za, zm * span_x) * inv_tw * tex_w)
            mw = tex.mip_width[fk, lv]
            mh = tex.mip_height[fk, lv]
            moff = tex.mip_offset[fk, lv]
            xt = _wrap(px * inv_tw * mw - 0.5, mw, 1.0 / mw)
            yt = _wrap(py * inv_th * mh - 0.5, mh, 1.0 / mh)
            j0 = min(int(xt), mw - 1)
            i0 = min(int(yt), mh - 1)
            fj = xt - j0
            fi = yt - i0
            j1 = j0 + 1 if j0 + 1 < mw else 0
            i1 = i0 + 1 if i0 + 1 < mh else 0
            r0 = moff + i0 * mw
            r1 = moff + i1 * mw
            alb = ((mip[r0 + j0] * (1.0 - fj) + mip[r0 + j1] * fj) * (1.0 - fi)
                   + (mip[r1 + j0] * (1.0 - fj) + mip[r1 + j1] * fj) * fi)
            irr = raster_lookup(light, zone, px, py)
        else:
            alb = scene.solids.top_albedo[sid]
            irr = light.ambient + lamp_irradiance(light, px, py, hh, 0.0, 0.0, 1.0)
            if view.level < 0.0:
                irr *= raster_lookup(light, light.zone, px, py)
        acc[i] += gain * cov * alb * irr


@span_helper
def _flat_depth(view, sub, kind, sid, hh, y0, y1, depth, floor_depth):
    """The depth at the pixel centres ``y0 <= i < y1`` of a span that is not a face: the floor's
    row depth (``floor_depth``), a solid's top at height ``hh`` m (``fy (cam_z - hh) / (i - cy)``),
    or 0 (background). The same rule as the faces' (``ceil(y0) <= i <= ceil(y1) - 1``, in
    integers): the spans of a column, which share their ends, give every centre exactly once.
    Of the floor, rows ``sub.skip_lo .. sub.skip_hi`` are left (the caller took them from the floor pass)."""
    skip_lo = sub.skip_lo
    skip_hi = sub.skip_hi
    lo = max(int(math.ceil(y0)), 0)
    hi = min(int(math.ceil(y1)) - 1, view.height - 1)
    if kind == _FLAT and sid < 0:
        for i in range(np.uint64(lo), np.uint64(max(min(hi, skip_lo - 1) + 1, lo))):
            depth[i] = floor_depth[i]
        for i in range(np.uint64(max(lo, skip_hi + 1)), np.uint64(max(hi + 1, lo, skip_hi + 1))):
            depth[i] = floor_depth[i]
    elif kind == _FLAT:
        k = view.fy * (view.cam_z - hh)
        for i in range(lo, hi + 1):
            depth[i] = k / (i - view.cy) if i - view.cy > k / FAR else 0.0
    else:
        for i in range(np.uint64(lo), np.uint64(max(hi + 1, lo))):
            depth[i] = 0.0


@span_helper
def _floor_span(view, scene, sub, y0, y1, work):
    """A span of the floor in the sub-column ``sub`` of column ``sub.j``, into ``work.acc``: the
    pixels it covers whole and the floor pass drew (``work.drawn[j]``, the pass's
    ``work.floor_img[:, j]``), the others from :func:`shade_flat`; rows ``sub.skip_lo ..
    sub.skip_hi`` (whole, drawn) not at all (the caller takes them from the floor pass)."""
    acc = work.acc
    floor_img = work.floor_img
    drawn = work.drawn
    j = sub.j
    i_lo = max(int(math.floor(y0 + 0.5)), 0)
    i_hi = min(int(math.floor(y1 + 0.5)), view.height - 1)
    f_lo = max(int(math.ceil(y0 + 0.5)), i_lo)  # rows covered whole
    f_hi = min(int(math.floor(y1 - 0.5)), i_hi)
    floor_id = np.int64(-1)
    for i in range(i_lo, i_hi + 1):
        if sub.skip_lo <= i <= sub.skip_hi:
            continue
        if f_lo <= i <= f_hi and drawn[j, i]:
            acc[i] += sub.weight * floor_img[i, j]
        else:  # a pixel the span covers in part (sampled where it does), or one the pass did not draw
            ya = max(i - 0.5, y0)
            yb = min(i + 0.5, y1)
            if yb > ya:
                shade_flat(view, scene, sub, floor_id, 0.0, ya, yb, acc)


@span_helper
def _background(view, scene, sub, y0, y1, acc):
    """Add the background's radiance over rows ``y0 .. y1`` of the sub-column ``sub`` to ``acc``."""
    h_img = view.height
    i_lo = max(int(math.floor(y0 + 0.5)), 0)
    i_hi = min(int(math.floor(y1 + 0.5)), h_img - 1)
    bg = sub.weight * scene.floor.background * view.background_level
    f_lo = max(int(math.ceil(y0 + 0.5)), i_lo)  # rows covered whole
    f_hi = min(int(math.floor(y1 - 0.5)), i_hi)
    # the rows above and below the whole ones (one at most each)
    bot = max(f_hi + 1, f_lo, i_lo)
    n_top = max(min(f_lo, i_hi + 1) - i_lo, 0)
    for q in range(n_top + max(i_hi + 1 - bot, 0)):
        i = i_lo + q if q < n_top else bot + q - n_top
        ya = max(y0, i - 0.5)
        yb = min(y1, i + 0.5)
        if yb > ya:
            acc[i] += bg * (yb - ya)
    for i in range(np.uint64(f_lo), np.uint64(max(f_hi + 1, f_lo))):
        acc[i] += bg


@span_helper
def shade_column(view, scene, sub, ns, work, depth):
    """Add the radiance of the ``ns`` spans in ``work.spans`` (rows ``y0 .. y1``, kind, id, value of
    span ``k`` at ``k``: :func:`~agvsim.sensors.render._raycast_kernels.cast_ray`) over the
    sub-column ``sub`` (:class:`~agvsim.sensors.render.ray_records.SubColumn`, times its weight)
    to ``work.acc`` ``(H,)`` float64.

    Args:
        scene: :class:`~agvsim.sensors.render.ray_records.Scene`.
        work: the frame's :class:`~agvsim.sensors.render.ray_records.FrameScratch`; the floor
            from the floor pass (:func:`agvsim.sensors.render._raycast_floor.floor_rows`) is in it.
        depth: ``(H,)`` float32 depth at the pixel centres (m along the axis, 0 = nothing),
            written when ``sub.write_depth``: every pixel centre's exactly once but the rows
            ``sub.skip_lo .. sub.skip_hi``, which are left out (neither radiance nor depth).
    """
    spans = work.spans
    acc = work.acc
    for k in range(ns):
        y0 = spans.y0[k]
        y1 = spans.y1[k]
        if y1 <= y0:
            continue
        kind = spans.kind[k]
        sid = spans.id[k]
        if kind == _FACE:
            shade_face(view, scene, sub, sid, spans.val[k], y0, y1, work, depth)
            continue  # (the face writes its depth)
        if kind == _FLAT and sid < 0:
            _floor_span(view, scene, sub, y0, y1, work)
        elif kind == _FLAT:
            shade_flat(view, scene, sub, sid, spans.val[k], y0, y1, acc)
        else:
            _background(view, scene, sub, y0, y1, acc)
        if sub.write_depth:  # the pixel centres in the span, y0 <= i < y1, as the faces take theirs
            _flat_depth(view, sub, kind, sid, spans.val[k], y0, y1, depth, work.floor_depth)
