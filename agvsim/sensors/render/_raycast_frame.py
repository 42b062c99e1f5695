"""The raycaster's frame kernels: a column's spans to radiance, and a whole level frame.

See :mod:`agvsim.sensors.render._raycast_kernels` for the geometry. Radiance is linear
and relative (:mod:`agvsim.sensors.render.lighting`): reflectance x (ambient + lamps) x
the lighting level at the surface point, as the pyrender backend's deferred shading.
"""
from __future__ import annotations

import math

import numpy as np

from agvsim.sensors.render._raycast_kernels import (MAX_HITS, MAX_SPANS, bin_solids, cast_ray, decal_cover,
                                                    lamp_irradiance, raster_lookup, same_spans)
from localizer._jit import fast_inline as inline
from localizer._jit import fast_jit as jit

__all__ = ["LIGHT_ROWS", "render_view", "shade_column"]

LIGHT_ROWS = 32.0  # px between the rows where a face's irradiance is evaluated (linear between)
_FACE, _FLAT, _BACKGROUND = 0, 1, 2
_FAR = 1.0e4  # m


@inline
def _face_s(view, faces, f, x):
    """Position along face ``f`` (m from its left end) where the ray of image column ``x``
    meets the face's line, clamped to the face."""
    xn = (x - view.cx) / view.fx
    dx = view.fwd_x + xn * view.right_x
    dy = view.fwd_y + xn * view.right_y
    qx = faces.x[f] - view.cam_x
    qy = faces.y[f] - view.cam_y
    den = dx * faces.ey[f] - dy * faces.ex[f]
    if abs(den) < 1e-12:
        return 0.0 if (qx * dx + qy * dy) > 0 else faces.length[f]
    s = -(dx * qy - dy * qx) / den
    return min(max(s, 0.0), faces.length[f])


@inline
def _face_irradiance(light, f, s, z):
    """Ambient + lamps on face ``f`` at ``s`` (m along it), ``z`` (m up): bilinear in the
    face's table (cells of ``light.face_res``, built once per map)."""
    res = light.face_res
    nc = light.face_cols[f]
    nr = light.face_rows[f]
    fs = min(max(s / res, 0.0), nc - 1.0)
    fz = min(max(z / res, 0.0), nr - 1.0)
    j = min(int(fs), nc - 2) if nc > 1 else 0
    i = min(int(fz), nr - 2) if nr > 1 else 0
    ts = fs - j
    tz = fz - i
    base = light.face_offset[f] + i * nc + j
    t = light.face_irr
    j1 = 1 if nc > 1 else 0
    i1 = nc if nr > 1 else 0
    return ((t[base] * (1.0 - ts) + t[base + j1] * ts) * (1.0 - tz)
            + (t[base + i1] * (1.0 - ts) + t[base + i1 + j1] * ts) * tz)


@inline
def _wrap(x, n, inv_n):
    """``x`` (float texel coordinate) folded into ``0 <= x < n``."""
    x = x - n * math.floor(x * inv_n)
    return x if x < n else 0.0


