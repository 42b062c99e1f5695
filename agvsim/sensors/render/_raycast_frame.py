"""The raycaster's frame kernel: a whole level frame, column-major (:func:`render_view`).

See :mod:`agvsim.sensors.render._raycast_kernels` for the geometry. A frame is drawn in
three passes: the spans of every column edge ray (:func:`_edge_spans`); the floor, row by
row, over the columns between the first and last that show it over a whole pixel in that
row (:func:`_floor_extent`, then :mod:`agvsim.sensors.render._raycast_floor`); then each
column, its spans shaded into one column of the image
(:func:`agvsim.sensors.render._raycast_column.shade_column`).
"""
from __future__ import annotations

import math

import numpy as np

from agvsim.sensors.render._raycast_column import shade_column
from agvsim.sensors.render._raycast_floor import floor_rows
from agvsim.sensors.render._raycast_kernels import MAX_SPANS, cast_ray, same_spans
from agvsim.sensors.render._sensor_kernels import column_counter, expose_flat, store_columns
from agvsim.sensors.render.ray_records import EXPOSE_BLOCK, SubColumn
from agvsim.sensors.render.kernel_jit import frame_kernel, helper, span_helper

__all__ = ["render_view"]

_FACE, _FLAT, _BACKGROUND = 0, 1, 2  # agvsim.sensors.render.ray_records.SpanKind


@span_helper
def _whole_rows(y0, y1, h):
    """``(lo, hi)``: the rows ``0 <= i < h`` the span ``y0 .. y1`` covers whole (none if ``hi < lo``)."""
    return max(int(math.ceil(y0 + 0.5)), 0), min(int(math.floor(y1 - 0.5)), h - 1)


@span_helper
def _zero_outside(acc, lo, hi):
    """``acc`` set to 0 but at ``lo .. hi`` (everywhere if ``hi < lo``; ``lo <= acc.size``)."""
    for i in range(np.uint64(lo)):  # (unsigned: vectorised fills)
        acc[i] = 0.0
    for i in range(np.uint64(max(hi + 1, lo)), np.uint64(acc.size)):
        acc[i] = 0.0


@helper
def _edge_spans(view, scene, cands, work):
    """The spans of every column edge ray (edge ``r`` at ``x = r - 0.5``) into ``work.edges`` (ray
    ``r``'s at offset ``r * MAX_SPANS``) and their numbers into ``work.e_n``; ``cands``: the CSR
    lists of :func:`~agvsim.sensors.render._raycast_kernels.bin_solids`."""
    start, items = cands
    for r in range(view.width + 1):
        c = max(r - 1, 0)  # the column left of the ray (its solids' list reaches 0.51 px beyond it)
        work.e_n[r] = cast_ray(view, scene, r - 0.5, items, start[c], start[c + 1] - start[c], work.hits, work.edges,
                               r * MAX_SPANS)


@helper
def _floor_extent(view, work):
    """The rows of each column where some edge ray sees the floor whole (``work.drawn``), and each
    row's first and last such column (``work.row_lo``, ``work.row_hi``): the floor pass draws them."""
    w = view.width
    h = view.height
    e = work.edges
    drawn_t = work.drawn
    for j in range(w):
        for i in range(h):
            drawn_t[j, i] = 0
    row_lo = work.row_lo
    row_hi = work.row_hi
    for i in range(h):
        row_lo[i] = w
        row_hi[i] = -1
    for r in range(w + 1):  # edge ray r bounds columns r - 1 and r (one of them at the image's sides)
        ja = max(r - 1, 0)
        jb = min(r, w - 1)
        o = r * MAX_SPANS
        for k in range(work.e_n[r]):
            if e.kind[o + k] == _FLAT and e.id[o + k] < 0 and e.y1[o + k] > e.y0[o + k]:
                lo = max(int(math.ceil(e.y0[o + k] + 0.5)), 0)
                hi = min(int(math.floor(e.y1[o + k] - 0.5)), h - 1)
                if hi < lo:
                    continue
                for i in range(np.uint64(lo), np.uint64(hi + 1)):  # unsigned: the loop is vectorised
                    drawn_t[ja, i] = 1
                    drawn_t[jb, i] = 1
                    row_lo[i] = min(row_lo[i], ja)
                    row_hi[i] = jb  # the rays come in column order


