"""Line thresholding, modified run-length coding and triple search (thesis §4.4-4.5.1).

Everything works on a whole batch of scan lines at once (a ``(k, W)`` uint8
array): the coarse scan of §4.4.1 thresholds, codes and searches its
``H / N`` lines. The per-pixel and per-run loops are compiled with numba
(``_``-prefixed kernels): numpy's per-call overhead (1-5 µs) would dominate on
arrays this small. The first call in a fresh environment compiles them (cached
in ``__pycache__`` afterwards). The detector calls the kernels from inside one
compiled search (:func:`localizer.recognize._recognize`); the Python functions here
(:func:`threshold_lines`, :func:`run_length_code`, :func:`find_triples`,
:func:`triple_levels`) run the same kernels on their own, for debug images and tests.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from localizer.params import DetectorParams


def threshold_lines(lines: np.ndarray, p: DetectorParams, window: int) -> np.ndarray:
    """Global plus local thresholding of §4.4.2, per pixel: ``(k, W)`` bool, True = white.

    The thesis takes one midway threshold per line. On a cluttered line that
    level is set by whatever is brightest and darkest anywhere on the line, so
    here the midway level is taken over a ``window``-pixel neighbourhood of
    each pixel (running max / min, i.e. a 1-D dilation / erosion, :func:`line_extrema`)
    wherever that neighbourhood has at least ``local_contrast`` grey levels of
    contrast; in flat stretches (the inside of a bar wider than the window) the
    line's own thesis threshold is used (:func:`_threshold`).
    """
    lines = np.ascontiguousarray(lines)
    hi, lo = line_extrema(lines, window)
    return _threshold(lines, hi, lo, int(p.contrast_window), float(p.local_contrast),
                      min(255, int(math.ceil(p.global_threshold))))


def line_extrema(lines: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Running max and min of each line of ``lines`` (k, W) uint8 over ``window`` pixels
    from ``window // 2`` left of each pixel, edges replicated (what OpenCV's dilate and
    erode with a ``1 x window`` kernel give): two ``(k, W)`` uint8 (:func:`_line_extrema`)."""
    return _line_extrema(lines, int(window))


@numba.njit(cache=True, nogil=True)
def _line_extrema(lines, window):
    """:func:`line_extrema`, compiled: the edge-padded lines laid end to end in one buffer,
    then the max / min over 2, 4, ... ``2^L <= window`` pixels by doubling (each pass two
    vectorised element-wise loops over the whole buffer, :func:`_max_min_into`; values
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
        _fill(x0[base:base + a], row[0])
        _copy(row, x0[base + a:base + a + w])
        _fill(x0[base + a + w:base + n], row[w - 1])
    _copy(x0, n0)
    k = 1
    while 2 * k <= window:  # x0[i] = max(padded[i : i + 2k])
        m = size - k
        _max_min_into(x0[:m], x0[k:], n0[:m], n0[k:], x1[:m], n1[:m])
        x0, x1 = x1, x0
        n0, n1 = n1, n0
        k *= 2
    o = window - k  # [c, c + window) = [c, c + k) and [c + o, c + o + k)
    m = size - o
    _max_min_into(x0[:m], x0[o:], n0[:m], n0[o:], x1[:m], n1[:m])
    hi = np.empty((k_n, w), np.uint8)
    lo = np.empty((k_n, w), np.uint8)
    for r in range(k_n):
        _copy(x1[r * n:r * n + w], hi[r])
        _copy(n1[r * n:r * n + w], lo[r])
    return hi, lo


@numba.njit(cache=True, nogil=True)
def _copy(src, dst):
    """``dst[:] = src[:dst.size]`` (a loop that vectorises)."""
    for i in range(dst.size):
        dst[i] = src[i]


@numba.njit(cache=True, nogil=True)
def _fill(dst, v):
    """``dst[:] = v``."""
    for i in range(dst.size):
        dst[i] = v


@numba.njit(cache=True, nogil=True)
def _max_min_into(a, b, c, d, mx, mn):
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


@numba.njit(cache=True, nogil=True)
def _threshold(lines, hi, lo, contrast_window, local_contrast, global_level):
    """Per-pixel threshold of :func:`threshold_lines` given the running max ``hi`` and min
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
        _threshold_line(row, hi[r], lo[r], np.int16(math.ceil(local_contrast)), np.int16(line_thr), out[r])
    return out


