"""The raycaster's face kernels: a vertical face's span of one image column to radiance.

The texture is filtered as the pyrender reference samples it (2 x 2 supersampling, each
sample trilinear at the supersampled footprint): with a level camera, ``u`` is fixed across
a column's span and ``v`` linear in the row, so each mip level is one column of texels
along the span, built once per span from the level's column-major storage
(:func:`_texel_column`, contiguous runs) and sampled per row; decals are integrated exactly
(:func:`agvsim.sensors.render._raycast_kernels.decal_cover`). Irradiance (ambient + lamps)
is the face's table, evaluated every :data:`LIGHT_ROWS` rows, linear between.
"""
from __future__ import annotations

import math

import numpy as np

from agvsim.sensors.render._raycast_kernels import box_edges, decal_cover, raster_lookup, sat_cell
from agvsim.sensors.render._raycast_rows import plain_rows
from agvsim.sensors.render._simd import PERMUTE, PERMUTE_WINDOW
from localizer._jit import fast_inline as inline

__all__ = ["LIGHT_ROWS", "scratch_size", "shade_face"]

_U1 = np.uint64(1)

LIGHT_ROWS = 32.0  # px between the rows where a face's irradiance is evaluated (linear between)


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
def _face_irradiance(light, f, s, z_top, dz, n, out):
    """Ambient + lamps on face ``f`` at ``s`` (m along it) and the heights ``z_top - m dz``
    (m up), ``m = 0 .. n - 1``, into ``out[:n]``: bilinear in the face's table (cells of
    ``light.face_res``, built once per map); the column of the table at ``s`` is interpolated
    once."""
    res = light.face_res
    inv_res = 1.0 / res
    nc = light.face_cols[f]
    nr = light.face_rows[f]
    fs = min(max(s * inv_res, 0.0), nc - 1.0)
    j = min(int(fs), nc - 2) if nc > 1 else 0
    ts = fs - j
    t = light.face_irr
    j1 = 1 if nc > 1 else 0
    i1 = nc if nr > 1 else 0
    col = light.face_offset[f] + j
    for m in range(n):
        fz = min(max((z_top - m * dz) * inv_res, 0.0), nr - 1.0)
        i = min(int(fz), nr - 2) if nr > 1 else 0
        tz = fz - i
        base = col + i * nc
        out[m] = ((t[base] * (1.0 - ts) + t[base + j1] * ts) * (1.0 - tz)
                  + (t[base + i1] * (1.0 - ts) + t[base + i1 + j1] * ts) * tz)


@inline
def _texel_column(tex, k, lv, u_c, u_half, v0, dvz, hc, cy, zpy, y_lo, y_hi, scale, buf, bo, cap):
    """Level ``lv`` of texture ``k`` along a face span: ``buf[bo + m]`` (float32) = ``scale`` x the mean of the
    bilinear samples at ``u_c - u_half`` and ``u_c + u_half`` in texel row ``k_lo + m`` (repeated
    if tiled, clamped if not), for the rows image rows ``y_lo .. y_hi`` reach (``cap`` at most).
    Returns ``(n, a, b)``: the rows filled, and the coordinate ``a + b y`` (from ``bo``) of image
    row ``y``.

    The level is stored column by column (``tex.column_major[k]``), so this reads four
    contiguous runs of texels (the two texel columns either side of each sample)."""
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
    n = min(int(math.floor(max(ra, rb))) + 2 - k_lo + 1, cap)
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
    ca0 = off + ja0 * mh
    ca1 = off + ja1 * mh
    cb0 = off + jb0 * mh
    cb1 = off + jb1 * mh
    wa0 = np.float32(0.5 * scale * (1.0 - fa))  # (float32, as the texels and buf)
    wa1 = np.float32(0.5 * scale * fa)
    wb0 = np.float32(0.5 * scale * (1.0 - fb))
    wb1 = np.float32(0.5 * scale * fb)
    q = 0
    while q < n:
        r = k_lo + q
        if tiled:
            rr = r % mh
            run = min(n - q, mh - rr)
        elif r < 0 or r >= mh:  # rows beyond the edge repeat the edge row
            rr = 0 if r < 0 else mh - 1
            run = min(n - q, -r) if r < 0 else n - q
            edge = wa0 * m[ca0 + rr] + wa1 * m[ca1 + rr] + wb0 * m[cb0 + rr] + wb1 * m[cb1 + rr]
            o = np.uint64(bo + q)
            for t in range(np.uint64(run)):
                buf[o + t] = edge
            q += run
            continue
        else:
            rr = r
            run = min(n - q, mh - rr)
        # four contiguous runs (unsigned indices, no views: the loop is vectorised)
        o = np.uint64(bo + q)
        a0 = np.uint64(ca0 + rr)
        a1 = np.uint64(ca1 + rr)
        b0 = np.uint64(cb0 + rr)
        b1 = np.uint64(cb1 + rr)
        for t in range(np.uint64(run)):
            buf[o + t] = wa0 * m[a0 + t] + wa1 * m[a1 + t] + wb0 * m[b0 + t] + wb1 * m[b1 + t]
        q += run
    return n, a - k_lo, b


