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

from agvsim.sensors.render._raycast_decals import decal_band, decal_cover
from agvsim.sensors.render._raycast_kernels import raster_lookup
from agvsim.sensors.render._raycast_rows import irr_at, own_reflectance, plain_rows
from agvsim.sensors.render.ray_records import FaceSpan, SpanLight, TexelColumns
from agvsim.sensors.render.kernel_jit import span_helper

__all__ = ["LIGHT_ROWS", "face_geometry", "shade_face"]


LIGHT_ROWS = 32.0  # px between the rows where a face's irradiance is evaluated (linear between)


@span_helper
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


@span_helper
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


@span_helper
def _texel_column(tex, k, lv, scale, span, buf, bo):
    """Level ``lv`` of texture ``k`` along the face span ``span``
    (:class:`~agvsim.sensors.render.ray_records.FaceSpan`): ``buf[bo + m]`` (float32) = ``scale`` x
    the mean of the bilinear samples at ``u_c - u_half`` and ``u_c + u_half`` in texel row
    ``k_lo + m`` (repeated if tiled, clamped if not), for the rows that image rows ``y0 - 1 ..
    y1 + 1`` reach (``buf.size // 2`` at most). Returns ``(n, a, b)``: the rows filled, and the
    coordinate ``a + b y`` (from ``bo``) of image row ``y``.

    The level is stored column by column (``tex.column_major[k]``), so this reads four
    contiguous runs of texels (the two texel columns either side of each sample)."""
    mw = tex.mip_width[k, lv]
    mh = tex.mip_height[k, lv]
    off = tex.mip_offset[k, lv]
    tiled = tex.tiled[k]
    cap = buf.size // 2
    # texel row coordinate (centre of row r at r) of image row y: v(y) * mh - 0.5
    b = span.vb * mh
    a = span.va * mh - 0.5
    ra = a + b * (min(span.y0, span.y1) - 1.0)
    rb = a + b * (max(span.y0, span.y1) + 1.0)
    k_lo = int(math.floor(min(ra, rb))) - 1
    n = min(int(math.floor(max(ra, rb))) + 2 - k_lo + 1, cap)
    # the two subsample columns: texel column coordinates and weights
    xa = (span.u_c - span.u_half) * mw - 0.5
    xb = (span.u_c + span.u_half) * mw - 0.5
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


@span_helper
def _edge_rows(scene, span, rows, buf, cols, irr, lit, acc):
    """The rows of the face span ``span`` that it covers in part (``rows``: ``(i_lo, n_top, bot,
    n_bot)``: ``n_top`` rows from ``i_lo``, ``n_bot`` from ``bot``), pixel by pixel: the part's
    own reflectance, decals integrated exactly
    (:func:`agvsim.sensors.render._raycast_kernels.decal_cover`), times the irradiance, into ``acc``."""
    i_lo, n_top, bot, n_bot = rows
    for q in range(n_top + n_bot):
        i = i_lo + q if q < n_top else bot + q - n_top
        ya = max(i - 0.5, span.y0)
        yb = min(i + 0.5, span.y1)
        cov = yb - ya
        if cov <= 0.0:
            continue
        ym = 0.5 * (ya + yb)
        alb = own_reflectance(buf, cols, ym)
        z_top = span.hc - (ya - span.cy) * span.zpy
        z_bot = span.hc - (yb - span.cy) * span.zpy
        if z_top > span.d_lo and z_bot < span.d_hi:
            alb = decal_cover(scene, span.face, span.s_a, span.s_b, z_bot, z_top, alb)
        acc[i] += span.gain * cov * alb * irr_at(irr, lit, ym)


@span_helper
def face_geometry(view, scene, sub, f, z, y0, y1):
    """The :class:`~agvsim.sensors.render.ray_records.FaceSpan` of face ``f`` at depth ``z`` (m)
    over rows ``y0 .. y1`` of the sub-column ``sub``: where its edge rays meet the face, the
    lighting level there, the texture's mapping and the decals' heights over the footprint."""
    faces = scene.faces
    decals = scene.decals
    s_a = _face_s(view, faces, f, sub.x0)
    s_b = _face_s(view, faces, f, sub.x1)
    s_c = 0.5 * (s_a + s_b)
    gain = sub.weight
    if view.level >= 0.0:
        gain *= view.level
    else:
        xn = (0.5 * (sub.x0 + sub.x1) - view.cx) / view.fx
        px = view.cam_x + z * (view.fwd_x + xn * view.right_x)
        py = view.cam_y + z * (view.fwd_y + xn * view.right_y)
        gain *= raster_lookup(scene.light, scene.light.zone, px, py)
    zpy = z / view.fy  # m of height per row
    du = (faces.u1[f] - faces.u0[f]) / faces.length[f]
    dvz = (faces.v1[f] - faces.v0[f]) / faces.height[f]
    # the rows of decals that this column's footprint on the face crosses
    d_lo = 1e300
    d_hi = -1e300
    s_lo = min(s_a, s_b)
    s_hi = max(s_a, s_b)
    for d in range(faces.decal_start[f], faces.decal_start[f + 1]):
        if decals.s0[d] < s_hi and decals.s1[d] > s_lo:
            d_lo = min(d_lo, decals.z0[d])
            d_hi = max(d_hi, decals.z1[d])
    hc = view.cam_z
    cy = view.cy
    return FaceSpan(f, z, y0, y1, s_a, s_b, hc, cy, zpy, gain, faces.u0[f] + du * s_c, 0.25 * du * (s_b - s_a),
                    faces.v0[f] + dvz * (hc + cy * zpy), -dvz * zpy, d_lo, d_hi)