@numba.njit(cache=True, nogil=True)
def _threshold_line(row, hi, lo, local_contrast, line_thr, out):
    """One line of :func:`_threshold`: ``out[c]`` = ``row[c] >= hi[c] - (hi[c] - lo[c]) // 2``
    where ``hi[c] - lo[c] >= local_contrast``, else ``row[c] >= line_thr`` (branch-free int16
    on separate arrays, so that it vectorises)."""
    for c in range(out.size):
        h = np.int16(hi[c])
        con = h - np.int16(lo[c])
        t = h - (con >> 1) if con >= local_contrast else line_thr
        out[c] = np.int16(row[c]) >= t


@dataclass(frozen=True)
class Runs:
    """Modified run-length code (g, l, y, x) of a batch of lines (§4.4.3).

    All arrays are ``(R,)``, sorted by line then x. ``g``: True for white;
    ``l``: run length (px); ``y``: image row; ``x``: column of the run's first
    pixel; ``line``: index of the line within the batch.
    """

    g: np.ndarray
    l: np.ndarray
    y: np.ndarray
    x: np.ndarray
    line: np.ndarray
    width: int = 0  # line length (px)


def run_length_code(binary: np.ndarray, rows: np.ndarray, x_offset: int = 0) -> Runs:
    """Run-length code a ``(k, W)`` boolean batch whose lines are image ``rows`` (``(k,)``).

    Compiled (:func:`_rle`): a run starts wherever a pixel differs from its left
    neighbour or a line starts.
    """
    g, l, line, x = _rle(np.ascontiguousarray(binary, dtype=np.bool_))
    return Runs(g=g, l=l, y=np.asarray(rows)[line], x=x + x_offset, line=line, width=binary.shape[1] + x_offset)


@numba.njit(cache=True, nogil=True)
def _rle(binary):
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
            g, ln, line, x = _grown(g, j, cap), _grown(ln, j, cap), _grown(line, j, cap), _grown(x, j, cap)
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


@numba.njit(cache=True, nogil=True)
def _grown(a, n, cap):
    """A ``(cap,)`` array of ``a``'s dtype holding ``a[:n]``."""
    out = np.empty(cap, a.dtype)
    out[:n] = a[:n]
    return out


@dataclass(frozen=True)
class Triples:
    """Three consecutive near-equal runs (bar, gap, bar) found on scan lines.

    ``(T,)`` arrays: ``y`` row, ``line`` batch line index, ``x`` ``(T, 4)`` run
    boundaries (first pixel of bar 1, gap, bar 2, and one past bar 2),
    ``positive`` True for black-white-black. ``regions`` ``(T, 7, 2)`` (start, end)
    columns of the pixels whose grey levels :func:`triple_levels` samples: the
    margin next to each outer edge, the non-boundary pixels of the three runs,
    and the run beyond each margin when that margin and that run are both as
    long as the bars (the triple may then be part of a grating or a chessboard;
    else an empty region).
    """

    y: np.ndarray
    line: np.ndarray
    x: np.ndarray
    positive: np.ndarray
    regions: np.ndarray

    def __len__(self) -> int:
        return int(self.y.size)


_EMPTY = Triples(np.zeros(0, int), np.zeros(0, int), np.zeros((0, 4), int), np.zeros(0, bool),
                 np.zeros((0, 7, 2), int))


def near_equal(l0, l1, l2, p: DetectorParams):
    """The §4.5.1 test "three runs of approximately equal length", element-wise (arrays broadcast;
    :func:`_near_equal` is the compiled rule the scans use).

    Blur with clipping (saturation) or a threshold off the midway level moves
    every edge towards its dark side by a common amount, shrinking the dark runs
    and growing the light ones by twice that. Up to ``max_edge_shift`` px of such a
    shift is undone first (estimated from the gap against the mean bar); then the
    longest and shortest run may differ by ``width_tolerance`` of the longest plus
    ``width_slack`` px.
    """
    a0, a1, a2 = np.broadcast_arrays(np.asarray(l0, float), np.asarray(l1, float), np.asarray(l2, float))
    out = np.empty(a0.shape, bool)
    for k in np.ndindex(a0.shape):
        out[k] = _near_equal(a0[k], a1[k], a2[k], float(p.width_tolerance), float(p.width_slack),
                             float(p.max_edge_shift))
    return out


