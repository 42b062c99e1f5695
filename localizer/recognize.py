"""Search (coarse + fine, §4.4.1), grouping and verification (§4.5.2) of candidates.

A candidate target is a *stack*: consecutive image rows each holding a
matching bar-gap-bar triple. Work per frame, in order of cost:

1. coarse scan: every ``N``-th line thresholded, run-length coded and searched
   for triples in one batch (:mod:`localizer.scan`);
2. every triple's grey levels on its own line: contrast between the runs,
   light margins, no grating (the cheap part of §4.5.2), then the minimum
   height and aspect tests in advance: 11 pixels across each surviving hit on
   17 sampled lines around it (:func:`_coarse_seeds`);
3. per remaining hit, the fine search of the thesis -- which walks up and down
   line by line from the hit until no line matches -- over one small region of
   interest thresholded at the hit's own midway level; on each line the runs
   around the hit's gap are found by walking out from it (:func:`_fine_stack`);
   then the full verification (:func:`_verify`).

Hits inside a stack already found are not searched again (the thesis's grouping).
The pixel loops are compiled with numba (``_``-prefixed kernels, cached in
``__pycache__`` after the first call in a fresh environment).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numba
import numpy as np

from localizer.camera import Camera
from localizer.params import DetectionStats, DetectorParams
from localizer.scan import _copy, _levels, _line_extrema, _near_equal, _rle, _threshold, _triples
from localizer.target import TargetSpec


@dataclass(frozen=True)
class Stack:
    """A verified (or candidate) target region.

    ``rows`` ``(n,)`` image rows (increasing; at most ``max_row_gap`` missing in a
    row); ``x`` ``(n, 4)`` run boundaries of each row's triple (first pixel of
    bar 1, gap, bar 2, one past bar 2); ``positive``: black bars on white;
    ``dark``/``bright``: mean grey levels of the bars and gap (or the reverse for
    negative targets); ``ends`` ``(2, 2)`` rough (first, last) row of each bar at
    its centre column (filled in by verification).
    """

    rows: np.ndarray
    x: np.ndarray
    positive: bool
    dark: float = float("nan")
    bright: float = float("nan")
    ends: tuple = ()
    median_x: np.ndarray | None = None

    @property
    def polarity(self) -> str:
        return "positive" if self.positive else "negative"

    @property
    def n_rows(self) -> int:
        """Rows spanned, first to last (a few may be missing, ``max_row_gap``)."""
        return int(self.rows[-1] - self.rows[0] + 1)

    @property
    def bounds(self) -> np.ndarray:
        """``(4,)`` median run boundaries (columns)."""
        if self.median_x is not None:
            return self.median_x
        return np.median(self.x, axis=0)


def find_stacks(image: np.ndarray, camera: Camera, target: TargetSpec, p: DetectorParams,
                stats: DetectionStats, keep_candidates: bool = True) -> tuple[list[Stack], list[Stack]]:
    """Coarse scan every ``coarse_step``-th row, check the hits' grey levels, fine-scan
    around each plausible new hit and verify the stack found (:func:`_verify`).

    The whole search runs in one compiled call (:func:`_recognize`); only the packing of
    the results is Python.

    Returns ``(candidates, verified)``: every stack found (only the verified ones unless
    ``keep_candidates``), and the verified ones (with grey levels and bar ends filled in)
    top to bottom, left to right.
    """
    counts, rows, x, ci, cf = _recognize(image, int(p.coarse_step), int(p.threshold_window), *_search_args(
        p, camera.fx, camera.fy, target.active_height, target.active_width, target.bar_width, target.bar_height))
    c = counts.tolist()
    stats.rows_scanned += c[0]
    stats.runs += c[1]
    stats.seeds += c[2]
    stats.candidates += c[3]
    for reason, k in zip(_REASONS, c[4:]):
        if k:
            stats.rejected[reason] = stats.rejected.get(reason, 0) + k
    stacks: list[Stack] = []
    verified: list[Stack] = []
    for i, ((a, b, pos, ok, t0, b0, t1, b1), f) in enumerate(zip(ci.tolist(), cf.tolist())):
        if ok:
            st = Stack(rows[a:b], x[a:b], pos == 1, f[4], f[5], ((t0, b0), (t1, b1)), cf[i, :4])
            verified.append(st)
            stacks.append(st)
        elif keep_candidates:
            stacks.append(Stack(rows[a:b], x[a:b], pos == 1, median_x=cf[i, :4]))
    if len(verified) > 1:
        verified.sort(key=lambda s: (int(s.rows[0]), float(s.x[0, 0])))
    return stacks, verified


@functools.lru_cache(maxsize=32)
def _search_args(p: DetectorParams, fx: float, fy: float, active_height: float, active_width: float,
                 bar_width: float, bar_height: float) -> tuple:
    """The scalar arguments of :func:`_recognize` after ``window`` for parameters ``p`` (resolved),
    a camera's focal lengths (px) and a target's geometry (m) (cached: ~30 conversions)."""
    ratio = active_height / active_width * fy / fx  # rows / columns of a target facing the camera
    return (int(p.contrast_window), float(p.local_contrast), min(255, int(math.ceil(p.global_threshold))),
            int(p.min_bar_px), float(p.width_tolerance), float(p.width_slack), float(p.max_edge_shift),
            float(p.min_margin_ratio), bool(p.reject_periodic), float(p.periodic_tolerance), float(p.min_contrast),
            float(p.min_contrast_ratio), int(p.min_rows), int(p.max_row_gap), ratio * (1.0 - p.aspect_tolerance),
            ratio / math.cos(p.max_alpha) * (1.0 + p.aspect_tolerance), float(p.uniformity),
            2.0 * bar_width / bar_height * math.sin(p.max_alpha) / fy, bool(p.check_margins),
            int(p.max_candidates), int(p.max_targets))


#: rejection reasons counted by :func:`_recognize`, by index (``stats.rejected`` keys)
_REASONS = ("fine_scan", "min_rows", "aspect_ratio", "uniformity", "contrast", "bar_ends", "bar_heights",
            "out_of_view", "margins")


@numba.njit(cache=True, nogil=True)
def _recognize(image, step, window, contrast_window, local_contrast, global_level, min_bar_px,
               width_tolerance, width_slack, max_edge_shift, min_margin_ratio, reject_periodic,
               periodic_tolerance, min_contrast, min_contrast_ratio, min_rows, max_row_gap, aspect_lo, aspect_hi,
               uniformity, height_term, check_margins, max_candidates, max_targets):
    """The search of :func:`find_stacks`, compiled as one call.

    The coarse scan lines are every ``step``-th image row, thresholded over ``window`` px
    (:func:`localizer.scan.threshold_lines`). In order: threshold, code
    and search the lines (:func:`localizer.scan._threshold`, ``_rle``, ``_triples``), grey
    levels and cheap tests of every triple (:func:`_coarse_seeds`), then per plausible hit,
    best-shaped triples first (where a margin, a bar and the gap pose as a triple of the
    other polarity, the true triple is then searched first) and unless it lies in a stack
    already searched (of the same polarity, or of either polarity once verified: a
    margin-bar-gap triple of a target looks like the other one), the fine search
    (:func:`_fine_stack`) and the verification (:func:`_verify`).

    Returns ``(counts, rows (N,), x (N, 4), ci (C, 8), cf (C, 6))`` for the ``C``
    candidate stacks found: ``counts`` = rows scanned, runs, seeds, candidates, then the
    rejections by :data:`_REASONS`; candidate ``c``'s rows are ``rows[a:b]`` with ``ci[c] =
    (a, b, positive, verified, top1, bottom1, top2, bottom2)`` and ``cf[c] = (median x (4),
    dark, bright)``.
    """
    h, w = image.shape
    lines = np.empty(((h + step - 1) // step, w), np.uint8)  # contiguous, so that loops vectorise
    for i in range(lines.shape[0]):
        _copy(image[i * step], lines[i])
    hi, lo = _line_extrema(lines, window)
    counts = np.zeros(4 + 9, np.int64)
    counts[0] = lines.shape[0]
    rows_out = np.empty(64, np.int64)
    x_out = np.empty((64, 4), np.int64)
    ci = np.zeros((0, 8), np.int64)
    cf = np.zeros((0, 6))
    binary = _threshold(lines, hi, lo, contrast_window, local_contrast, global_level)
    g, ln, line, xr = _rle(binary)
    counts[1] = ln.size
    if ln.size < 5:
        return counts, rows_out[:0], x_out[:0], ci, cf
    idx, tx, reg = _triples(ln, xr, line, lines.shape[1], min_bar_px, width_tolerance, width_slack,
                            max_edge_shift, min_margin_ratio, reject_periodic, periodic_tolerance)
    nt = idx.size
    if nt == 0:
        return counts, rows_out[:0], x_out[:0], ci, cf
    tline = np.empty(nt, np.int64)
    ty = np.empty(nt, np.int64)
    tpos = np.empty(nt, np.bool_)
    for t in range(nt):
        tline[t] = line[idx[t]]
        ty[t] = step * tline[t]
        tpos[t] = not g[idx[t]]
    lv = _levels(lines, tline, reg)
    seeds, top, bottom, thr_all, key = _coarse_seeds(image, lv, ty, tx, tpos, min_contrast, min_contrast_ratio,
                                                     reject_periodic, min_rows, max_row_gap, aspect_lo)
    ns = seeds.size
    counts[2] = ns
    if ns == 0:
        return counts, rows_out[:0], x_out[:0], ci, cf
    order = np.argsort(key, kind="mergesort")
    nmax = min(ns, max_candidates)
    ci = np.zeros((nmax, 8), np.int64)
    cf = np.zeros((nmax, 6))
    taken = np.empty((nmax, 6), np.int64)  # (row0, row1, x0, x1, positive, verified)
    nc = 0
    nv = 0
    nrows = 0
    gap = 2 + max_row_gap  # a hit this near a stack's end belongs to it (blurred end lines)
    for o in range(ns):
        s = order[o]
        k = seeds[s]
        y = ty[k]
        pk = tpos[k]
        skip = False
        for j in range(nc):
            if (taken[j, 0] - gap <= y <= taken[j, 1] + gap and tx[k, 1] < taken[j, 3] and tx[k, 2] > taken[j, 2]
                    and (taken[j, 4] == pk or taken[j, 5] == 1)):
                skip = True
                break
        if skip:
            continue
        if nc >= max_candidates or nv >= max_targets:
            break
        srows, sx, med, scanned = _fine_stack(image, y, tx[k, 0], tx[k, 1], tx[k, 2], tx[k, 3], pk, thr_all[k],
                                              top[s], bottom[s], max_row_gap, min_bar_px, width_tolerance,
                                              width_slack, max_edge_shift, min_margin_ratio)
        counts[0] += scanned
        if srows.size == 0:
            counts[4] += 1
            continue
        counts[3] += 1
        m = srows.size
        while nrows + m > rows_out.size:
            grown = np.empty(2 * rows_out.size, np.int64)
            grown[:nrows] = rows_out[:nrows]
            rows_out = grown
            xg = np.empty((2 * x_out.shape[0], 4), np.int64)
            xg[:nrows] = x_out[:nrows]
            x_out = xg
        rows_out[nrows:nrows + m] = srows
        x_out[nrows:nrows + m] = sx
        code, dark, bright, t0, b0, t1, b1 = _verify(image, srows, med, pk, min_rows, aspect_lo, aspect_hi,
                                                     uniformity, min_contrast, min_contrast_ratio, height_term,
                                                     check_margins)
        ci[nc, 0] = nrows
        ci[nc, 1] = nrows + m
        ci[nc, 2] = 1 if pk else 0
        x0 = sx[0, 0]
        x1 = sx[0, 3]
        for i in range(m):
            x0 = min(x0, sx[i, 0])
            x1 = max(x1, sx[i, 3])
        taken[nc, 0] = srows[0]
        taken[nc, 1] = srows[m - 1]
        taken[nc, 2] = x0
        taken[nc, 3] = x1
        taken[nc, 4] = 1 if pk else 0
        taken[nc, 5] = 1 if code == 0 else 0
        for c in range(4):
            cf[nc, c] = med[c]
        if code == 0:
            ci[nc, 3] = 1
            ci[nc, 4] = t0
            ci[nc, 5] = b0
            ci[nc, 6] = t1
            ci[nc, 7] = b1
            cf[nc, 4] = dark
            cf[nc, 5] = bright
            nv += 1
        else:
            counts[4 + code] += 1
        nrows += m
        nc += 1
    return counts, rows_out[:nrows], x_out[:nrows], ci[:nc], cf[:nc]


@numba.njit(cache=True, nogil=True)
def _coarse_seeds(image, lv, ty, tx, tpos, min_contrast, min_contrast_ratio, reject_periodic, min_rows,
                  max_row_gap, lo_ratio):
    """The cheap part of the verification (§4.5.2) for every coarse triple, in one pass.

    (a) Grey levels ``lv`` (T, 7) of the triple on its own line (:func:`triple_levels`):
    the gap must differ from both bars by ``min(min_contrast, min_contrast_ratio * bright)``,
    the margins must not be nearer the bars' shade than 0.35 of the contrast, and (periodic
    test) no run beyond a margin may be of the bars' shade (below 0.3).

    (b) Minimum height and aspect tests in advance: the stack through the triple's row
    ``y`` must be at least ``M`` rows tall, ``M`` = ``min_rows`` or, if more, the least
    height the aspect test allows for the triple's width (``lo_ratio`` times it). On 8
    rows either side of ``y``, spaced ``M / 8`` (at least ``min_rows // 6``) apart, 11
    pixels across the triple -- the middle of each margin, and the first, middle and
    last non-boundary pixel of each run -- thresholded at the midway level must have
    the triple's shades (the margin pixels may be blurred grey, within a quarter of the
    contrast of the threshold, but not clearly of the bars' shade); a single failing
    sampled row between good ones is forgiven where rows are sampled no further apart
    than ``max_row_gap + 1``; the run of good sampled rows through ``y`` must be able
    to span ``M`` rows.

    Args: ``ty`` (T,) rows, ``tx`` (T, 4) run boundaries, ``tpos`` (T,) polarities.
    Returns ``(seeds, top, bottom, thr, key)``: indices (S,) of the triples that pass,
    the (exclusive) bounds (S,) of the rows their stacks span as far as looked, the
    midway grey level (T,) of every triple, and the shape key (S,) (max - min) / max of
    the three run lengths.
    """
    h, w = image.shape
    nt = ty.size
    kmax = 8
    thr = np.empty(nt)
    seeds = np.empty(nt, np.int64)
    top = np.empty(nt, np.int64)
    bottom = np.empty(nt, np.int64)
    key = np.empty(nt)
    bad = np.empty(2 * kmax + 1, np.bool_)
    iso = np.empty(2 * kmax + 1, np.bool_)
    cols = np.empty(11, np.int64)
    ns = 0
    for t in range(nt):
        pos = tpos[t]
        l0, l1, l2, l3, l4 = lv[t, 0], lv[t, 1], lv[t, 2], lv[t, 3], lv[t, 4]
        outer = 0.5 * (l1 + l3)
        dark = outer if pos else l2
        bright = l2 if pos else outer
        thr[t] = 0.5 * (dark + bright)
        if np.isnan(l0) or np.isnan(l1) or np.isnan(l2) or np.isnan(l3) or np.isnan(l4):
            continue
        span = max(bright - dark, 1.0)
        # f: 0 = bar shade, 1 = gap shade, either polarity
        f0 = (l0 - dark) / span if pos else 1.0 - (l0 - dark) / span
        f4 = (l4 - dark) / span if pos else 1.0 - (l4 - dark) / span
        c = min(l2 - l1, l2 - l3) * (1.0 if pos else -1.0)
        need = min(min_contrast, min_contrast_ratio * bright)
        if not (c >= need and c > 0 and min(f0, f4) >= 0.35):
            continue
        if reject_periodic:
            periodic = False
            for r in (5, 6):
                fr = (lv[t, r] - dark) / span if pos else 1.0 - (lv[t, r] - dark) / span
                if fr < 0.3:  # NaN (no run flagged) is not periodic
                    periodic = True
            if periodic:
                continue
        # (b) the height test
        y = ty[t]
        x0, x3 = tx[t, 0], tx[t, 3]
        width = x3 - x0
        need_rows = max(min_rows, int(lo_ratio * width))
        step = max(max(1, min_rows // 6), -(-(need_rows - 1) // kmax))
        mw = max(1, width // 12)
        cols[0] = max(x0 - (mw + 1) // 2, 0)
        for j in range(3):
            a, b = tx[t, j], tx[t, j + 1]
            e = min(1, (b - a - 1) // 2)
            cols[1 + 3 * j] = a + e
            cols[2 + 3 * j] = (a + b) // 2
            cols[3 + 3 * j] = b - 1 - e
        cols[10] = min(x3 + mw // 2, w - 1)
        thr_t = thr[t]
        tol = 0.25 * (bright - dark)
        for k in range(2 * kmax + 1):
            row = y + (k - kmax) * step
            if row < 0 or row >= h:
                bad[k] = True
                continue
            b_ = False
            for j in range(1, 10):
                light = image[row, cols[j]] >= thr_t
                # shades of a positive target: margin light, bar dark, gap light, bar dark
                want = (j >= 4 and j <= 6) == pos
                if light != want:
                    b_ = True
            for j in (0, 10):
                v = float(image[row, cols[j]])
                if (pos and v < thr_t - tol) or (not pos and v > thr_t + tol):
                    b_ = True
            bad[k] = b_
        iso[0] = False
        iso[2 * kmax] = False
        for k in range(1, 2 * kmax):
            iso[k] = bad[k] and not bad[k - 1] and not bad[k + 1]
        if step <= max_row_gap + 1:
            for k in range(2 * kmax + 1):
                if iso[k]:
                    bad[k] = False
        n_up = kmax + 1
        for k in range(kmax + 1):
            if bad[kmax - k]:
                n_up = k
                break
        n_dn = kmax + 1
        for k in range(kmax + 1):
            if bad[kmax + k]:
                n_dn = k
                break
        if (n_up + n_dn - 1) * step < need_rows - 1:
            continue
        seeds[ns] = t
        top[ns] = y - n_up * step
        bottom[ns] = y + n_dn * step
        r0, r1, r2 = tx[t, 1] - x0, tx[t, 2] - tx[t, 1], x3 - tx[t, 2]
        lmax = max(r0, r1, r2)
        key[ns] = (lmax - min(r0, r1, r2)) / lmax
        ns += 1
    return seeds[:ns], top[:ns], bottom[:ns], thr, key[:ns]


@numba.njit(cache=True, nogil=True)
def _fine_rows(image, r0, r1, c0, c1, thr, positive, xg, xa, xb1, xb2, xc, tol, min_bar_px, width_tolerance,
               width_slack, max_edge_shift, min_margin_ratio):
    """The per-line test of the fine search (§4.4.1, §4.5.1) over rows ``r0:r1`` and
    columns ``c0:c1`` of ``image``, thresholded at ``thr`` (a pixel is of the bars' shade
    when ``< thr`` for positive targets, ``>= thr`` for negative ones).

    On each line the gap run holding column ``xg`` (relative to ``c0``) and the runs
    either side of it are found by walking out from ``xg``: left margin start ``l3``,
    bar 1 start ``l2``, gap start ``l1``, gap end ``r1``, bar 2 end ``r2``, right margin
    end ``r3`` (the margins are cut at the region's sides). A line matches when the
    three runs are at least ``min_bar_px`` long and near-equal (:func:`near_equal`),
    its margins are at least ``min_margin_ratio`` of the mean run, and its four
    boundaries are within ``tol`` px of the coarse hit's ``xa, xb1, xb2, xc``.
    Returns ``ok`` ``(r1 - r0,)`` bool and ``(r1 - r0, 4)`` boundaries ``l2, l1, r1, r2``
    (columns relative to ``c0``).
    """
    nrow = r1 - r0
    ncol = c1 - c0
    ok = np.zeros(nrow, np.bool_)
    bnd = np.zeros((nrow, 4), np.int64)
    for i in range(nrow):
        row = image[r0 + i, c0:c1]
        if (row[xg] < thr) == positive:  # the hit's gap column has the bars' shade
            continue
        l1 = xg
        while l1 > 0 and (row[l1 - 1] < thr) != positive:
            l1 -= 1
        if l1 == 0:
            continue
        l2 = l1 - 1
        while l2 > 0 and (row[l2 - 1] < thr) == positive:
            l2 -= 1
        l3 = 0
        if l2 > 0:
            l3 = l2 - 1
            while l3 > 0 and (row[l3 - 1] < thr) != positive:
                l3 -= 1
        rr1 = xg + 1
        while rr1 < ncol and (row[rr1] < thr) != positive:
            rr1 += 1
        if rr1 == ncol:
            continue
        rr2 = rr1 + 1
        while rr2 < ncol and (row[rr2] < thr) == positive:
            rr2 += 1
        rr3 = rr2
        if rr2 < ncol:
            rr3 = rr2 + 1
            while rr3 < ncol and (row[rr3] < thr) != positive:
                rr3 += 1
        b1 = l1 - l2
        gp = rr1 - l1
        b2 = rr2 - rr1
        if min(b1, gp, b2) < min_bar_px:
            continue
        if not _near_equal(float(b1), float(gp), float(b2), width_tolerance, width_slack, max_edge_shift):
            continue
        if 3.0 * min(l2 - l3, rr3 - rr2) < min_margin_ratio * (b1 + gp + b2):
            continue
        if abs(l2 - xa) > tol or abs(rr2 - xc) > tol or abs(l1 - xb1) > tol or abs(rr1 - xb2) > tol:
            continue
        ok[i] = True
        bnd[i, 0] = l2
        bnd[i, 1] = l1
        bnd[i, 2] = rr1
        bnd[i, 3] = rr2
    return ok, bnd


@numba.njit(cache=True, nogil=True)
def _fine_stack(image, y, xa, xb1, xb2, xc, positive, thr, span0, span1, max_row_gap, min_bar_px,
                width_tolerance, width_slack, max_edge_shift, min_margin_ratio):
    """Fine search (§4.4.1) around the coarse hit at row ``y`` with run boundaries ``xa, xb1,
    xb2, xc``, over the rows ``span0:span1`` (from :func:`_coarse_seeds`).

    Every line of a region of interest around the hit is thresholded at ``thr``
    (midway between the hit's dark and bright levels, §4.4.2); on each line the
    two transitions either side of the hit's gap centre give that line's bar,
    gap, bar and margin runs, which must pass the §4.5.1 test and stay within
    half a bar of the hit's boundaries (the bars' vertical edges are vertical
    in the image of a level camera) (:func:`_fine_rows`). The connected run of matching lines
    through the hit (at most ``max_row_gap`` lines missing in a row) is the stack;
    the region grows while the stack reaches its top or bottom line.

    Returns ``(rows (n,), x (n, 4), median_x (4,), rows_scanned)``; ``n`` is 0 when no
    matching line connects to the hit's row ``y``."""
    h, w = image.shape
    width = xc - xa
    m = width / 3.0
    pad = int(m) + 3
    c0 = max(0, xa - pad)
    c1 = min(w, xc + pad)
    r0 = max(0, span0 - 1)
    r1 = min(h, span1 + 1)
    xg = (xb1 + xb2) // 2 - c0
    tol = max(2.0, 0.5 * m)
    step = 1 + max_row_gap
    scanned = 0
    lo = 0
    hi = -1
    ok = np.zeros(0, np.bool_)
    bnd = np.zeros((0, 4), np.int64)
    for _ in range(8):  # grow the region while the stack reaches its top or bottom line
        nrow = r1 - r0
        scanned += nrow
        ok, bnd = _fine_rows(image, r0, r1, c0, c1, thr, positive, xg, xa - c0, xb1 - c0, xb2 - c0, xc - c0,
                             tol, min_bar_px, width_tolerance, width_slack, max_edge_shift, min_margin_ratio)
        # the connected run of matching lines through (or within `step` of) line y - r0,
        # consecutive matching lines at most `step` apart
        at = y - r0
        j = -1
        for i in range(max(0, at), min(nrow, at + step + 1)):  # first matching line at or below `at`
            if ok[i]:
                j = i
                break
        if j < 0:
            for i in range(min(at - 1, nrow - 1), max(-1, at - step - 1), -1):
                if ok[i]:
                    j = i
                    break
        if j < 0:
            return np.zeros(0, np.int64), np.zeros((0, 4), np.int64), np.zeros(4), scanned
        lo = j
        while True:
            k = lo - 1
            while k >= 0 and not ok[k] and lo - k <= step:
                k -= 1
            if k >= 0 and ok[k] and lo - k <= step:
                lo = k
            else:
                break
        hi = j
        while True:
            k = hi + 1
            while k < nrow and not ok[k] and k - hi <= step:
                k += 1
            if k < nrow and ok[k] and k - hi <= step:
                hi = k
            else:
                break
        grow_up = lo == 0 and r0 > 0
        grow_dn = hi == nrow - 1 and r1 < h
        if not (grow_up or grow_dn):
            break
        extra = max(2 * (hi - lo + 1), 8)
        if grow_up:
            r0 = max(0, r0 - extra)
        if grow_dn:
            r1 = min(h, r1 + extra)
    n = 0
    for i in range(lo, hi + 1):
        if ok[i]:
            n += 1
    rows = np.empty(n, np.int64)
    x = np.empty((n, 4), np.int64)
    k = 0
    for i in range(lo, hi + 1):
        if ok[i]:
            rows[k] = i + r0
            for c in range(4):
                x[k, c] = bnd[i, c] + c0
            k += 1
    med = np.empty(4)
    for c in range(4):
        xs = np.sort(x[:, c])
        med[c] = xs[n // 2] if n % 2 else 0.5 * (xs[n // 2 - 1] + xs[n // 2])
    return rows, x, med, scanned


@numba.njit(cache=True, nogil=True)
def _rough_ends(image, r0, r1, nr, col, thr, positive):
    """First and last row of the bar crossing rows ``r0..r1`` at column ``col``: walk
    up and down (at most ``nr`` rows) from the stack while the pixel keeps the bar's shade
    (``< thr`` for positive targets). Returns ``(top, bottom)`` rows."""
    h = image.shape[0]
    lo = max(0, r0 - nr)
    top = lo
    for r in range(r0, lo - 1, -1):
        if (image[r, col] < thr) != positive:  # the first pixel off the bar
            top = r + 1
            break
    hi = min(h, r1 + nr + 1) - 1
    bot = hi
    for r in range(r1, hi + 1):
        if (image[r, col] < thr) != positive:
            bot = r - 1
            break
    return top, bot


@numba.njit(cache=True, nogil=True)
def _mean_sd(image, r0, r1, c0, c1):
    """Mean and (population) standard deviation of ``image[r0:r1, c0:c1]`` (grey levels)."""
    s = 0
    ss = 0
    for r in range(r0, r1):
        seg = image[r, c0:c1]
        for c in range(seg.size):  # integer sums over a slice, so that it vectorises
            v = np.int32(seg[c])
            s += v
            ss += v * v
    n = max((r1 - r0) * (c1 - c0), 1)
    mu = s / n
    return mu, math.sqrt(max(ss / n - mu * mu, 0.0))


@numba.njit(cache=True, nogil=True)
def _count_shade(image, r0, r1, c0, c1, thr, light):
    """Pixels of ``image[r0:r1, c0:c1]`` that are ``>= thr`` (``light``) or ``< thr``."""
    n = 0
    for r in range(r0, r1):
        for c in range(c0, c1):
            if (image[r, c] >= thr) == light:
                n += 1
    return n


@numba.njit(cache=True, nogil=True)
def _verify_grey(image, r0, r1, nr, ra, rb, xb, positive, uniformity, min_contrast, min_contrast_ratio,
                 height_term, check_margins):
    """The grey-level part of :func:`_verify` for the stack on rows ``r0..r1`` (``nr``
    rows) with median run boundaries ``xb`` (4,), its segments sampled on rows ``ra:rb``.

    Uniform segments (``3.3 sd`` of the non-boundary pixels at most ``uniformity``),
    contrast between them, the rough bar ends (:func:`_rough_ends`) at each bar's centre
    column near the stack's ends, bar heights differing by at most ``height_term * h^2``
    plus slack (``height_term = 2 (b / H) sin(max_alpha) / fy``), and (``check_margins``)
    the blank margins above and below both bars. Returns ``(code, dark, bright, top1,
    bottom1, top2, bottom2)``; ``code`` 0 = passed, else 1 uniformity, 2 contrast, 3 bar ends, 4 bar
    heights, 5 out of view, 6 margins.
    """
    h, w = image.shape
    xi = np.empty(4, np.int64)
    for k in range(4):
        xi[k] = int(np.rint(xb[k]))
    means = np.empty(3)
    spread = 0.0
    for s in range(3):
        a, b = xi[s], xi[s + 1]
        mm = min(2, (b - a - 1) // 2)
        mu, sd = _mean_sd(image, ra, rb, a + mm, b - mm)
        means[s] = mu
        spread = max(spread, 3.3 * sd)
    if spread > uniformity:
        return 1, 0.0, 0.0, 0, 0, 0, 0
    if positive:
        dark, bright = 0.5 * (means[0] + means[2]), means[1]
        c = min(means[1] - means[0], means[1] - means[2])
    else:
        dark, bright = means[1], 0.5 * (means[0] + means[2])
        c = min(means[0] - means[1], means[2] - means[1])
    need = min(min_contrast, min_contrast_ratio * bright)
    if c < need or c <= 0:
        return 2, dark, bright, 0, 0, 0, 0
    thr = 0.5 * (dark + bright)
    t0, b0 = _rough_ends(image, r0, r1, nr, min(max((xi[0] + xi[1]) // 2, 0), w - 1), thr, positive)
    t1, b1 = _rough_ends(image, r0, r1, nr, min(max((xi[2] + xi[3]) // 2, 0), w - 1), thr, positive)
    # the stack ends where the shorter bar ends (a margin strip next to a bar, seen as a
    # bar of the other polarity, runs on past both ends of the stack)
    slack = 2 + 0.05 * nr
    if min(r0 - t0, r0 - t1) > slack or min(b0 - r1, b1 - r1) > slack:
        return 3, dark, bright, t0, b0, t1, b1
    # bar heights h1, h2 differ at most as the ranges of the bar centres do (|alpha| <= max_alpha):
    # |h1 - h2| / h <= 2 b sin(max_alpha) / Z with Z = fy H / h (eq 4.3), plus 2 rows of slack
    h0, h1 = b0 - t0 + 1, b1 - t1 + 1
    hm = 0.5 * (h0 + h1)
    if abs(h0 - h1) > height_term * hm * hm + 2.0 + 0.03 * hm:
        return 4, dark, bright, t0, b0, t1, b1
    if check_margins:
        # blank margin above and below each bar (thesis §3.4: s = H/4 tall)
        for k in range(2):
            t, b = (t0, b0) if k == 0 else (t1, b1)
            hb = b - t + 1
            ka = max(2, int(np.rint(0.12 * hb)))
            kb = max(ka, int(np.rint(0.17 * hb)))
            if t - kb < 0 or b + kb >= h:
                return 5, dark, bright, t0, b0, t1, b1
            a, bb = xi[2 * k], xi[2 * k + 1]
            for ya, yb in ((t - kb, t - ka + 1), (b + ka, b + kb + 1)):
                if _count_shade(image, ya, yb, a, bb, thr, positive) < 0.75 * (yb - ya) * max(bb - a, 0):
                    return 6, dark, bright, t0, b0, t1, b1
    return 0, dark, bright, t0, b0, t1, b1


@numba.njit(cache=True, nogil=True)
def _verify(image, rows, xb, positive, min_rows, aspect_lo, aspect_hi, uniformity, min_contrast,
            min_contrast_ratio, height_term, check_margins):
    """Pattern verification (§4.5.2) of the stack on ``rows`` (n,) with median run boundaries
    ``xb`` (4,): (1) minimum height (``min_rows``) and aspect ratio (rows spanned / width
    within ``aspect_lo .. aspect_hi``); (2) uniform grey within each segment (spread of
    non-boundary pixels, ``3.3 sd`` as a robust range, at most ``uniformity``; boundary = up
    to 2 px at each end, the thesis's 5-pixel edge transition) and contrast between adjacent
    segments (:func:`_verify_grey`); (3) connectivity is built into the stack. Also, with
    ``check_margins``: the blank margin above and below each bar. Returns ``(code, dark, bright,
    top1, bottom1, top2, bottom2)``, ``code`` 0 = verified, else an index into ``_REASONS``
    (1 = min_rows, 2 = aspect_ratio, 3.. = :func:`_verify_grey`'s codes + 2)."""
    r0, r1 = rows[0], rows[rows.size - 1]
    nr = r1 - r0 + 1
    if nr < min_rows:
        return 1, 0.0, 0.0, 0, 0, 0, 0
    ratio = nr / (xb[3] - xb[0])
    if not (aspect_lo <= ratio <= aspect_hi):
        return 2, 0.0, 0.0, 0, 0, 0, 0
    e = max(1, nr // 8)  # skip rows near the bar ends (blur, slanted tops)
    ra, rb = r0 + e, r1 + 1 - e
    if rb - ra < 2:
        return 1, 0.0, 0.0, 0, 0, 0, 0
    code, dark, bright, t0, b0, t1, b1 = _verify_grey(image, r0, r1, nr, ra, rb, xb, positive, uniformity,
                                                      min_contrast, min_contrast_ratio, height_term, check_margins)
    return (code + 2 if code else 0), dark, bright, t0, b0, t1, b1
