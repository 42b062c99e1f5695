"""The raycaster's frame kernels: a column's spans to radiance, and a whole level frame.

See :mod:`agvsim.sensors.render._raycast_kernels` for the geometry. Radiance is linear
and relative (:mod:`agvsim.sensors.render.lighting`): reflectance x (ambient + lamps) x
the lighting level at the surface point, as the pyrender backend's deferred shading.

A frame (:func:`render_view`) is drawn in three passes: the spans of every column edge
ray; the floor, row by row, over the columns between the first and last that show it over
a whole pixel in that row (:mod:`agvsim.sensors.render._raycast_floor`); then each column, its spans shaded into
one column of the image: faces by
:mod:`agvsim.sensors.render._raycast_face`, the floor from the floor pass (the pixels a
span covers only in part sampled where it does), tops and background here.
"""
from __future__ import annotations

import math

import numpy as np

from agvsim.sensors.render._raycast_face import shade_face
from agvsim.sensors.render._raycast_floor import floor_level, floor_rows
from agvsim.sensors.render._sensor_kernels import column_counter, expose_flat, store_columns
from agvsim.sensors.render.ray_records import EXPOSE_BLOCK
from agvsim.sensors.render._raycast_kernels import (FAR, MAX_HITS, MAX_SPANS, bin_solids, cast_ray, lamp_irradiance,
                                                    raster_lookup, same_spans)
from localizer._jit import borrowed
from localizer._jit import fast_inline as inline
from localizer._jit import fast_jit as jit

__all__ = ["render_view", "shade_column"]

_FACE, _FLAT, _BACKGROUND = 0, 1, 2


@inline
def _wrap(x, n, inv_n):
    """``x`` (float texel coordinate) folded into ``0 <= x < n``."""
    x = x - n * math.floor(x * inv_n)
    return x if x < n else 0.0


@inline
def _whole_rows(y0, y1, h):
    """``(lo, hi)``: the rows ``0 <= i < h`` the span ``y0 .. y1`` covers whole (none if ``hi < lo``)."""
    return max(int(math.ceil(y0 + 0.5)), 0), min(int(math.floor(y1 - 0.5)), h - 1)


@inline
def _zero_outside(acc, lo, hi):
    """``acc`` set to 0 but at ``lo .. hi`` (everywhere if ``hi < lo``; ``lo <= acc.size``)."""
    for i in range(np.uint64(lo)):  # (unsigned: vectorised fills)
        acc[i] = 0.0
    for i in range(np.uint64(max(hi + 1, lo)), np.uint64(acc.size)):
        acc[i] = 0.0


@inline
def _shade_flat(view, tex, light, floor, solids, sid, hh, y0, y1, x0, x1, weight, acc):
    """Add ``weight`` x the radiance of a flat span (the floor, ``sid < 0``, or the top of solid
    ``sid`` at height ``hh`` m) over rows ``y0 .. y1`` of the (sub-)column ``x0 .. x1`` to ``acc``,
    each pixel sampled at the middle of the part the span covers."""
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
            alb = solids.top_albedo[sid]
            irr = light.ambient + lamp_irradiance(light, px, py, hh, 0.0, 0.0, 1.0)
            if view.level < 0.0:
                irr *= raster_lookup(light, light.zone, px, py)
        acc[i] += gain * cov * alb * irr


@inline
def _flat_depth(view, kind, sid, hh, y0, y1, depth, floor_depth, skip_lo, skip_hi):
    """The depth at the pixel centres ``y0 <= i < y1`` of a span that is not a face: the floor's
    row depth (``floor_depth``), a solid's top at height ``hh`` m (``fy (cam_z - hh) / (i - cy)``),
    or 0 (background). The same rule as the faces' (``ceil(y0) <= i <= ceil(y1) - 1``, in
    integers): the spans of a column, which share their ends, give every centre exactly once.
    Of the floor, rows ``skip_lo .. skip_hi`` are left (the caller took them from the floor pass)."""
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