@span_helper
def _face_texels(scene, span, buf):
    """The span's texture, filtered as the pyrender reference samples it (2 x 2 supersampling,
    each sample trilinear at the supersampled footprint): ``u`` is fixed across the span and ``v``
    linear in the row, so each mip level is a column of texels along the span, each weighted by
    its trilinear weight, into ``buf`` (``(2 (4 H + 8),)`` float32). Returns their
    :class:`~agvsim.sensors.render.ray_records.TexelColumns`."""
    tex = scene.tex
    f = span.face
    tk = scene.faces.texture[f]
    du = (scene.faces.u1[f] - scene.faces.u0[f]) / scene.faces.length[f]
    rho = 0.5 * max(abs(du * (span.s_b - span.s_a)) * tex.width[tk], abs(span.vb) * tex.height[tk])
    lam = math.log2(rho) if rho > 1.0 else 0.0
    n_lev = tex.mip_levels[tk]
    lv0 = min(int(lam), n_lev - 1)
    lv1 = min(lv0 + 1, n_lev - 1)
    w1 = (lam - int(lam)) if lv1 > lv0 else 0.0
    b0 = np.int64(0)  # (not a literal 0: one compiled specialization of the callees)
    b1 = buf.size // 2
    n0, t0a, t0b = _texel_column(tex, tk, lv0, 1.0 - w1, span, buf, b0)
    if w1 > 0.0:
        n1, t1a, t1b = _texel_column(tex, tk, lv1, w1, span, buf, b1)
    else:  # one level (magnified, or the last one): the other's samples would all be +0.0
        n1, t1a, t1b = np.int64(0), 0.0, 0.0
    return TexelColumns(b0, n0, t0a, t0b, b1, n1, t1a, t1b)


@span_helper
def shade_face(view, scene, sub, f, z, y0, y1, work, depth):
    """Add the radiance of face ``f`` (depth ``z`` m along the axis) over rows ``y0 .. y1`` of the
    sub-column ``sub`` (:class:`~agvsim.sensors.render.ray_records.SubColumn`: its weight) to
    ``work.acc`` ``(H,)``; ``depth`` ``(H,)`` gets ``z`` at the pixel centres it covers when
    ``sub.write_depth``. ``work``: the frame's
    :class:`~agvsim.sensors.render.ray_records.FrameScratch` (its ``irr``, ``cover``, ``texels``).

    Rows the span covers whole and no decal reaches go to :func:`plain_rows`, those decals
    reach to :func:`decal_band`, the (at most two) rows it covers in part pixel by pixel."""
    h_img = view.height
    acc = work.acc
    span = face_geometry(view, scene, sub, f, z, y0, y1)
    # irradiance at rows y0 + m * step, linear between
    n_l = int(math.ceil((y1 - y0) / LIGHT_ROWS)) + 1
    step = (y1 - y0) / (n_l - 1)
    lit = SpanLight(y0, step, 1.0 / step, n_l)
    irr = work.irr
    _face_irradiance(scene.light, f, 0.5 * (span.s_a + span.s_b), span.hc - (y0 - span.cy) * span.zpy,
                     step * span.zpy, n_l, irr)
    texels = work.texels
    cols = _face_texels(scene, span, texels)
    i_lo = max(int(math.floor(y0 + 0.5)), 0)
    i_hi = min(int(math.floor(y1 + 0.5)), h_img - 1)
    # rows the span covers whole and no decal reaches: the plain loop; the rest pixel by pixel
    f_lo = max(int(math.ceil(y0 + 0.5)), i_lo)
    f_hi = min(int(math.floor(y1 - 0.5)), i_hi)
    b_lo = f_hi + 1
    b_hi = f_hi
    zpy = span.zpy
    if span.d_hi > span.d_lo:  # decal rows: z_top > d_lo and z_bot < d_hi
        b_lo = max(int(math.floor((span.hc - span.d_hi) / zpy + span.cy - 0.5)), f_lo)
        b_hi = min(int(math.ceil((span.hc - span.d_lo) / zpy + span.cy + 0.5)), f_hi)
        if b_hi < b_lo:
            b_lo = f_hi + 1
            b_hi = f_hi
    # the rows above and below the whole ones (one at most each), then the decal band
    n_top = max(min(f_lo, i_hi + 1) - i_lo, 0)
    bot = max(f_hi + 1, f_lo, i_lo)
    _edge_rows(scene, span, (i_lo, n_top, bot, max(i_hi + 1 - bot, 0)), texels, cols, irr, lit, acc)
    if b_hi >= b_lo:
        decal_band(scene, span, b_lo, b_hi, texels, cols, irr, lit, work.cover, acc)
    g = 0.5 * span.gain  # the mean of the two subsample rows, and the gain
    plain_rows(f_lo, min(b_lo - 1, f_hi), g, texels, cols, irr, lit, acc)  # above the band
    plain_rows(max(b_hi + 1, f_lo), f_hi, g, texels, cols, irr, lit, acc)  # and below it
    if sub.write_depth:  # the pixel centres inside the span: y0 <= i < y1
        d_a = max(int(math.ceil(y0)), i_lo)
        for i in range(np.uint64(d_a), np.uint64(max(min(int(math.ceil(y1)) - 1, i_hi) + 1, d_a))):
            depth[i] = z  # (unsigned: a vectorised fill)
