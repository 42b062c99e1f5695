"""The raycaster's floor pass: the lit floor of a level frame, drawn row by row.

With a level camera every pixel row below the horizon sees the floor at one depth
``Z = fy (cam_z) / (y - cy)`` (thesis §3.5: rows are level), along a line parallel to the
image plane: across the row, the floor point, its texture coordinate and its place in the
lighting raster all move linearly with the column, and the mip level (the footprint's
size, ``max(dZ, Z / fx)`` per pixel) is the same for the whole row. So the floor is drawn
here in row order before the columns are shaded (:func:`floor_rows`), and the column pass
(:func:`agvsim.sensors.render._raycast_frame.render_view`) takes each floor pixel from it,
weighted by the share of the pixel the floor covers in that column.

The filter is the one the per-pixel path used (a bilinear sample of the nearest mip level
at the footprint's scale, the texture repeating every tile), at the pixel's centre.
"""
from __future__ import annotations

import numpy as np

from agvsim.sensors.render._raycast_kernels import FAR
from agvsim.sensors.render.kernel_jit import helper

__all__ = ["floor_level", "floor_rows"]

_ONE = np.float32(1.0)


@helper
def floor_level(tex, fk, foot):
    """The mip level of the floor texture ``fk`` for a footprint of ``foot`` level-0 texels:
    the first whose texels the footprint covers fewer than two of (the last if none)."""
    lv = 0
    while foot >= 2.0 and lv < tex.mip_levels[fk] - 1:
        foot *= 0.5
        lv += 1
    return lv


@helper
def floor_rows(view, scene, work):
    """Draw the floor into ``work.floor_img`` over each row's range of columns.

    Args:
        view: the camera (:class:`~agvsim.sensors.render.ray_records.View`).
        scene: the :class:`~agvsim.sensors.render.ray_records.Scene` (its textures, light, floor).
        work: the frame's :class:`~agvsim.sensors.render.ray_records.FrameScratch`. Read:
            ``row_lo``, ``row_hi`` ``(H,)`` int64, the first and last column of each row where
            some column shows the floor over a whole pixel (none if ``row_hi < row_lo``). Every
            pixel between them is drawn, including those a column does not show the floor at:
            the column pass reads the floor only where it does, and writes every pixel of the
            frame. Written: ``floor_img`` ``(H, >= W)`` float32, the floor's radiance (relative)
            at those pixels (others are left as they are); ``floor_depth`` ``(H,)`` float32, the
            floor's depth at each row's pixel centres (m along the optical axis; 0 at and above
            the horizon); ``floor_idx``, ``floor_wts`` (``(4 W,)`` uint64 and float32) scratch.

    A row is drawn in two loops (:func:`_row_samples`, :func:`_gather_row`): the first,
    vectorised, takes each pixel's texel and raster coordinates (linear in the column, thesis
    §3.5) to the flat indices and bilinear weights of its 2 x 2 texels and 2 x 2 lighting
    cells; the second gathers them (scalar loads) and multiplies, in float32 (the texels, the
    raster and the frame are float32: no conversions). The numbers are the per-pixel sample's
    up to float32 rounding (the coordinates in float64; the floor point is stepped from the
    row's first column, not from column 0).
    """
    h = view.height
    cy = view.cy
    k = view.fy * view.cam_z
    horizon = k / FAR
    floor_depth = work.floor_depth
    for i in range(h):
        floor_depth[i] = k / (i - cy) if i - cy > horizon else 0.0
    zoned = view.level < 0.0
    light = scene.light
    irr_raster = light.floor_zone_irradiance if zoned else light.floor_irradiance
    gain32 = np.float32(1.0 if zoned else view.level)
    irr = irr_raster.reshape(irr_raster.size)
    ucols = np.uint64(irr_raster.shape[1])
    for i in range(h):
        j_lo = work.row_lo[i]
        j_hi = work.row_hi[i]
        if j_hi < j_lo:
            continue
        _row_samples(view, scene, irr_raster, i, j_lo, j_hi + 1 - j_lo, work.floor_idx, work.floor_wts)
        _gather_row(scene.tex.mip, irr, ucols, gain32, work.floor_idx, work.floor_wts, work.floor_img[i, j_lo:j_hi + 1])