@inline
def _column_at(buf, o, t, n):
    """Linear interpolation of the ``n`` entries ``buf[o:o + n]`` at coordinate ``t`` (clamped)."""
    if t < 0.0:
        t = 0.0
    if t > n - 1.000001:
        t = n - 1.000001
    q = int(t)
    a = np.uint64(o + q)
    return buf[a] + (buf[a + _U1] - buf[a]) * (t - q)


@inline
def _own_reflectance(buf, b0, n0, t0a, t0b, b1, n1, t1a, t1b, ym):
    """The face's own reflectance at row coordinate ``ym``: its two subsample rows
    (``ym -+ 1/4``), trilinear between the span's two levels (their texel columns, weighted, at
    ``buf[b0:]`` and ``buf[b1:]``; coordinate ``ta + tb y`` of image row ``y``; ``n1 == 0``: no
    second level, whose terms would be +0.0)."""
    ta = ym - 0.25
    tb = ym + 0.25
    own = _column_at(buf, b0, t0a + t0b * ta, n0) + _column_at(buf, b0, t0a + t0b * tb, n0)
    if n1 > 0:
        own = own + _column_at(buf, b1, t1a + t1b * ta, n1) + _column_at(buf, b1, t1a + t1b * tb, n1)
    return 0.5 * own


@inline
def _face_pixel(view, faces, decals, tex, f, i, y0, y1, s_a, s_b, hc, cy, zpy, buf, b0, n0, t0a, t0b,
                b1, n1, t1a, t1b, d_lo, d_hi):
    """``(cov, reflectance, ym)`` of face ``f`` in pixel row ``i`` (the part ``y0 .. y1`` covers);
    ``buf[b0:]``, ``buf[b1:]``: the span's texel columns, weighted by their trilinear weights."""
    ya = max(i - 0.5, y0)
    yb = min(i + 0.5, y1)
    cov = yb - ya
    if cov <= 0.0:
        return 0.0, 0.0, 0.0
    ym = 0.5 * (ya + yb)
    alb = _own_reflectance(buf, b0, n0, t0a, t0b, b1, n1, t1a, t1b, ym)
    z_top = hc - (ya - cy) * zpy
    z_bot = hc - (yb - cy) * zpy
    if z_top > d_lo and z_bot < d_hi:
        alb = decal_cover(faces, decals, tex, f, s_a, s_b, z_bot, z_top, alb)
    return cov, alb, ym


@inline
def _sat_row_span(sat, row, ja, fa, jb, fb):
    """Row ``row`` of a summed-area table (``sat[row:]``) at column ``jb + fb`` minus at ``ja + fa``."""
    return (sat[row + jb] + (sat[row + jb + 1] - sat[row + jb]) * fb
            - sat[row + ja] - (sat[row + ja + 1] - sat[row + ja]) * fa)


