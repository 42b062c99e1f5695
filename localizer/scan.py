"""Line thresholding, modified run-length coding and triple search (thesis §4.4-4.5.1).

Everything works on a whole batch of scan lines at once (a ``(k, W)`` uint8
array): the coarse scan of §4.4.1 thresholds, codes and searches its
``H / N`` lines with a fixed number of numpy calls, whatever the image holds.
Per-call overhead of numpy (1-5 µs) dominates on arrays this small, so the
functions here avoid per-line or per-run Python loops.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from localizer.params import DetectorParams


def line_thresholds(lines: np.ndarray, p: DetectorParams) -> np.ndarray:
    """Per-line threshold of §4.4.2, ``(k,)`` grey levels (a pixel is white when ``>=``).

    The contrast over every ``contrast_window``-pixel stretch of a line is
    computed; if its maximum reaches ``local_contrast`` the line is
    thresholded midway between its brightest and darkest pixel, otherwise at
    the global threshold.
    """
    import cv2

    k = int(p.contrast_window) - 1
    contrast = cv2.absdiff(lines[:, k:], lines[:, :-k]).max(axis=1)
    hi = lines.max(axis=1).astype(np.int32)
    lo = lines.min(axis=1).astype(np.int32)
    mid = (hi + lo + 1) // 2
    return np.where(contrast >= p.local_contrast, mid, int(np.ceil(p.global_threshold))).astype(np.uint8)


def threshold_lines(lines: np.ndarray, p: DetectorParams, window: int) -> np.ndarray:
    """Global plus local thresholding of §4.4.2, per pixel: ``(k, W)`` bool, True = white.

    The thesis takes one midway threshold per line. On a cluttered line that
    level is set by whatever is brightest and darkest anywhere on the line, so
    here the midway level is taken over a ``window``-pixel neighbourhood of
    each pixel (running max / min, i.e. a 1-D dilation / erosion) wherever that
    neighbourhood has at least ``local_contrast`` grey levels of contrast; in
    flat stretches (the inside of a bar wider than the window) the line's own
    thesis threshold (:func:`line_thresholds`) is used.
    """
    import cv2

    kernel = np.ones((1, int(window)), np.uint8)
    hi = cv2.dilate(lines, kernel, borderType=cv2.BORDER_REPLICATE)
    lo = cv2.erode(lines, kernel, borderType=cv2.BORDER_REPLICATE)
    contrast = cv2.subtract(hi, lo)
    mid = cv2.subtract(hi, contrast >> 1)  # (hi + lo + 1) // 2 without overflow
    flat = contrast < p.local_contrast
    local = lines >= mid
    glob = lines >= line_thresholds(lines, p)[:, None]
    return (local & ~flat) | (glob & flat)


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

    One pass over the flattened batch: a run starts wherever a pixel differs
    from its left neighbour or a line starts.
    """
    k, w = binary.shape
    flatb = binary.ravel()
    change = np.empty(k * w, dtype=bool)
    change[0] = True
    np.not_equal(flatb[1:], flatb[:-1], out=change[1:])
    change[::w] = True
    start = np.flatnonzero(change)
    end = np.empty_like(start)
    end[:-1] = start[1:]
    end[-1] = k * w
    line = start // w
    x = start - line * w
    # a run never crosses a line end: the next line's first pixel always starts a run
    return Runs(g=flatb[start], l=end - start, y=np.asarray(rows)[line], x=x + x_offset, line=line,
                width=w + x_offset)


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
    """The §4.5.1 test "three runs of approximately equal length", element-wise.

    Blur with clipping (saturation) or a threshold off the midway level moves
    every edge towards its dark side by a common amount, shrinking the dark runs
    and growing the light ones by twice that. Up to ``max_edge_shift`` px of such a
    shift is undone first (estimated from the gap against the mean bar); then the
    longest and shortest run may differ by ``width_tolerance`` of the longest plus
    ``width_slack`` px.
    """
    c = np.minimum(np.maximum((l1 - 0.5 * (l0 + l2)) * 0.25, -p.max_edge_shift), p.max_edge_shift)
    a0 = l0 + 2.0 * c
    a1 = l1 - 2.0 * c
    a2 = l2 + 2.0 * c
    lmax = np.maximum(np.maximum(a0, a1), a2)
    lmin = np.minimum(np.minimum(a0, a1), a2)
    return (lmax - lmin) <= p.width_tolerance * lmax + p.width_slack