@span_helper
def _mean_spans(work, j, h):
    """Column ``j``, whose two edge rays see the same spans: their mean into ``work.spans`` (the
    span edges are straight across the column; 1/Z is affine across a face). Returns ``(s_lo,
    s_hi)``: the rows of its largest floor span that it covers whole and the floor pass drew
    (the edge rays' same span's whole rows, when they meet; none if ``s_hi < s_lo``)."""
    e = work.edges
    m = work.spans
    oa = j * MAX_SPANS
    ob = oa + MAX_SPANS
    s_lo = h
    s_hi = -1
    for k in range(work.e_n[j + 1]):
        m.y0[k] = 0.5 * (e.y0[oa + k] + e.y0[ob + k])
        m.y1[k] = 0.5 * (e.y1[oa + k] + e.y1[ob + k])
        m.kind[k] = e.kind[ob + k]
        m.id[k] = e.id[ob + k]
        if e.kind[ob + k] == _FACE:  # 1/Z is affine across a plane
            m.val[k] = 2.0 / (1.0 / e.val[oa + k] + 1.0 / e.val[ob + k])
        else:
            m.val[k] = e.val[ob + k]
        if e.kind[ob + k] == _FLAT and e.id[ob + k] < 0:
            lo, hi = _whole_rows(m.y0[k], m.y1[k], h)
            if hi - lo > s_hi - s_lo:
                la, ha = _whole_rows(e.y0[oa + k], e.y1[oa + k], h)
                lb, hb = _whole_rows(e.y0[ob + k], e.y1[ob + k], h)
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
    return s_lo, s_hi


@span_helper
def _split_column(view, scene, cands, j, work, dcol):
    """Column ``j``, which a silhouette crosses: ``view.subcolumns`` sub-columns, each cast from its
    centre ray and shaded over its own footprint into ``work.acc`` (zeroed first); the one holding
    the column's centre writes the depth ``dcol``."""
    start, items = cands
    acc = work.acc
    for i in range(view.height):
        acc[i] = 0.0
    sub = max(view.subcolumns, 1)
    none_lo = np.int64(view.height)
    none_hi = np.int64(-1)
    for qs in range(sub):
        x0 = j - 0.5 + qs / sub
        x1 = j - 0.5 + (qs + 1) / sub
        n_c = cast_ray(view, scene, 0.5 * (x0 + x1), items, start[j], start[j + 1] - start[j], work.hits, work.spans,
                       np.int64(0))
        shade_column(view, scene, SubColumn(j, x0, x1, 1.0 / sub, x0 <= j < x1, none_lo, none_hi), n_c, work, dcol)


@span_helper
def _store_column(work, j, s_lo, s_hi, radiance_t, params, image):
    """Column ``j``'s radiance, contiguous in the frame (``radiance_t[j]``), or exposed into a
    block of columns stored in the 8-bit ``image`` a block at a time (``image`` not ``(0, 0)``):
    the shaded rows (``work.acc``) and the rows ``s_lo .. s_hi`` kept from the floor pass (its
    radiance as it is)."""
    exposed = image.shape[0] > 0
    h = work.acc.size
    acc = work.acc
    uj = np.uint64(j)
    out = work.column if exposed else radiance_t[uj]
    for i in range(np.uint64(s_lo)):
        out[i] = acc[i]
    for i in range(np.uint64(s_lo), np.uint64(max(s_hi + 1, s_lo))):
        out[i] = work.floor_img[i, uj]
    for i in range(np.uint64(max(s_hi + 1, s_lo)), np.uint64(h)):
        out[i] = acc[i]
    if exposed:
        cols = work.exposed
        q = j % EXPOSE_BLOCK
        expose_flat(work.column, cols[q, :h], params, column_counter(params, h, j))
        if q == EXPOSE_BLOCK - 1 or j == image.shape[1] - 1:
            store_columns(cols, j - q, q + 1, image)