@inline
def _texel_column(tex, k, lv, u_c, u_half, v0, dvz, hc, cy, zpy, y_lo, y_hi, buf):
    """Level ``lv`` of texture ``k`` along a face span: ``buf[m]`` = the mean of the bilinear
    samples at ``u_c - u_half`` and ``u_c + u_half`` in texel row ``k_lo + m`` (repeated if
    tiled, clamped if not), for the rows image rows ``y_lo .. y_hi`` reach. Returns
    ``(n, a, b)``: the rows filled, and the coordinate ``a + b y`` in ``buf`` of image row ``y``."""
    mw = tex.mip_width[k, lv]
    mh = tex.mip_height[k, lv]
    off = tex.mip_offset[k, lv]
    tiled = tex.tiled[k]
    # texel row coordinate (centre of row r at r) of image row y: v(y) * mh - 0.5
    b = -dvz * zpy * mh
    a = (v0 + dvz * (hc + cy * zpy)) * mh - 0.5
    ra = a + b * y_lo
    rb = a + b * y_hi
    k_lo = int(math.floor(min(ra, rb))) - 1
    n = min(int(math.floor(max(ra, rb))) + 2 - k_lo + 1, buf.shape[0])
    # the two subsample columns: texel column coordinates and weights
    xa = (u_c - u_half) * mw - 0.5
    xb = (u_c + u_half) * mw - 0.5
    ja = int(math.floor(xa))
    jb = int(math.floor(xb))
    fa = xa - ja
    fb = xb - jb
    if tiled:
        ja0 = ja % mw
        ja1 = (ja + 1) % mw
        jb0 = jb % mw
        jb1 = (jb + 1) % mw
    else:
        ja0 = min(max(ja, 0), mw - 1)
        ja1 = min(max(ja + 1, 0), mw - 1)
        jb0 = min(max(jb, 0), mw - 1)
        jb1 = min(max(jb + 1, 0), mw - 1)
    m = tex.mip
    row = k_lo % mh if tiled else k_lo
    for q in range(n):
        rr = row if tiled else min(max(row, 0), mh - 1)
        base = off + rr * mw
        buf[q] = 0.5 * (m[base + ja0] * (1.0 - fa) + m[base + ja1] * fa
                        + m[base + jb0] * (1.0 - fb) + m[base + jb1] * fb)
        row += 1
        if tiled and row == mh:
            row = 0
    return n, a - k_lo, b


@inline
def _column_at(buf, t, n):
    """Linear interpolation of the first ``n`` entries of ``buf`` at coordinate ``t`` (clamped)."""
    if t < 0.0:
        t = 0.0
    if t > n - 1.000001:
        t = n - 1.000001
    q = int(t)
    return buf[q] + (buf[q + 1] - buf[q]) * (t - q)


@inline
def _shade_face(view, faces, decals, tex, light, f, z, y0, y1, x0, x1, gain, acc, depth, write_depth,
                irr_scratch):
    buf0 = irr_scratch[view.height + 2:view.height + 2 + 4 * view.height + 8]
    buf1 = irr_scratch[view.height + 2 + 4 * view.height + 8:]
    h_img = view.height
    fy = view.fy
    cy = view.cy
    hc = view.cam_z
    s_a = _face_s(view, faces, f, x0)
    s_b = _face_s(view, faces, f, x1)
    s_c = 0.5 * (s_a + s_b)
    xn = (0.5 * (x0 + x1) - view.cx) / view.fx
    px = view.cam_x + z * (view.fwd_x + xn * view.right_x)
    py = view.cam_y + z * (view.fwd_y + xn * view.right_y)
    if view.level >= 0.0:
        gain *= view.level
    else:
        gain *= raster_lookup(light, light.zone, px, py)
    zpy = z / fy  # m of height per row
    # irradiance at rows y0 + m * step, linear between
    n_l = int(math.ceil((y1 - y0) / LIGHT_ROWS)) + 1
    step = (y1 - y0) / (n_l - 1)
    inv_step = 1.0 / step
    for m in range(n_l):
        irr_scratch[m] = _face_irradiance(light, f, s_c, hc - (y0 + m * step - cy) * zpy)
    # the texture, filtered as the pyrender reference samples it (2 x 2 supersampling, each
    # sample trilinear at the supersampled footprint): u is fixed across the span and v
    # linear in the row, so each mip level is a column of texels along the span (buf0, buf1)
    tk = faces.texture[f]
    du = (faces.u1[f] - faces.u0[f]) / faces.length[f]
    dvz = (faces.v1[f] - faces.v0[f]) / faces.height[f]
    u_c = faces.u0[f] + du * s_c
    u_half = 0.25 * du * (s_b - s_a)  # texture units from the pixel centre to a subsample
    rho = 0.5 * max(abs(du * (s_b - s_a)) * tex.width[tk], abs(dvz * zpy) * tex.height[tk])
    lam = math.log2(rho) if rho > 1.0 else 0.0
    n_lev = tex.mip_levels[tk]
    lv0 = min(int(lam), n_lev - 1)
    lv1 = min(lv0 + 1, n_lev - 1)
    w1 = (lam - int(lam)) if lv1 > lv0 else 0.0
    t_lo = min(y0, y1) - 1.0
    t_hi = max(y0, y1) + 1.0
    n0, t0a, t0b = _texel_column(tex, tk, lv0, u_c, u_half, faces.v0[f], dvz, hc, cy, zpy, t_lo, t_hi, buf0)
    n1, t1a, t1b = _texel_column(tex, tk, lv1, u_c, u_half, faces.v0[f], dvz, hc, cy, zpy, t_lo, t_hi, buf1)
    d_lo = 1e300
    d_hi = -1e300
    s_lo = min(s_a, s_b)
    s_hi = max(s_a, s_b)
    for d in range(faces.decal_start[f], faces.decal_start[f + 1]):
        if decals.s0[d] < s_hi and decals.s1[d] > s_lo:
            d_lo = min(d_lo, decals.z0[d])
            d_hi = max(d_hi, decals.z1[d])
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
        # two subsample rows, trilinear between the span's two levels
        ta = ym - 0.25
        tb = ym + 0.25
        alb = (1.0 - w1) * 0.5 * (_column_at(buf0, t0a + t0b * ta, n0) + _column_at(buf0, t0a + t0b * tb, n0))
        if w1 > 0.0:
            alb += w1 * 0.5 * (_column_at(buf1, t1a + t1b * ta, n1) + _column_at(buf1, t1a + t1b * tb, n1))
        z_top = hc - (ya - cy) * zpy
        z_bot = hc - (yb - cy) * zpy
        if z_top > d_lo and z_bot < d_hi:
            alb = decal_cover(faces, decals, tex, f, s_a, s_b, z_bot, z_top, alb)
        qq = (ym - y0) * inv_step
        mm = int(qq)
        if mm > n_l - 2:
            mm = n_l - 2
        tt = qq - mm
        acc[i] += gain * cov * alb * (irr_scratch[mm] + (irr_scratch[mm + 1] - irr_scratch[mm]) * tt)
        if write_depth and ya <= i < yb:
            depth[i] = z