def find_triples(runs: Runs, p: DetectorParams) -> Triples:
    """Feature detection (§4.5.1): runs i, i+1, i+2 of one line, alternately
    dark-light-dark (positive target) or light-dark-light (negative), near-equal
    in length (``width_tolerance``, ``width_slack``), at least ``min_bar_px`` long,
    with margin runs of at least ``min_margin_ratio`` times their mean on both sides.
    With ``reject_periodic``, triples inside five or more equal runs (gratings,
    chessboards) are dropped."""
    l = runs.l
    n = l.size
    if n < 5:
        return _EMPTY
    line = runs.line
    longr = l >= p.min_bar_px
    # first-bar index i in 1..n-4; runs i-1 .. i+3 on one line (lines are sorted)
    cand = longr[1:-3] & longr[2:-2] & longr[3:-1] & (line[:-4] == line[4:])
    i = np.flatnonzero(cand) + 1
    if i.size == 0:
        return _EMPTY
    ok = near_equal(l[i], l[i + 1], l[i + 2], p)
    ok &= 3 * np.minimum(l[i - 1], l[i + 3]) >= p.min_margin_ratio * (l[i] + l[i + 1] + l[i + 2])
    i = i[ok]
    if i.size == 0:
        return _EMPTY
    x = runs.x
    x0, x1, x2 = x[i], x[i + 1], x[i + 2]
    x3 = x2 + l[i + 2]
    # sampled regions (start, end): left margin, bar, gap, bar, right margin, and the runs
    # beyond the margins when those could make five equal runs (else empty)
    b = (x3 - x0) / 3.0
    mw = np.maximum(1, (b * 0.25).astype(x.dtype))
    e0 = np.minimum(2, (x1 - x0 - 1) // 2)
    e1 = np.minimum(2, (x2 - x1 - 1) // 2)
    e2 = np.minimum(2, (x3 - x2 - 1) // 2)
    reg = np.empty((i.size, 7, 2), dtype=x.dtype)
    reg[:, 0, 0] = np.maximum(x0 - mw, 0)
    reg[:, 0, 1] = x0
    reg[:, 1, 0] = x0 + e0
    reg[:, 1, 1] = x1 - e0
    reg[:, 2, 0] = x1 + e1
    reg[:, 2, 1] = x2 - e1
    reg[:, 3, 0] = x2 + e2
    reg[:, 3, 1] = x3 - e2
    reg[:, 4, 0] = x3
    reg[:, 4, 1] = np.minimum(x3 + mw, runs.width)
    reg[:, 5:, :] = 0
    if p.reject_periodic:
        # five or more equal runs in a row (a grating, a chessboard): flag the run beyond
        # each margin; its grey level decides (a bar's shade = periodic, see find_stacks)
        tol = p.periodic_tolerance * b + 1.0
        im2 = np.maximum(i - 2, 0)
        ip4 = np.minimum(i + 4, n - 1)
        li = line[i]
        left = (line[im2] == li) & (i >= 2) & (np.abs(l[i - 1] - b) <= tol) & (np.abs(l[im2] - b) <= tol)
        right = (line[ip4] == li) & (i + 4 < n) & (np.abs(l[i + 3] - b) <= tol) & (np.abs(l[ip4] - b) <= tol)
        reg[left, 5, 0] = x[im2[left]]
        reg[left, 5, 1] = x[im2[left]] + l[im2[left]]
        reg[right, 6, 0] = x[ip4[right]]
        reg[right, 6, 1] = x[ip4[right]] + l[ip4[right]]
    return Triples(y=runs.y[i], line=line[i], x=np.stack([x0, x1, x2, x3], axis=1), positive=~runs.g[i],
                   regions=reg)


def scan_lines(image: np.ndarray, rows: np.ndarray, p: DetectorParams, window: int):
    """Threshold (:func:`threshold_lines`), code and search image ``rows`` (``(k,)``).

    Returns ``(triples, lines, n_runs)`` with ``lines`` the ``(k, W)`` grey lines.
    """
    lines = image[rows]
    binary = threshold_lines(lines, p, window)
    runs = run_length_code(binary, rows)
    return find_triples(runs, p), lines, int(runs.l.size)


def triple_levels(lines: np.ndarray, tri: Triples) -> np.ndarray:
    """Mean grey level of each triple's sampled regions on its own scan line.

    ``(T, 7)``: left margin, bar, gap, bar, right margin (non-boundary pixels: up
    to 2 px at each end of a run are boundary, the thesis's 5-pixel edge
    transition; the margins are the ``max(1, b/4)`` pixels next to the outer edges),
    then the runs flagged by the periodic test (NaN where none). One prefix sum
    over the lines and one gather: a fixed number of numpy calls for any ``T``.
    """
    k, w = lines.shape
    cs = np.zeros((k, w + 1), np.int32)
    np.cumsum(lines, axis=1, dtype=np.int32, out=cs[:, 1:])
    li = tri.line[:, None]
    reg = tri.regions
    cnt = reg[:, :, 1] - reg[:, :, 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        return (cs[li, reg[:, :, 1]] - cs[li, reg[:, :, 0]]) / cnt