@helper
def _row_samples(view, scene, irr_raster, i, j_lo, n, idx, wts):
    """:func:`floor_rows`' first loop for row ``i``, columns ``j_lo .. j_lo + n - 1``: per pixel,
    4 apart in ``idx`` and ``wts`` (one pointer each in the gather loop), the first texel's flat
    index, the steps to the next texel along u and up v (the tile wraps: uint64 arithmetic
    modulo 2^64), the first lighting cell's flat index in ``irr_raster``; the weights along u, v,
    x, y."""
    tex = scene.tex
    light = scene.light
    floor = scene.floor
    cy = view.cy
    k = view.fy * view.cam_z
    horizon = k / FAR
    fk = floor.texture
    tex_w = tex.width[fk]
    inv_tw = 1.0 / floor.tile_w
    inv_th = 1.0 / floor.tile_h
    rows_r, cols_r = irr_raster.shape
    cmax = cols_r - 1.0  # the raster is at least 2 x 2 (RaycastBackend pads a thinner one)
    rmax = rows_r - 1.0
    inv_res = 1.0 / light.raster_res
    x_step_x = view.right_x / view.fx  # floor point per column per metre of depth
    x_step_y = view.right_y / view.fx
    base_x = view.fwd_x - view.cx * x_step_x  # direction of column 0's ray
    base_y = view.fwd_y - view.cx * x_step_y
    zm = k / (i - cy) if i - cy > horizon else FAR
    za = k / (i + 0.5 - cy) if i + 0.5 - cy > horizon else FAR
    zb = k / (i - 0.5 - cy) if i - 0.5 - cy > horizon else FAR
    lv = floor_level(tex, fk, max(zb - za, zm / view.fx) * inv_tw * tex_w)
    mw = tex.mip_width[fk, lv]
    mh = tex.mip_height[fk, lv]
    moff = tex.mip_offset[fk, lv]
    fmw = float(mw)
    fmh = float(mh)
    inv_mw = 1.0 / fmw
    inv_mh = 1.0 / fmh
    # the floor point of column j_lo + q: (px + q dpx, py + q dpy)
    dpx = zm * x_step_x
    dpy = zm * x_step_y
    px = view.cam_x + zm * base_x + j_lo * dpx
    py = view.cam_y + zm * base_y + j_lo * dpy
    su = inv_tw * mw  # texels per metre
    sv = inv_th * mh
    u0 = px * su - 0.5
    v0 = py * sv - 0.5
    du = dpx * su
    dv = dpy * sv
    mx0 = (px - light.raster_x0) * inv_res
    my0 = (py - light.raster_y0) * inv_res
    dmx = dpx * inv_res
    dmy = dpy * inv_res
    for q in range(n):
        fq = float(q)
        # texel coordinates folded into the tile (0 <= u < mw up to rounding)
        u = u0 + fq * du
        v = v0 + fq * dv
        u = u - fmw * np.floor(u * inv_mw)
        v = v - fmh * np.floor(v * inv_mh)
        j0 = min(int(u), mw - 1)
        i0 = min(int(v), mh - 1)
        idx[4 * q] = moff + i0 * mw + j0
        idx[4 * q + 1] = 1 if j0 + 1 < mw else 1 - mw
        idx[4 * q + 2] = mw if i0 + 1 < mh else (1 - mh) * mw
        wts[4 * q] = u - j0
        wts[4 * q + 1] = v - i0
        # the lighting raster, edge cells repeated
        mx = min(max(mx0 + fq * dmx, 0.0), cmax)
        my = min(max(my0 + fq * dmy, 0.0), rmax)
        gx = min(int(mx), cols_r - 2)
        gy = min(int(my), rows_r - 2)
        idx[4 * q + 3] = gy * cols_r + gx
        wts[4 * q + 2] = mx - gx
        wts[4 * q + 3] = my - gy


@helper
def _gather_row(mip, irr, ucols, gain32, idx, wts, out):
    """:func:`floor_rows`' second loop: ``out[q]`` (float32) = ``gain32`` x the bilinear texel of
    ``mip`` x the bilinear lighting cell of ``irr`` (the raster flattened, ``ucols`` wide) of
    pixel ``q`` (:func:`_row_samples`' ``idx``, ``wts``), in float32."""
    one = np.uint64(1)
    for q in range(out.size):
        a = idx[4 * q]
        b = a + idx[4 * q + 1]
        c = a + idx[4 * q + 2]
        d = c + idx[4 * q + 1]
        fj = wts[4 * q]
        fi = wts[4 * q + 1]
        alb = ((mip[a] * (_ONE - fj) + mip[b] * fj) * (_ONE - fi)
               + (mip[c] * (_ONE - fj) + mip[d] * fj) * fi)
        g0 = idx[4 * q + 3]
        g1 = g0 + ucols
        gj = wts[4 * q + 2]
        gi = wts[4 * q + 3]
        irr_q = ((irr[g0] * (_ONE - gj) + irr[g0 + one] * gj) * (_ONE - gi)
                 + (irr[g1] * (_ONE - gj) + irr[g1 + one] * gj) * gi)
        out[q] = gain32 * alb * irr_q