@inline
def _shade_flat(view, tex, light, floor, solids, sid, hh, y0, y1, x0, x1, weight, acc, depth, write_depth):
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
        zm = k / (ym - cy) if ym - cy > k / _FAR else _FAR
        px = view.cam_x + zm * dx
        py = view.cam_y + zm * dy
        if sid < 0:  # the floor, sampled at the footprint's scale
            za = k / (yb - cy) if yb - cy > k / _FAR else _FAR
            zb = k / (ya - cy) if ya - cy > k / _FAR else _FAR
            foot = max(zb - za, zm * span_x) * inv_tw * tex_w
            lv = 0
            while foot >= 2.0 and lv < tex.mip_levels[fk] - 1:
                foot *= 0.5
                lv += 1
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
        if write_depth and ya <= i < yb:
            zi = k / (i - cy) if i - cy > k / _FAR else 0.0
            depth[i] = zi


@inline
def shade_column(view, faces, decals, tex, light, floor, solids, ns, sp_y0, sp_y1, sp_kind, sp_id, sp_val,
                 x0, x1, weight, acc, depth, write_depth, irr_scratch):
    """Add ``weight`` x the radiance of the spans of the (sub-)column ``x0 .. x1`` to ``acc``.

    Args:
        acc: ``(H,)`` float64 radiance accumulator of the column.
        depth: ``(H,)`` float32 depth at the pixel centres (m along the axis, 0 = nothing),
            written when ``write_depth``.
        irr_scratch: ``(H + 2,)`` float64 scratch.
    """
    h_img = view.height
    for k in range(ns):
        y0 = sp_y0[k]
        y1 = sp_y1[k]
        if y1 <= y0:
            continue
        kind = sp_kind[k]
        if kind == _FACE:
            _shade_face(view, faces, decals, tex, light, sp_id[k], sp_val[k], y0, y1, x0, x1, weight, acc, depth,
                        write_depth, irr_scratch)
        elif kind == _FLAT:
            _shade_flat(view, tex, light, floor, solids, sp_id[k], sp_val[k], y0, y1, x0, x1, weight, acc, depth,
                        write_depth)
        else:
            i_lo = max(int(math.floor(y0 + 0.5)), 0)
            i_hi = min(int(math.floor(y1 + 0.5)), h_img - 1)
            bg = weight * floor.background * view.background_level
            for i in range(i_lo, i_hi + 1):
                ya = max(y0, i - 0.5)
                yb = min(y1, i + 0.5)
                if yb <= ya:
                    continue
                acc[i] += bg * (yb - ya)
                if write_depth and ya <= i < yb:
                    depth[i] = 0.0