@helper
def _column_pass(view, scene, cands, radiance_t, depth_t, work, params, image):
    """:func:`render_view`'s third pass (arguments as its): each column's spans shaded into
    ``work.acc`` and stored (the per-column and per-span functions it calls are inlined into it:
    :data:`~agvsim.sensors.render.kernel_jit.span_helper`)."""
    w = view.width
    h = view.height
    floor_depth = work.floor_depth
    e = work.edges
    every = np.bool_(True)
    for j in range(w):
        dcol = depth_t[np.uint64(j)]
        oa = j * MAX_SPANS
        if same_spans(e.kind, e.id, work.e_n[j], oa, work.e_n[j + 1], oa + MAX_SPANS):
            s_lo, s_hi = _mean_spans(work, j, h)
            _zero_outside(work.acc, s_lo, s_hi)
            for i in range(np.uint64(s_lo), np.uint64(max(s_hi + 1, s_lo))):  # the rows kept from the floor pass
                dcol[i] = floor_depth[i]
            shade_column(view, scene, SubColumn(j, j - 0.5, j + 0.5, 1.0, every, s_lo, s_hi), work.e_n[j + 1], work,
                         dcol)
        else:
            s_lo, s_hi = h, -1
            _split_column(view, scene, cands, j, work, dcol)
        _store_column(work, j, s_lo, s_hi, radiance_t, params, image)


@frame_kernel
def render_view(view, scene, cands, radiance_t, depth_t, work, params, image):
    """Draw one level frame, column-major.

    Args:
        view: the camera (:class:`~agvsim.sensors.render.ray_records.View`).
        scene: the map's :class:`~agvsim.sensors.render.ray_records.Scene`.
        cands: ``(start, items)``, the solids that may cross each column
            (:func:`~agvsim.sensors.render._raycast_kernels.bin_solids` of the view).
        radiance_t: out ``(W, H)`` float32, C-contiguous: radiance (relative), column ``j`` of
            the image at ``radiance_t[j]`` (the transpose of the ``(H, W)`` frame).
        depth_t: out ``(W, H)`` float32, C-contiguous: depth (m along the optical axis, 0 =
            nothing), likewise.
        work: the :class:`~agvsim.sensors.render.ray_records.FrameScratch` for ``W`` x ``H``
            (:data:`~agvsim.sensors.render._raycast_kernels.MAX_SPANS`, ``MAX_HITS``).
        params, image: ``image`` of shape ``(0, 0)``: the radiance is stored in ``radiance_t``.
            Else ``image`` ``(H, W)`` uint8, C-contiguous, out: the frame exposed by the sensor
            (:class:`~agvsim.sensors.render.ray_records.SensorParams` ``params``) column by column
            as it is drawn, exactly as
            :func:`~agvsim.sensors.render._sensor_kernels.expose_columns` exposes the stored
            radiance (bit for bit: each column in float32, its own noise counter), and
            ``radiance_t`` is not written: the radiance never leaves the first levels of the
            cache (a 1 MB store and load the less).

    The column pass shades each column into contiguous scratch (``work.acc``) and stores it
    whole where the frame holds it contiguously (a row-major frame would take each column a
    pixel per row, one cache line each: a fifth of the frame's time). The floor pass draws
    into ``work.floor_img`` (rows padded past a power-of-two stride: the columns read it down
    a column, and rows 2 kB apart would share a few sets of the cache); where a column's
    largest floor span covers the rows whole and the pass drew them, the column takes its
    values from there as they are (the sum it would take, 0 + 1 x the pass's value, is that
    value) and the floor's depth.
    """
    _edge_spans(view, scene, cands, work)
    _floor_extent(view, work)
    floor_rows(view, scene, work)
    _column_pass(view, scene, cands, radiance_t, depth_t, work, params, image)