@inline
def _decal_rows(faces, decals, tex, f, s_lo, s_hi, hc, cy, zpy, lo, hi, gain, buf, b0, n0, t0a, t0b, b1, n1,
                t1a, t1b, irr, y0, inv_step, n_l, acc, cover):
    """Rows ``lo .. hi`` of a face span that covers them whole and that decals reach: the
    face's own reflectance (as :func:`_face_pixel`) where no decal is, each decal's printed
    face integrated exactly over the part of the pixel it covers (as
    :func:`agvsim.sensors.render._raycast_kernels.decal_cover`, whose result this is to
    rounding), times the irradiance, into ``acc``.

    Decal by decal: its columns over the footprint ``s_lo .. s_hi`` (m along the face) are
    found once, then each row's integral is the difference of two rows of the summed-area
    table, each read at those two columns. ``cover``: ``(2 (hi + 1 - lo),)`` float64 scratch."""
    n = hi + 1 - lo
    # cover[q]: sum of coverage x printed mean; cover[n + q]: sum of coverage
    for q in range(2 * n):
        cover[q] = 0.0
    if s_hi - s_lo < 1e-9:
        s_hi = s_lo + 1e-9
    inv_sw = 1.0 / (s_hi - s_lo)
    for d in range(faces.decal_start[f], faces.decal_start[f + 1]):
        a = max(s_lo, decals.s0[d])
        b = min(s_hi, decals.s1[d])
        dz0 = decals.z0[d]
        dz1 = decals.z1[d]
        if b <= a:
            continue
        k = decals.texture[d]
        w = tex.width[k]
        h = tex.height[k]
        stride = w + 1
        off = tex.offset[k]
        sat = tex.sat
        dw = decals.s1[d] - decals.s0[d]
        dh = dz1 - dz0
        # the box's columns in texels, clamped and widened as box_average does
        ua, ub = box_edges((a - decals.s0[d]) / dw * w, (b - decals.s0[d]) / dw * w, w)
        ja, fa = sat_cell(ua, w)
        jb, fb = sat_cell(ub, w)
        weight = (b - a) * inv_sw / (ub - ua)  # the footprint's share over the box's width in texels
        r_lo = max(lo, int(math.floor((hc - dz1) / zpy + cy - 0.5)))
        r_hi = min(hi, int(math.ceil((hc - dz0) / zpy + cy + 0.5)))
        for i in range(r_lo, r_hi + 1):
            z_top = hc - (i - 0.5 - cy) * zpy
            z_bot = hc - (i + 0.5 - cy) * zpy
            c = max(z_bot, dz0)
            e = min(z_top, dz1)
            if e <= c:
                continue
            vc, ve = box_edges((c - dz0) / dh * h, (e - dz0) / dh * h, h)
            ic, gc = sat_cell(vc, h)
            ie, ge = sat_cell(ve, h)
            rc = off + ic * stride
            re = off + ie * stride
            top = (_sat_row_span(sat, re, ja, fa, jb, fb) * (1.0 - ge)
                   + _sat_row_span(sat, re + stride, ja, fa, jb, fb) * ge)
            bottom = (_sat_row_span(sat, rc, ja, fa, jb, fb) * (1.0 - gc)
                      + _sat_row_span(sat, rc + stride, ja, fa, jb, fb) * gc)
            share = (e - c) / (z_top - z_bot)  # of the pixel's height
            q = i - lo
            cover[q] += (top - bottom) * weight * share / (ve - vc)
            cover[n + q] += (b - a) * inv_sw * share
    for q in range(n):
        i = lo + q
        own = _own_reflectance(buf, b0, n0, t0a, t0b, b1, n1, t1a, t1b, float(i))
        acc[i] += gain * (own * (1.0 - cover[n + q]) + cover[q]) * _irr_at(irr, float(i), y0, inv_step, n_l)


@inline
def _irr_at(irr, ym, y0, inv_step, n_l):
    """The span's irradiance at row coordinate ``ym`` (linear between its samples)."""
    qq = (ym - y0) * inv_step
    mm = min(int(qq), n_l - 2)
    return irr[mm] + (irr[mm + 1] - irr[mm]) * (qq - mm)


@inline
def scratch_size(h):
    """Lengths ``(shade, texels)`` of :func:`shade_face`'s scratch for an image ``h`` rows high:
    float64, the irradiance samples (``h + 2``) and the decal rows' coverage (``2 h``); float32,
    the two texel columns (``4 h + 8`` each, and a window's reach past the second:
    :func:`agvsim.sensors.render._simd.pair_sums8`)."""
    return h + 2 + 2 * h, 2 * (4 * h + 8) + PERMUTE_WINDOW