@jit
def render_view(view, solids, faces, decals, tex, light, floor, radiance_t, depth_t):
    """Draw one level frame.

    Args:
        view: the camera (:class:`~agvsim.sensors.render.ray_records.View`).
        radiance_t: out ``(W, H)`` float32, radiance, *transposed* (column-major image).
        depth_t: out ``(W, H)`` float32, depth (m along the optical axis, 0 = nothing), transposed.
    """
    w = view.width
    h = view.height
    start, items = bin_solids(view, solids)
    hit_in = np.empty(MAX_HITS)
    hit_out = np.empty(MAX_HITS)
    hit_solid = np.empty(MAX_HITS, np.int64)
    hit_edge = np.empty(MAX_HITS, np.int64)
    # spans of the column's left edge ray (a), right edge ray (b), mean (m)
    ay0 = np.empty(MAX_SPANS)
    ay1 = np.empty(MAX_SPANS)
    akind = np.empty(MAX_SPANS, np.int64)
    aid = np.empty(MAX_SPANS, np.int64)
    aval = np.empty(MAX_SPANS)
    by0 = np.empty(MAX_SPANS)
    by1 = np.empty(MAX_SPANS)
    bkind = np.empty(MAX_SPANS, np.int64)
    bid = np.empty(MAX_SPANS, np.int64)
    bval = np.empty(MAX_SPANS)
    my0 = np.empty(MAX_SPANS)
    my1 = np.empty(MAX_SPANS)
    mval = np.empty(MAX_SPANS)
    acc = np.zeros(h)
    dcol = np.zeros(h, np.float32)
    scratch = np.empty(h + 2 + 2 * (4 * h + 8))  # irradiance samples, two texel columns
    n_a = cast_ray(view, solids, floor, -0.5, items[start[0]:], start[1] - start[0], hit_in, hit_out,
                   hit_solid, hit_edge, ay0, ay1, akind, aid, aval)
    sub = max(view.subcolumns, 1)
    for j in range(w):
        cand = items[start[j]:]
        n_cand = start[j + 1] - start[j]
        n_b = cast_ray(view, solids, floor, j + 0.5, cand, n_cand, hit_in, hit_out, hit_solid, hit_edge,
                       by0, by1, bkind, bid, bval)
        acc[:] = 0.0
        if same_spans(n_a, akind, aid, n_b, bkind, bid):
            for k in range(n_b):
                my0[k] = 0.5 * (ay0[k] + by0[k])
                my1[k] = 0.5 * (ay1[k] + by1[k])
                if bkind[k] == _FACE:  # 1/Z is affine across a plane
                    mval[k] = 2.0 / (1.0 / aval[k] + 1.0 / bval[k])
                else:
                    mval[k] = bval[k]
            shade_column(view, faces, decals, tex, light, floor, solids, n_b, my0, my1, bkind, bid, mval,
                         j - 0.5, j + 0.5, 1.0, acc, dcol, True, scratch)
        else:
            for q in range(sub):
                x0 = j - 0.5 + q / sub
                x1 = j - 0.5 + (q + 1) / sub
                n_c = cast_ray(view, solids, floor, 0.5 * (x0 + x1), cand, n_cand, hit_in, hit_out, hit_solid,
                               hit_edge, my0, my1, akind, aid, mval)
                shade_column(view, faces, decals, tex, light, floor, solids, n_c, my0, my1, akind, aid, mval,
                             x0, x1, 1.0 / sub, acc, dcol, x0 <= j < x1, scratch)
        for i in range(h):
            radiance_t[j, i] = acc[i]
            depth_t[j, i] = dcol[i]
        # the right edge ray is the next column's left edge ray
        n_a = n_b
        for k in range(n_b):
            ay0[k] = by0[k]
            ay1[k] = by1[k]
            akind[k] = bkind[k]
            aid[k] = bid[k]
            aval[k] = bval[k]

