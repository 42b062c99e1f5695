"""Line thresholding, modified run-length coding and triple search (thesis §4.4-4.5.1).

Everything works on a whole batch of scan lines at once (a ``(k, W)`` uint8
array): the coarse scan of §4.4.1 thresholds, codes and searches its
``H / N`` lines. The per-pixel and per-run loops are compiled with numba
(:mod:`localizer._kernels.scan`): numpy's per-call overhead (1-5 µs) would dominate on
arrays this small. The first call in a fresh environment compiles them (cached
in ``__pycache__`` afterwards). The detector calls the kernels from inside one
compiled search (:func:`localizer._kernels.search.recognize`); the Python functions here
(:func:`threshold_lines`, :func:`run_length_code`, :func:`find_triples`,
:func:`triple_levels`) run the same kernels on their own, for debug images and tests.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from localizer._kernels import scan as kernels
from localizer._kernels.records import RunTest
from localizer.model.params import DetectorParams


def threshold_lines(lines: np.ndarray, p: DetectorParams, window: int, noise: float = 0.0) -> np.ndarray:
    """Global plus local thresholding of §4.4.2, per pixel: ``(k, W)`` bool, True = white.

    The thesis takes one midway threshold per line. On a cluttered line that
    level is set by whatever is brightest and darkest anywhere on the line, so
    here the midway level is taken over a ``window``-pixel neighbourhood of
    each pixel (running max / min, i.e. a 1-D dilation / erosion, :func:`line_extrema`)
    wherever that neighbourhood has at least ``local_contrast`` grey levels of
    contrast; in flat stretches (the inside of a bar wider than the window) the
    line's own thesis threshold is used (:func:`localizer._kernels.scan.threshold`).

    ``noise``: the frame's noise sd (grey levels; :func:`localizer._kernels.noise.frame_noise`,
    what the detector measures), which raises that contrast to :func:`noise_contrast` times
    it where that is more (0: ``local_contrast`` alone).
    """
    lines = np.ascontiguousarray(lines)
    hi, lo = line_extrema(lines, window)
    contrast = max(float(p.local_contrast), noise_contrast(window) * float(noise))
    return kernels.threshold(lines, hi, lo, int(p.contrast_window), contrast,
                      min(255, int(math.ceil(p.global_threshold))))


#: the largest probability that a threshold window of pure sensor noise reaches
#: :func:`noise_contrast` times its sd (a bound: the true share is about ten times less)
NOISE_FALSE_EDGE = 0.05


@functools.lru_cache(maxsize=16)
def noise_contrast(window: int) -> float:
    """How many noise sd of contrast (max - min) a ``window``-pixel neighbourhood must reach
    before the line thresholding (§4.4.2) takes it for an edge: ``K`` with
    ``2 n Q(K / 2) = NOISE_FALSE_EDGE`` (``n = window``, ``Q`` the Gaussian tail). A window of
    ``n`` pixels of noise sd ``s`` reaches a range of ``K s`` only if a pixel lies ``K s / 2``
    from their mean, which each does with probability ``2 Q(K / 2)`` (a union bound). 6.3 for
    the 33-pixel window at 512 columns.

    Why: the thesis's fixed "30 grey levels within an area" (``local_contrast``) assumes a
    quiet sensor. Under ~8 grey levels of noise (a small sensor in poor light) the range of 33
    pixels of flat paper is ~33 levels, so the inside of a bar or gap wider than half the
    window was thresholded midway between its own noise extremes, and its run broke into
    pieces of 1-5 px: no bar-gap-bar triple on any scan line of a near target. Scaled with
    the noise measured on the frame, the test keeps the thesis's 30 levels on a quiet frame
    and asks for more only where the noise itself reaches them.
    """
    n = max(int(window), 1)
    q = 0.5 * NOISE_FALSE_EDGE / n  # Q(K / 2)
    lo, hi = 0.0, 40.0
    for _ in range(100):  # Q(z) = erfc(z / sqrt(2)) / 2, decreasing
        mid = 0.5 * (lo + hi)
        if 0.5 * math.erfc(mid / math.sqrt(2.0)) > q:
            lo = mid
        else:
            hi = mid
    return 2.0 * lo


def line_extrema(lines: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Running max and min of each line of ``lines`` (k, W) uint8 over ``window`` pixels
    from ``window // 2`` left of each pixel, edges replicated (what OpenCV's dilate and
    erode with a ``1 x window`` kernel give): two ``(k, W)`` uint8
    (:func:`localizer._kernels.scan.line_extrema`)."""
    return kernels.line_extrema(lines, int(window))


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

    Compiled (:func:`localizer._kernels.scan.rle`): a run starts wherever a pixel differs from its left
    neighbour or a line starts.
    """
    g, l, line, x = kernels.rle(np.ascontiguousarray(binary, dtype=np.bool_))
    return Runs(g=g, l=l, y=np.asarray(rows)[line], x=x + x_offset, line=line, width=binary.shape[1] + x_offset)


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
    :func:`localizer._kernels.scan.near_equal` is the compiled rule the scans use).

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
        out[k] = kernels.near_equal(a0[k], a1[k], a2[k], float(p.width_tolerance), float(p.width_slack),
                             float(p.max_edge_shift))
    return out


def run_test(p: DetectorParams) -> RunTest:
    """The §4.5.1 run-test settings of ``p`` as the kernels take them."""
    return RunTest(int(p.min_bar_px), float(p.width_tolerance), float(p.width_slack), float(p.max_edge_shift),
                   float(p.min_margin_ratio), bool(p.reject_periodic), float(p.periodic_tolerance))


def find_triples(runs: Runs, p: DetectorParams) -> Triples:
    """Feature detection (§4.5.1): runs i, i+1, i+2 of one line, alternately
    dark-light-dark (positive target) or light-dark-light (negative), near-equal
    in length (``width_tolerance``, ``width_slack``), at least ``min_bar_px`` long,
    with margin runs of at least ``min_margin_ratio`` times their mean on both sides.
    With ``reject_periodic``, triples inside five or more equal runs (gratings,
    chessboards) are dropped."""
    if runs.l.size < 5:
        return _EMPTY
    i, xs, reg = kernels.triples(runs.l, runs.x, runs.line, int(runs.width), run_test(p))
    if i.size == 0:
        return _EMPTY
    return Triples(y=runs.y[i], line=runs.line[i], x=xs, positive=~runs.g[i], regions=reg)


def triple_levels(lines: np.ndarray, tri: Triples) -> np.ndarray:
    """Mean grey level of each triple's sampled regions on its own scan line.

    ``(T, 7)``: left margin, bar, gap, bar, right margin (non-boundary pixels: up
    to 2 px at each end of a run are boundary, the thesis's 5-pixel edge
    transition; the margins are the ``max(1, b/4)`` pixels next to the outer edges),
    then the runs flagged by the periodic test (NaN where none).
    """
    return kernels.levels(np.ascontiguousarray(lines), tri.line, tri.regions)