@inline
def shade_face(view, faces, decals, tex, light, f, z, y0, y1, x0, x1, gain, acc, depth, write_depth,
               work):
    """Add ``gain`` x the radiance of face ``f`` (depth ``z`` m along the axis) over rows
    ``y0 .. y1`` of the (sub-)column ``x0 .. x1`` to ``acc`` ``(H,)``; ``depth`` ``(H,)`` gets
    ``z`` at the pixel centres it covers when ``write_depth``. ``work``: the frame's
    :class:`~agvsim.sensors.render.ray_records.FrameScratch` (its ``shade``: irradiance samples
    and decal coverage; its ``texels``: the span's two texel columns, float32)."""
    scratch = work.shade
    texels = work.texels
    h_img = view.height
    cap = 4 * h_img + 8
    b0 = 0  # the texel columns' offsets in texels
    b1 = cap
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
    _face_irradiance(light, f, s_c, hc - (y0 - cy) * zpy, step * zpy, n_l, scratch)
    # the texture, filtered as the pyrender reference samples it (2 x 2 supersampling, each
    # sample trilinear at the supersampled footprint): u is fixed across the span and v
    # linear in the row, so each mip level is a column of texels along the span (at b0, b1)
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
    # (each weighted by its trilinear weight)
    n0, t0a, t0b = _texel_column(tex, tk, lv0, u_c, u_half, faces.v0[f], dvz, hc, cy, zpy, t_lo, t_hi, 1.0 - w1,
                                 texels, b0, cap)
    if w1 > 0.0:
        n1, t1a, t1b = _texel_column(tex, tk, lv1, u_c, u_half, faces.v0[f], dvz, hc, cy, zpy, t_lo, t_hi, w1,
                                     texels, b1, cap)
    else:  # one level (magnified, or the last one): the other's samples would all be +0.0
        n1, t1a, t1b = 0, 0.0, 0.0
    # the rows of decals that this column's footprint on the face crosses
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
    # rows the span covers whole and no decal reaches: the plain loop; the rest pixel by pixel
    f_lo = max(int(math.ceil(y0 + 0.5)), i_lo)
    f_hi = min(int(math.floor(y1 - 0.5)), i_hi)
    b_lo = f_hi + 1
    b_hi = f_hi
    if d_hi > d_lo:  # decal rows: z_top > d_lo and z_bot < d_hi
        b_lo = max(int(math.floor((hc - d_hi) / zpy + cy - 0.5)), f_lo)
        b_hi = min(int(math.ceil((hc - d_lo) / zpy + cy + 0.5)), f_hi)
        if b_hi < b_lo:
            b_lo = f_hi + 1
            b_hi = f_hi
    # the rows above and below the whole ones (one at most each), then the decal band
    n_top = max(min(f_lo, i_hi + 1) - i_lo, 0)
    bot = max(f_hi + 1, f_lo, i_lo)
    n_bot = max(i_hi + 1 - bot, 0)
    n_band = max(b_hi + 1 - b_lo, 0)
    for q in range(n_top + n_bot):
        i = i_lo + q if q < n_top else bot + q - n_top
        cov, alb, ym = _face_pixel(view, faces, decals, tex, f, i, y0, y1, s_a, s_b, hc, cy, zpy, texels, b0, n0,
                                   t0a, t0b, b1, n1, t1a, t1b, d_lo, d_hi)
        if cov > 0.0:
            acc[i] += gain * cov * alb * _irr_at(scratch, ym, y0, inv_step, n_l)
    if n_band > 0:
        _decal_rows(faces, decals, tex, f, s_lo, s_hi, hc, cy, zpy, b_lo, b_hi, gain, texels, b0, n0, t0a, t0b, b1,
                    n1, t1a, t1b, scratch, y0, inv_step, n_l, acc, scratch[h_img + 2:])
    g = 0.5 * gain  # the mean of the two subsample rows, and the gain
    for lo, hi in ((f_lo, min(b_lo - 1, f_hi)), (max(b_hi + 1, f_lo), f_hi)):  # above and below the band
        plain_rows(lo, hi, g, texels, b0, t0a, t0b, b1, t1a, t1b, n1 > 0, scratch, y0, step, n_l, acc,
                    work.rows, PERMUTE)
    if write_depth:  # the pixel centres inside the span: y0 <= i < y1
        d_a = max(int(math.ceil(y0)), i_lo)
        for i in range(np.uint64(d_a), np.uint64(max(min(int(math.ceil(y1)) - 1, i_hi) + 1, d_a))):
            depth[i] = z  # (unsigned: a vectorised fill)
