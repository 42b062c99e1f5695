"""The raycaster's decals: printed quads on faces, integrated exactly over each pixel.

A decal's texture is a summed-area table (:class:`~agvsim.sensors.render.ray_records.Textures`),
so the mean over any box of it is four reads (:func:`box_average`); a pixel's reflectance
on a face is the face's own where no decal is and each decal's printed mean over the part
of the pixel it covers (:func:`decal_cover`); the rows of a face span that decals reach and
that the span covers whole are done a decal at a time (:func:`decal_band`).
"""
from __future__ import annotations

import math

from agvsim.sensors.render._raycast_rows import irr_at, own_reflectance
from agvsim.sensors.render.kernel_jit import frame_kernel, span_helper

__all__ = ["box_average", "box_edges", "decal_band", "decal_cover", "sat_cell"]


@span_helper
def box_edges(lo, hi, n):
    """A box's edges ``lo <= hi`` (texels) on a table of ``n`` texels: clamped to ``0 .. n`` (at
    least 1e-6 inside), and widened to 1e-6 about their middle when thinner (a point sample)."""
    lo = min(max(lo, 0.0), n - 1e-6)
    hi = min(max(hi, 1e-6), float(n))
    if hi - lo < 1e-6:
        m = 0.5 * (lo + hi)
        lo, hi = m - 5e-7, m + 5e-7
    return lo, hi


@span_helper
def sat_cell(x, n):
    """Coordinate ``x`` (``0 .. n``) of a summed-area table of ``n`` texels as ``(j, frac)``,
    ``0 <= j < n``: the table's entry ``j`` and the weight of ``j + 1``."""
    j = min(max(int(math.floor(x)), 0), n - 1)
    return j, x - j


@span_helper
def _sat_at(sat, off, w, h, rows, cols):
    """Bilinear value of a summed-area table (exact integral of the texels) at fractional
    ``(rows, cols)`` inside ``0..h, 0..w``."""
    i, fi = sat_cell(rows, h)
    j, fj = sat_cell(cols, w)
    stride = w + 1
    base = off + i * stride + j
    s00 = sat[base]
    s01 = sat[base + 1]
    s10 = sat[base + stride]
    s11 = sat[base + stride + 1]
    return (s00 * (1.0 - fi) * (1.0 - fj) + s01 * (1.0 - fi) * fj + s10 * fi * (1.0 - fj) + s11 * fi * fj)


@frame_kernel
def box_average(tex, k, u0, u1, v0, v1):
    """Mean reflectance of texture ``k`` (a decal's: clamped at its edges) over the box
    ``u0..u1 x v0..v1`` (texture units, 1 = the whole texture; ``v`` up); the texels are
    constant squares, so this is exact. Boxes thinner than 1e-6 of a texel are widened to
    that (a point sample)."""
    w = tex.width[k]
    h = tex.height[k]
    off = tex.offset[k]
    a, b = (u0, u1) if u0 <= u1 else (u1, u0)
    c, d = (v0, v1) if v0 <= v1 else (v1, v0)
    a *= w
    b *= w
    c *= h
    d *= h
    a, b = box_edges(a, b, w)
    c, d = box_edges(c, d, h)
    sat = tex.sat
    total = (_sat_at(sat, off, w, h, d, b) - _sat_at(sat, off, w, h, d, a)
             - _sat_at(sat, off, w, h, c, b) + _sat_at(sat, off, w, h, c, a))
    return total / ((b - a) * (d - c))


@span_helper
def decal_cover(scene, f, s0, s1, z0, z1, base):
    """Mean reflectance over ``s0..s1 x z0..z1`` of face ``f`` whose own surface there has
    reflectance ``base``: each decal replaces it over its rectangle with its printed face,
    integrated exactly (summed-area table; ``scene``: :class:`~agvsim.sensors.render.ray_records.Scene`)."""
    faces = scene.faces
    decals = scene.decals
    if s1 < s0:
        s0, s1 = s1, s0
    if s1 - s0 < 1e-9:
        s1 = s0 + 1e-9
    if z1 < z0:
        z0, z1 = z1, z0
    if z1 - z0 < 1e-9:
        z1 = z0 + 1e-9
    area = (s1 - s0) * (z1 - z0)
    total = base * area
    for d in range(faces.decal_start[f], faces.decal_start[f + 1]):
        a = max(s0, decals.s0[d])
        b = min(s1, decals.s1[d])
        c = max(z0, decals.z0[d])
        e = min(z1, decals.z1[d])
        if b <= a or e <= c:
            continue
        dw = decals.s1[d] - decals.s0[d]
        dh = decals.z1[d] - decals.z0[d]
        printed = box_average(scene.tex, decals.texture[d], (a - decals.s0[d]) / dw, (b - decals.s0[d]) / dw,
                              (c - decals.z0[d]) / dh, (e - decals.z0[d]) / dh)
        total += (printed - base) * (b - a) * (e - c)
    return total / area



@span_helper
def _sat_row_span(sat, row, ja, fa, jb, fb):
    """Row ``row`` of a summed-area table (``sat[row:]``) at column ``jb + fb`` minus at ``ja + fa``."""
    return (sat[row + jb] + (sat[row + jb + 1] - sat[row + jb]) * fb
            - sat[row + ja] - (sat[row + ja + 1] - sat[row + ja]) * fa)


@span_helper
def _band_cover(scene, span, lo, hi, cover):
    """``cover[q]``, ``cover[n + q]`` (``n = hi + 1 - lo``): the sums over the decals of the face
    span ``span`` of (coverage x printed mean) and of coverage in row ``lo + q``, each decal's
    printed face integrated exactly over the part of the pixel it covers (as
    :func:`decal_cover`, whose result this gives to rounding).

    Decal by decal: its columns over the footprint ``s_a .. s_b`` (m along the face) are found
    once, then each row's integral is the difference of two rows of the summed-area table, each
    read at those two columns."""
    faces = scene.faces
    decals = scene.decals
    tex = scene.tex
    hc = span.hc
    cy = span.cy
    zpy = span.zpy
    n = hi + 1 - lo
    for q in range(2 * n):
        cover[q] = 0.0
    s_lo = min(span.s_a, span.s_b)
    s_hi = max(span.s_a, span.s_b)
    if s_hi - s_lo < 1e-9:
        s_hi = s_lo + 1e-9
    inv_sw = 1.0 / (s_hi - s_lo)
    f = span.face
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


@span_helper
def decal_band(scene, span, lo, hi, buf, cols, irr, lit, cover, acc):
    """Rows ``lo .. hi`` of the face span ``span`` (:class:`~agvsim.sensors.render.ray_records.FaceSpan`)
    that it covers whole and that decals reach: the face's own reflectance (``buf``, ``cols``:
    :class:`~agvsim.sensors.render.ray_records.TexelColumns`) where no decal is, the decals'
    printed faces (:func:`_band_cover`, into ``cover``: ``(>= 2 (hi + 1 - lo),)`` float64
    scratch) where they are, times the irradiance (``irr``, ``lit``:
    :class:`~agvsim.sensors.render.ray_records.SpanLight`), into ``acc``."""
    _band_cover(scene, span, lo, hi, cover)
    n = hi + 1 - lo
    for q in range(n):
        i = lo + q
        own = own_reflectance(buf, cols, float(i))
        acc[i] += span.gain * (own * (1.0 - cover[n + q]) + cover[q]) * irr_at(irr, lit, float(i))
