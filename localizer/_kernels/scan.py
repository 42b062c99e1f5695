"""Kernels of :mod:`localizer.search.scan`: line thresholding, run-length coding and the triple
search (thesis §4.4-4.5.1) on a batch of scan lines, a ``(k, W)`` uint8 array.

Loops here work on slices passed to small kernels (:func:`~localizer._kernels.arrays.copy`,
:func:`~localizer._kernels.arrays.fill`,
:func:`max_min_into`, :func:`threshold_line`): loops with computed indices do not
vectorise.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import inline, jit
from localizer._kernels.arrays import copy, fill


@jit
def line_extrema(lines, window):
    """:func:`localizer.search.scan.line_extrema`, compiled: the edge-padded lines laid end to end in one buffer,
    then the max / min over 2, 4, ... ``2^L <= window`` pixels by doubling (each pass two
    vectorised element-wise loops over the whole buffer, :func:`max_min_into`; values
    that straddle two lines are never read back), and two overlapping ``2^L``-pixel
    windows cover ``window``.

    (Hand-written rather than OpenCV: on the 48 short lines of a coarse scan this takes
    ~11 µs against ~25 µs for the two OpenCV calls, which also rise to 70-100 µs after
    another detector has run and their code has left the caches. Loops here work on
    slices passed to small kernels: loops with computed indices do not vectorise.)
    """
    k_n, w = lines.shape
    a = window // 2
    n = w + window - 1  # padded line
    size = k_n * n
    x0 = np.empty(size, np.uint8)
    x1 = np.empty(size, np.uint8)
    n0 = np.empty(size, np.uint8)
    n1 = np.empty(size, np.uint8)
    for r in range(k_n):  # the line, its end pixels repeated `a` (left) and `window - 1 - a` times
        base = r * n
        row = lines[r]
        fill(x0[base:base + a], row[0])
        copy(row, x0[base + a:base + a + w])
        fill(x0[base + a + w:base + n], row[w - 1])
    copy(x0, n0)
    k = 1
    while 2 * k <= window:  # x0[i] = max(padded[i : i + 2k])
        m = size - k
        max_min_into(x0[:m], x0[k:], n0[:m], n0[k:], x1[:m], n1[:m])
        x0, x1 = x1, x0
        n0, n1 = n1, n0
        k *= 2
    o = window - k  # [c, c + window) = [c, c + k) and [c + o, c + o + k)
    m = size - o
    max_min_into(x0[:m], x0[o:], n0[:m], n0[o:], x1[:m], n1[:m])
    hi = np.empty((k_n, w), np.uint8)
    lo = np.empty((k_n, w), np.uint8)
    for r in range(k_n):
        copy(x1[r * n:r * n + w], hi[r])
        copy(n1[r * n:r * n + w], lo[r])
    return hi, lo


@jit
def max_min_into(a, b, c, d, mx, mn):
    """``mx = max(a, b)``, ``mn = min(c, d)`` element-wise over ``mx.size`` / ``mn.size``
    elements (separate arrays, so that the loops vectorise)."""
    for i in range(mx.size):
        x = a[i]
        y = b[i]
        mx[i] = x if x > y else y
    for i in range(mn.size):
        x = c[i]
        y = d[i]
        mn[i] = x if x < y else y


@jit
def threshold(lines, hi, lo, contrast_window, local_contrast, global_level):
    """Per-pixel threshold of :func:`localizer.search.scan.threshold_lines` given the running max ``hi`` and min
    ``lo`` (k, W) of the lines.

    Per line (the thesis's rule): if the largest contrast over any ``contrast_window``-pixel
    stretch reaches ``local_contrast``, the line's threshold is midway between its
    brightest and darkest pixel, else ``global_level``. Per pixel: where ``hi - lo`` reaches
    ``local_contrast`` the pixel is white when ``>= hi - (hi - lo) // 2`` (midway, rounded
    up), elsewhere when ``>=`` the line's threshold.
    """
    k_n, w = lines.shape
    out = np.empty((k_n, w), np.bool_)
    k = contrast_window - 1
    for r in range(k_n):
        row = lines[r]
        ahead = lines[r, k:]
        behind = lines[r, :w - k]
        dmax = np.int16(0)
        dmin = np.int16(0)
        for c in range(w - k):  # (as two slices and int16, so that it vectorises)
            d = np.int16(ahead[c]) - np.int16(behind[c])
            dmax = max(dmax, d)
            dmin = min(dmin, d)
        cmax = max(np.int32(dmax), -np.int32(dmin))
        vmax = np.int32(0)
        vmin = np.int32(255)
        for c in range(w):
            vmax = max(vmax, np.int32(row[c]))
            vmin = min(vmin, np.int32(row[c]))
        line_thr = (vmax + vmin + 1) // 2 if cmax >= local_contrast else global_level
        threshold_line(row, hi[r], lo[r], np.int16(math.ceil(local_contrast)), np.int16(line_thr), out[r])
    return out


@jit
def threshold_line(row, hi, lo, local_contrast, line_thr, out):
    """One line of :func:`threshold`: ``out[c]`` = ``row[c] >= hi[c] - (hi[c] - lo[c]) // 2``
    where ``hi[c] - lo[c] >= local_contrast``, else ``row[c] >= line_thr`` (branch-free int16
    on separate arrays, so that it vectorises)."""
    for c in range(out.size):
        h = np.int16(hi[c])
        con = h - np.int16(lo[c])
        t = h - (con >> 1) if con >= local_contrast else line_thr
        out[c] = np.int16(row[c]) >= t


@jit
def rle(binary):
    """Run-length code of a ``(k, W)`` boolean batch, line by line: ``(g, l, line, x)``
    ``(R,)`` arrays (shade, length, line index, first column) in line then x order.

    Per line the changes ``b[c] != b[c - 1]`` are marked in one vectorised pass, then
    read eight at a time (a 64-bit word) so that stretches without a change cost one test.
    """
    k, w = binary.shape
    b8 = binary.view(np.uint8)
    nw = (w + 7) // 8
    change = np.zeros(8 * nw, np.uint8)  # change[c]: pixel c starts a new run (c >= 1)
    words = change.view(np.uint64)
    cap = 64 * k
    g = np.empty(cap, np.bool_)
    ln = np.empty(cap, np.int64)
    line = np.empty(cap, np.int64)
    x = np.empty(cap, np.int64)
    j = 0
    for r in range(k):
        row = b8[r]
        cur = row[1:]
        prev = row[:w - 1]
        dst = change[1:w]
        for c in range(w - 1):
            dst[c] = cur[c] ^ prev[c]
        if j + w > cap:  # room for a line of one-pixel runs
            cap = max(2 * cap, j + w)
            g, ln, line, x = grown(g, j, cap), grown(ln, j, cap), grown(line, j, cap), grown(x, j, cap)
        start = 0
        for q in range(nw):
            if words[q] == 0:
                continue
            for c in range(8 * q, 8 * q + 8):
                if change[c]:
                    g[j] = row[start] != 0
                    ln[j] = c - start
                    line[j] = r
                    x[j] = start
                    j += 1
                    start = c
        g[j] = row[start] != 0
        ln[j] = w - start
        line[j] = r
        x[j] = start
        j += 1
    return g[:j], ln[:j], line[:j], x[:j]


@jit
def grown(a, n, cap):
    """A ``(cap,)`` array of ``a``'s dtype holding ``a[:n]``."""
    out = np.empty(cap, a.dtype)
    copy(a, out[:n])
    return out