@numba.njit(cache=True, nogil=True)
def _near_equal(l0, l1, l2, width_tolerance, width_slack, max_edge_shift):
    """:func:`near_equal` for one triple of run lengths (px)."""
    c = min(max((l1 - 0.5 * (l0 + l2)) * 0.25, -max_edge_shift), max_edge_shift)
    a0 = l0 + 2.0 * c
    a1 = l1 - 2.0 * c
    a2 = l2 + 2.0 * c
    lmax = max(a0, a1, a2)
    return lmax - min(a0, a1, a2) <= width_tolerance * lmax + width_slack


def find_triples(runs: Runs, p: DetectorParams) -> Triples:
    """Feature detection (§4.5.1): runs i, i+1, i+2 of one line, alternately
    dark-light-dark (positive target) or light-dark-light (negative), near-equal
    in length (``width_tolerance``, ``width_slack``), at least ``min_bar_px`` long,
    with margin runs of at least ``min_margin_ratio`` times their mean on both sides.
    With ``reject_periodic``, triples inside five or more equal runs (gratings,
    chessboards) are dropped."""
    if runs.l.size < 5:
        return _EMPTY
    i, xs, reg = _triples(runs.l, runs.x, runs.line, int(runs.width), int(p.min_bar_px), float(p.width_tolerance),
                          float(p.width_slack), float(p.max_edge_shift), float(p.min_margin_ratio),
                          bool(p.reject_periodic), float(p.periodic_tolerance))
    if i.size == 0:
        return _EMPTY
    return Triples(y=runs.y[i], line=runs.line[i], x=xs, positive=~runs.g[i], regions=reg)


@numba.njit(cache=True, nogil=True)
def _triples(l, x, line, width, min_bar_px, width_tolerance, width_slack, max_edge_shift, min_margin_ratio,
             reject_periodic, periodic_tolerance):
    """The loop of :func:`find_triples` over run-length code ``l``, ``x``, ``line`` (R,).

    Returns ``(i (T,), x (T, 4), regions (T, 7, 2))``: the index of each triple's first
    bar, its run boundaries and sampled regions (see :class:`Triples`).
    """
    n = l.size
    idx = np.empty(max(n - 4, 0), np.int64)
    t = 0
    for i in range(1, n - 3):
        if line[i - 1] != line[i + 3] or l[i] < min_bar_px or l[i + 1] < min_bar_px or l[i + 2] < min_bar_px:
            continue
        l0, l1, l2 = l[i], l[i + 1], l[i + 2]
        if not _near_equal(float(l0), float(l1), float(l2), width_tolerance, width_slack, max_edge_shift):
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
            # five or more equal runs in a row (a grating, a chessboard): flag the run beyond
            # each margin; its grey level decides (a bar's shade = periodic, see find_stacks)
            tol = periodic_tolerance * b + 1.0
            if i >= 2 and line[i - 2] == line[i] and abs(l[i - 1] - b) <= tol and abs(l[i - 2] - b) <= tol:
                reg[k, 5, 0] = x[i - 2]
                reg[k, 5, 1] = x[i - 2] + l[i - 2]
            if i + 4 < n and line[i + 4] == line[i] and abs(l[i + 3] - b) <= tol and abs(l[i + 4] - b) <= tol:
                reg[k, 6, 0] = x[i + 4]
                reg[k, 6, 1] = x[i + 4] + l[i + 4]
    return idx, xs, reg


def triple_levels(lines: np.ndarray, tri: Triples) -> np.ndarray:
    """Mean grey level of each triple's sampled regions on its own scan line.

    ``(T, 7)``: left margin, bar, gap, bar, right margin (non-boundary pixels: up
    to 2 px at each end of a run are boundary, the thesis's 5-pixel edge
    transition; the margins are the ``max(1, b/4)`` pixels next to the outer edges),
    then the runs flagged by the periodic test (NaN where none).
    """
    return _levels(np.ascontiguousarray(lines), tri.line, tri.regions)


@numba.njit(cache=True, nogil=True)
def _levels(lines, line, regions):
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