@inline
def _floor_span(view, tex, light, floor, solids, y0, y1, x0, x1, weight, acc, floor_img, drawn, j, skip_lo,
                skip_hi):
    """A span of the floor in column ``j``: the pixels it covers whole and the floor pass drew
    (``drawn[j]``, the pass's ``floor_img[:, j]``), the others from :func:`_shade_flat`; rows
    ``skip_lo .. skip_hi`` (whole, drawn) not at all (the caller takes them from the floor pass)."""
    i_lo = max(int(math.floor(y0 + 0.5)), 0)
    i_hi = min(int(math.floor(y1 + 0.5)), view.height - 1)
    f_lo = max(int(math.ceil(y0 + 0.5)), i_lo)  # rows covered whole
    f_hi = min(int(math.floor(y1 - 0.5)), i_hi)
    for i in range(i_lo, i_hi + 1):
        if skip_lo <= i <= skip_hi:
            continue
        if f_lo <= i <= f_hi and drawn[j, i]:
            acc[i] += weight * floor_img[i, j]
        else:  # a pixel the span covers in part (sampled where it does), or one the pass did not draw
            ya = max(i - 0.5, y0)
            yb = min(i + 0.5, y1)
            if yb > ya:
                _shade_flat(view, tex, light, floor, solids, -1, 0.0, ya, yb, x0, x1, weight, acc)


@inline
def shade_column(view, faces, decals, tex, light, floor, solids, ns, sp_y0, sp_y1, sp_val, sp_kind, sp_id, ko,
                 x0, x1, weight, acc, depth, write_depth, work, floor_img, drawn, j, floor_depth, skip_lo,
                 skip_hi):
    """Add ``weight`` x the radiance of the spans of the (sub-)column ``x0 .. x1`` of column
    ``j`` to ``acc``.

    Args:
        ns, sp_y0, sp_y1, sp_val: the spans: rows and value of span ``k`` at ``k``;
            sp_kind, sp_id: their kind and id at ``ko + k`` (:func:`cast_ray`).
        acc: ``(H,)`` float64 radiance accumulator of the column.
        depth: ``(H,)`` float32 depth at the pixel centres (m along the axis, 0 = nothing),
            written when ``write_depth``.
        work: the frame's :class:`~agvsim.sensors.render.ray_records.FrameScratch` (the face
            kernel's, :func:`~agvsim.sensors.render._raycast_face.shade_face`).
        floor_img, drawn, floor_depth: the floor from the floor pass
            (:func:`agvsim.sensors.render._raycast_floor.floor_rows`): radiance ``(H, W)``
            (column ``j`` read), which rows of each column it drew ``(W, H)`` uint8, the floor's
            depth per row ``(H,)``.
        skip_lo, skip_hi: rows a floor span covers whole and the pass drew that are left out
            (neither ``acc`` nor ``depth`` written there; none if ``skip_hi < skip_lo``). Every other
            pixel centre's depth is written exactly once (when ``write_depth``).
    """
    h_img = view.height
    for k in range(ns):
        y0 = sp_y0[k]
        y1 = sp_y1[k]
        if y1 <= y0:
            continue
        kind = sp_kind[ko + k]
        sid = sp_id[ko + k]
        if kind == _FACE:
            shade_face(view, faces, decals, tex, light, sid, sp_val[k], y0, y1, x0, x1, weight, acc, depth,
                       write_depth, work)
            continue  # (the face writes its depth)
        if kind == _FLAT and sid < 0:
            _floor_span(view, tex, light, floor, solids, y0, y1, x0, x1, weight, acc, floor_img, drawn, j, skip_lo,
                        skip_hi)
        elif kind == _FLAT:
            _shade_flat(view, tex, light, floor, solids, sid, sp_val[k], y0, y1, x0, x1, weight, acc)
        else:
            i_lo = max(int(math.floor(y0 + 0.5)), 0)
            i_hi = min(int(math.floor(y1 + 0.5)), h_img - 1)
            bg = weight * floor.background * view.background_level
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
        if write_depth:  # the pixel centres in the span, y0 <= i < y1, as the faces take theirs
            _flat_depth(view, kind, sid, sp_val[k], y0, y1, depth, floor_depth, skip_lo, skip_hi)


