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

import math

import numpy as np

from agvsim.sensors.render._raycast_kernels import FAR
from localizer._jit import fast_inline as inline
from localizer._jit import fast_jit as jit

__all__ = ["floor_level", "floor_rows"]


@inline
def floor_level(tex, fk, foot):
    """The mip level of the floor texture ``fk`` for a footprint of ``foot`` level-0 texels:
    the first whose texels the footprint covers fewer than two of (the last if none)."""
    lv = 0
    while foot >= 2.0 and lv < tex.mip_levels[fk] - 1:
        foot *= 0.5
        lv += 1
    return lv


@jit
def floor_rows(view, tex, light, floor, drawn_t, row_lo, row_hi, radiance, floor_depth):
    """Draw the floor into ``radiance_t`` where ``drawn_t`` says a column shows it.

    Args:
        view: the camera (:class:`~agvsim.sensors.render.ray_records.View`).
        tex, light, floor: the scene's :class:`Textures`, :class:`Light`, :class:`Floor`.
        drawn_t: ``(W, H)`` uint8: the pixels to draw (image transposed), 1 where some column
            shows the floor over a whole pixel.
        row_lo, row_hi: ``(H,)`` int64: the first and last column ``drawn_t`` marks in each row
            (none if ``row_hi < row_lo``).
        radiance: ``(H, W)`` float32, out: the floor's radiance (relative) at those pixels
            (others are left as they are).
        floor_depth: ``(H,)`` float32, out: the floor's depth at each row's pixel centres (m
            along the optical axis; 0 at and above the horizon).
    """
    h = view.height
    cy = view.cy
    k = view.fy * view.cam_z
    horizon = k / FAR
    for i in range(h):
        floor_depth[i] = k / (i - cy) if i - cy > horizon else 0.0
    fk = floor.texture
    tex_w = tex.width[fk]
    inv_tw = 1.0 / floor.tile_w
    inv_th = 1.0 / floor.tile_h
    zoned = view.level < 0.0
    irr_raster = light.floor_zone_irradiance if zoned else light.floor_irradiance
    gain = 1.0 if zoned else view.level
    rows_r, cols_r = irr_raster.shape
    irr_flat = irr_raster.ravel()
    ucols = np.uint64(cols_r)
    cmax = cols_r - 1.0  # the raster is at least 2 x 2 (RaycastBackend pads a thinner one)
    rmax = rows_r - 1.0
    one = np.uint64(1)
    zero = np.uint64(0)
    inv_res = 1.0 / light.raster_res
    mip = tex.mip
    x_step_x = view.right_x / view.fx  # floor point per column per metre of depth
    x_step_y = view.right_y / view.fx
    base_x = view.fwd_x - view.cx * x_step_x  # direction of column 0's ray
    base_y = view.fwd_y - view.cx * x_step_y
    for i in range(h):
        j_lo = row_lo[i]
        j_hi = row_hi[i]
        if j_hi < j_lo:
            continue
        zm = k / (i - cy) if i - cy > horizon else FAR
        za = k / (i + 0.5 - cy) if i + 0.5 - cy > horizon else FAR
        zb = k / (i - 0.5 - cy) if i - 0.5 - cy > horizon else FAR
        lv = floor_level(tex, fk, max(zb - za, zm / view.fx) * inv_tw * tex_w)
        mw = tex.mip_width[fk, lv]
        mh = tex.mip_height[fk, lv]
        moff = np.uint64(tex.mip_offset[fk, lv])
        umw = np.uint64(mw)
        fmw = float(mw)
        fmh = float(mh)
        # floor point of column j: (px0 + j dpx, py0 + j dpy); texel and raster coordinates linear in j
        px0 = view.cam_x + zm * base_x
        py0 = view.cam_y + zm * base_y
        dpx = zm * x_step_x
        dpy = zm * x_step_y
        su = inv_tw * mw
        sv = inv_th * mh
        inv_mw = 1.0 / mw
        inv_mh = 1.0 / mh
        for j in range(j_lo, j_hi + 1):
            if not drawn_t[j, i]:
                continue
            px = px0 + j * dpx
            py = py0 + j * dpy
            # texel coordinates folded into the tile (0 <= x < mw), unsigned indices from there
            xt = px * su - 0.5
            yt = py * sv - 0.5
            xt = xt - fmw * math.floor(xt * inv_mw)
            yt = yt - fmh * math.floor(yt * inv_mh)
            xf = min(math.floor(xt), fmw - 1.0)
            yf = min(math.floor(yt), fmh - 1.0)
            fj = xt - xf
            fi = yt - yf
            j0 = np.uint64(xf)
            i0 = np.uint64(yf)
            j1 = j0 + one if xf + 1.0 < fmw else zero
            i1 = i0 + one if yf + 1.0 < fmh else zero
            r0 = moff + i0 * umw
            r1 = moff + i1 * umw
            alb = ((mip[r0 + j0] * (1.0 - fj) + mip[r0 + j1] * fj) * (1.0 - fi)
                   + (mip[r1 + j0] * (1.0 - fj) + mip[r1 + j1] * fj) * fi)
            # the lighting raster, bilinear, edge cells repeated
            mx = min(max((px - light.raster_x0) * inv_res, 0.0), cmax)
            my = min(max((py - light.raster_y0) * inv_res, 0.0), rmax)
            gx = min(math.floor(mx), cmax - 1.0)
            gy = min(math.floor(my), rmax - 1.0)
            gj = mx - gx
            gi = my - gy
            c0 = np.uint64(gx)
            q0 = np.uint64(gy) * ucols
            q1 = q0 + ucols
            irr = ((irr_flat[q0 + c0] * (1.0 - gj) + irr_flat[q0 + c0 + one] * gj) * (1.0 - gi)
                   + (irr_flat[q1 + c0] * (1.0 - gj) + irr_flat[q1 + c0 + one] * gj) * gi)
            radiance[i, j] = gain * alb * irr