@inline
def near_equal(l0, l1, l2, width_tolerance, width_slack, max_edge_shift):
    """The §4.5.1 run test (:func:`localizer.search.scan.near_equal`) for one triple of run lengths
    ``l0, l1, l2`` (px)."""
    c = min(max((l1 - 0.5 * (l0 + l2)) * 0.25, -max_edge_shift), max_edge_shift)
    a0 = l0 + 2.0 * c
    a1 = l1 - 2.0 * c
    a2 = l2 + 2.0 * c
    lmax = max(a0, a1, a2)
    return lmax - min(a0, a1, a2) <= width_tolerance * lmax + width_slack


@jit
def triples(l, x, line, width, runs):
    """The loop of :func:`localizer.search.scan.find_triples` over the run-length code ``l``
    (lengths, px), ``x`` (first columns), ``line`` (line indices), all (R,), of lines
    ``width`` px long, with the run test ``runs`` (:class:`~localizer._kernels.records.RunTest`).

    Returns ``(i (T,), x (T, 4), regions (T, 7, 2))``: the index of each triple's first
    bar, its run boundaries (columns) and sampled regions (see :class:`localizer.search.scan.Triples`).
    """
    min_bar_px, width_tolerance, width_slack = runs.min_bar_px, runs.width_tolerance, runs.width_slack
    max_edge_shift, min_margin_ratio = runs.max_edge_shift, runs.min_margin_ratio
    reject_periodic, periodic_tolerance = runs.reject_periodic, runs.periodic_tolerance
    n = l.size
    idx = np.empty(max(n - 4, 0), np.int64)
    t = 0
    for i in range(1, n - 3):
        if line[i - 1] != line[i + 3] or l[i] < min_bar_px or l[i + 1] < min_bar_px or l[i + 2] < min_bar_px:
            continue
        l0, l1, l2 = l[i], l[i + 1], l[i + 2]
        if not near_equal(float(l0), float(l1), float(l2), width_tolerance, width_slack, max_edge_shift):
            continue
        if 3 * min(l[i - 1], l[i + 3]) < min_margin_ratio * (l0 + l1 + l2):
            continue
        idx[t] = i
        t += 1
    idx = idx[:t]
    xs = np.empty((t, 4), np.int64)
    reg = np.zeros((t, 7, 2), np.int64)
    for k in range(t):
        i = idx[k]
        x0, x1, x2 = x[i], x[i + 1], x[i + 2]
        m0, m1, m2 = float(l[i]), float(l[i + 1]), float(l[i + 2])
        x3 = x2 + l[i + 2]
        xs[k, 0] = x0
        xs[k, 1] = x1
        xs[k, 2] = x2
        xs[k, 3] = x3
        # sampled regions (start, end): left margin, bar, gap, bar, right margin
        b = (x3 - x0) / 3.0
        mw = max(1, int(b * 0.25))
        e0 = min(2, (x1 - x0 - 1) // 2)
        e1 = min(2, (x2 - x1 - 1) // 2)
        e2 = min(2, (x3 - x2 - 1) // 2)
        reg[k, 0, 0] = max(x0 - mw, 0)
        reg[k, 0, 1] = x0
        reg[k, 1, 0] = x0 + e0
        reg[k, 1, 1] = x1 - e0
        reg[k, 2, 0] = x1 + e1
        reg[k, 2, 1] = x2 - e1
        reg[k, 3, 0] = x2 + e2
        reg[k, 3, 1] = x3 - e2
        reg[k, 4, 0] = x3
        reg[k, 4, 1] = min(x3 + mw, width)
        if reject_periodic:
            # five or more equal runs in a row (a grating, a chessboard, a row of equal bars:
            # a target's margin is half a bar, so a margin as wide as a bar with a bar's
            # width of the bars' shade beyond it is a third bar at the pitch): flag the run
            # beyond each margin; its grey level decides (a bar's shade = periodic, see
            # find_stacks). The common dark-side edge shift that the run test undoes
            # (near_equal: runs of the bars' shade grow by 2c, of the gap's shade shrink by
            # 2c) may be undone here too: a row of 5 px bars at a 15 px pitch is 7, 8, 7, ...
            # px. The runs are equal if they are so either as measured or with the shift undone.
            sh = min(max((m1 - 0.5 * (m0 + m2)) * 0.25, -max_edge_shift), max_edge_shift)
            bc = b + 2.0 * sh / 3.0
            tol = periodic_tolerance * b + 1.0
            tol_c = periodic_tolerance * bc + 1.0
            if i >= 2 and line[i - 2] == line[i] and (
                    (abs(l[i - 1] - b) <= tol and abs(l[i - 2] - b) <= tol)
                    or (abs(l[i - 1] - 2.0 * sh - bc) <= tol_c and abs(l[i - 2] + 2.0 * sh - bc) <= tol_c)):
                reg[k, 5, 0] = x[i - 2]
                reg[k, 5, 1] = x[i - 2] + l[i - 2]
            if i + 4 < n and line[i + 4] == line[i] and (
                    (abs(l[i + 3] - b) <= tol and abs(l[i + 4] - b) <= tol)
                    or (abs(l[i + 3] - 2.0 * sh - bc) <= tol_c and abs(l[i + 4] + 2.0 * sh - bc) <= tol_c)):
                reg[k, 6, 0] = x[i + 4]
                reg[k, 6, 1] = x[i + 4] + l[i + 4]
    return idx, xs, reg


@jit
def levels(lines, line, regions):
    """Mean of ``lines[line[t], a:b]`` over each ``(a, b)`` of ``regions`` (T, 7, 2); NaN if empty."""
    t_n = line.size
    out = np.empty((t_n, regions.shape[1]))
    for t in range(t_n):
        row = lines[line[t]]
        for r in range(regions.shape[1]):
            a, b = regions[t, r, 0], regions[t, r, 1]
            if b <= a:
                out[t, r] = np.nan
                continue
            seg = row[a:b]
            acc = 0
            for c in range(seg.size):
                acc += np.int32(seg[c])
            out[t, r] = acc / (b - a)
    return out