@jit
def render_view(view, solids, faces, decals, tex, light, floor, radiance_t, depth_t, work, params, image):
    """Draw one level frame, column-major.

    Args:
        view: the camera (:class:`~agvsim.sensors.render.ray_records.View`).
        radiance_t: out ``(W, H)`` float32, C-contiguous: radiance (relative), column ``j`` of
            the image at ``radiance_t[j]`` (the transpose of the ``(H, W)`` frame).
        depth_t: out ``(W, H)`` float32, C-contiguous: depth (m along the optical axis, 0 =
            nothing), likewise.
        work: the :class:`~agvsim.sensors.render.ray_records.FrameScratch` for ``W`` x ``H``
            (:data:`MAX_SPANS`, :data:`MAX_HITS`, ``scratch_size(H)``).
        params, image: ``image`` of shape ``(0, 0)``: the radiance is stored in ``radiance_t``.
            Else ``image`` ``(H, W)`` uint8, C-contiguous, out: the frame exposed by the sensor
            (:class:`~agvsim.sensors.render.ray_records.SensorParams` ``params``) column by column
            as it is drawn, exactly as
            :func:`~agvsim.sensors.render._sensor_kernels.expose_columns` exposes the stored
            radiance (bit for bit: each column in float32, its own noise counter), and
            ``radiance_t`` is not written: the radiance never leaves the first levels of the
            cache (a 1 MB store and load the less).

    The column pass shades each column into contiguous scratch and stores it whole where the
    frame holds it contiguously (a row-major frame would take each column a pixel per row,
    one cache line each: a fifth of the frame's time, storing blocks of columns row by row).
    Accumulating in the frame itself instead was slower (a read-modify-write per sample in a
    1 MB array, where the scratch stays in the first level of the cache).
    The floor pass draws into ``work.floor_img`` (rows padded past a power-of-two stride: the
    columns read it down a column, and rows 2 kB apart would share a few sets of the cache);
    where a column's largest floor span covers the rows whole and the pass drew them, the
    column takes its values from there as they are (the sum it would take, 0 + 1 x the pass's
    value, is that value) and the floor's depth.

    Every array argument is used :func:`~localizer._jit.borrowed` (the caller holds them):
    the inlined helpers take records of arrays per ray, column and span, and counting
    references to them would cost a tenth of the frame.
    """
    solids = borrowed(solids)
    faces = borrowed(faces)
    decals = borrowed(decals)
    tex = borrowed(tex)
    light = borrowed(light)
    radiance_t = borrowed(radiance_t)
    depth_t = borrowed(depth_t)
    work = borrowed(work)
    image = borrowed(image)
    exposed = image.shape[0] > 0
    column = work.column
    cols = work.exposed
    w = view.width
    h = view.height
    start, items = bin_solids(view, solids)
    hit_in = work.hit_in
    hit_out = work.hit_out
    hit_solid = work.hit_solid
    hit_edge = work.hit_edge
    # the spans of every column edge ray (edge r at x = r - 0.5), ray r's at offset r * MAX_SPANS
    e_y0 = work.e_y0
    e_y1 = work.e_y1
    e_kind = work.e_kind
    e_id = work.e_id
    e_val = work.e_val
    e_n = work.e_n
    for r in range(w + 1):
        c = max(r - 1, 0)  # the column left of the ray (its solids' list reaches 0.51 px beyond it)
        e_n[r] = cast_ray(view, solids, floor, r - 0.5, items, start[c], start[c + 1] - start[c], hit_in, hit_out,
                          hit_solid, hit_edge, e_y0, e_y1, e_kind, e_id, e_val, r * MAX_SPANS)
    # the rows of each column where some edge ray sees the floor whole: the floor pass draws them
    drawn_t = work.drawn
    for j in range(w):
        for i in range(h):
            drawn_t[j, i] = 0
    row_lo = work.row_lo  # the first and last column to draw in each row
    row_hi = work.row_hi
    for i in range(h):
        row_lo[i] = w
        row_hi[i] = -1
    for r in range(w + 1):  # edge ray r bounds columns r - 1 and r (one of them at the image's sides)
        ja = max(r - 1, 0)
        jb = min(r, w - 1)
        o = r * MAX_SPANS
        for k in range(e_n[r]):
            if e_kind[o + k] == _FLAT and e_id[o + k] < 0 and e_y1[o + k] > e_y0[o + k]:
                lo = max(int(math.ceil(e_y0[o + k] + 0.5)), 0)
                hi = min(int(math.floor(e_y1[o + k] - 0.5)), h - 1)
                if hi < lo:
                    continue
                for i in range(np.uint64(lo), np.uint64(hi + 1)):  # unsigned: the loop is vectorised
                    drawn_t[ja, i] = 1
                    drawn_t[jb, i] = 1
                    row_lo[i] = min(row_lo[i], ja)
                    row_hi[i] = jb  # the rays come in column order
    floor_depth = work.floor_depth
    floor_img = work.floor_img
    floor_rows(view, tex, light, floor, row_lo, row_hi, floor_img, floor_depth, work.floor_idx, work.floor_wts)
    my0 = work.my0
    my1 = work.my1
    mkind = work.mkind
    mid = work.mid
    mval = work.mval
    acc = work.acc
    for i in range(h):
        acc[i] = 0.0
    sub = max(view.subcolumns, 1)
    # each column's radiance is shaded into ``acc`` (in the first level of the cache) and stored
    # whole, contiguous in the column-major frame; its depth is written there directly. Of the
    # floor, a column's largest span leaves the rows it covers whole where the floor pass drew
    # them (s_lo .. s_hi): there the pass's radiance is taken as it is (0 + 1 x it, the column's
    # sum) and the depth is the floor's row's
    for j in range(w):
        uj = np.uint64(j)
        dcol = depth_t[j]
        oa = j * MAX_SPANS
        ob = oa + MAX_SPANS
        n_a = e_n[j]
        n_b = e_n[j + 1]
        s_lo = h
        s_hi = -1
        if same_spans(e_kind, e_id, n_a, oa, n_b, ob):
            for k in range(n_b):
                my0[k] = 0.5 * (e_y0[oa + k] + e_y0[ob + k])
                my1[k] = 0.5 * (e_y1[oa + k] + e_y1[ob + k])
                if e_kind[ob + k] == _FACE:  # 1/Z is affine across a plane
                    mval[k] = 2.0 / (1.0 / e_val[oa + k] + 1.0 / e_val[ob + k])
                else:
                    mval[k] = e_val[ob + k]
                if e_kind[ob + k] == _FLAT and e_id[ob + k] < 0:
                    lo, hi = _whole_rows(my0[k], my1[k], h)
                    if hi - lo > s_hi - s_lo:
                        # of them, those the floor pass drew: the edge rays' same span's
                        # whole rows (the middle's lie between theirs), when they meet
                        la, ha = _whole_rows(e_y0[oa + k], e_y1[oa + k], h)
                        lb, hb = _whole_rows(e_y0[ob + k], e_y1[ob + k], h)
                        if ha < la:
                            la, ha = lb, hb
                        elif hb >= lb and max(la, lb) <= min(ha, hb) + 1:
                            la, ha = min(la, lb), max(ha, hb)
                        elif hb - lb > ha - la:
                            la, ha = lb, hb
                        lo = max(lo, la)
                        hi = min(hi, ha)
                        if hi - lo > s_hi - s_lo:
                            s_lo = lo
                            s_hi = hi
            if s_hi < s_lo:
                s_lo = h
                s_hi = -1
            _zero_outside(acc, s_lo, s_hi)
            for i in range(np.uint64(s_lo), np.uint64(max(s_hi + 1, s_lo))):  # the rows kept from the floor pass
                dcol[i] = floor_depth[i]
            shade_column(view, faces, decals, tex, light, floor, solids, n_b, my0, my1, mval, e_kind, e_id, ob,
                         j - 0.5, j + 0.5, 1.0, acc, dcol, True, work, floor_img, drawn_t, j, floor_depth,
                         s_lo, s_hi)
        else:
            for i in range(h):
                acc[i] = 0.0
            for qs in range(sub):
                x0 = j - 0.5 + qs / sub
                x1 = j - 0.5 + (qs + 1) / sub
                n_c = cast_ray(view, solids, floor, 0.5 * (x0 + x1), items, start[j], start[j + 1] - start[j],
                               hit_in, hit_out, hit_solid, hit_edge, my0, my1, mkind, mid, mval, 0)
                shade_column(view, faces, decals, tex, light, floor, solids, n_c, my0, my1, mval, mkind, mid, 0,
                             x0, x1, 1.0 / sub, acc, dcol, x0 <= j < x1, work, floor_img, drawn_t, j,
                             floor_depth, h, -1)
        # the column's radiance, contiguous in the frame (or in ``column``, to be exposed): the
        # shaded rows and the rows kept from the floor pass (its radiance as it is)
        out = column if exposed else radiance_t[uj]
        for i in range(np.uint64(s_lo)):
            out[i] = acc[i]
        for i in range(np.uint64(s_lo), np.uint64(max(s_hi + 1, s_lo))):
            out[i] = floor_img[i, uj]
        for i in range(np.uint64(max(s_hi + 1, s_lo)), np.uint64(h)):
            out[i] = acc[i]
        if exposed:  # into a block of columns, stored in the 8-bit frame a block at a time
            q = j % EXPOSE_BLOCK
            expose_flat(column, cols[q, :h], params, column_counter(params, h, j))
            if q == EXPOSE_BLOCK - 1 or j == w - 1:
                store_columns(cols, j - q, q + 1, image)
