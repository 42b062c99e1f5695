"""Kernels of the whole search (thesis §4.4.1, §4.5.2): coarse scan, cheap tests of every
coarse triple, fine search and verification of the plausible hits, in one compiled call.
"""
from __future__ import annotations

import numpy as np

from localizer._jit import jit
from localizer._kernels.fine import fine_stack
from localizer._kernels.records import CANDIDATE, SEARCH_COUNTS, Reject, RunTest, SearchResult
from localizer._kernels.arrays import copy, copy_rows
from localizer._kernels.noise import frame_noise
from localizer._kernels.scan import levels, line_extrema, rle, threshold, triples
from localizer._kernels.verify import verify


@jit
def recognize(image, settings):
    """The search of :func:`localizer.search.recognize.find_stacks`, compiled as one call.

    Args:
        image: ``(H, W)`` uint8 grey frame, C-contiguous.
        settings: ``(1,)`` :data:`~localizer._kernels.records.SEARCH_SETTINGS` record, the
            :class:`~localizer._kernels.records.SearchSettings` of the frame.

    The coarse scan lines are every ``s.step``-th image row, thresholded over ``s.window``
    px (:func:`localizer.search.scan.threshold_lines`; the contrast that switches a pixel to the
    midway threshold is ``local_contrast`` or, on a noisy frame, ``noise_contrast`` times the
    frame's noise sd, :func:`localizer._kernels.noise.frame_noise`). In order: threshold, code and search the
    lines (:func:`localizer._kernels.scan.threshold`, ``rle``, ``triples``), grey levels and
    cheap tests of every triple (:func:`coarse_seeds`), then per plausible hit,
    best-shaped triples first (where a margin, a bar and the gap pose as a triple of the
    other polarity, the true triple is then searched first) and unless it lies in a stack
    already searched (of the same polarity, or of either polarity once verified: a
    margin-bar-gap triple of a target looks like the other one), the fine search
    (:func:`localizer._kernels.fine.fine_stack`) and the verification
    (:func:`localizer._kernels.verify.verify`).

    Returns a :class:`~localizer._kernels.records.SearchResult`: the work counts and the
    rejections counted by :class:`~localizer._kernels.records.Reject`
    (:data:`~localizer._kernels.records.SEARCH_COUNTS`), the rows ``(N,)`` and run
    boundaries ``(N, 4)`` of every candidate's lines and the ``C`` candidate stacks
    (:data:`~localizer._kernels.records.CANDIDATE` records).
    """
    s = settings[0]
    runs = RunTest(s.min_bar_px, s.width_tolerance, s.width_slack, s.max_edge_shift, s.min_margin_ratio,
                   s.reject_periodic, s.periodic_tolerance)
    step, window, max_row_gap = s.step, s.window, s.max_row_gap
    max_candidates, max_targets = s.max_candidates, s.max_targets
    h, w = image.shape
    lines = np.empty(((h + step - 1) // step, w), np.uint8)  # contiguous, so that loops vectorise
    for i in range(lines.shape[0]):
        copy(image[i * step], lines[i])
    hi, lo = line_extrema(lines, window)
    counts = np.zeros(1, SEARCH_COUNTS)
    c = counts[0]
    c.rows_scanned = lines.shape[0]
    rows_out = np.empty(64, np.int64)
    x_out = np.empty((64, 4), np.int64)
    # the contrast that switches to the midway threshold: at least what the frame's own noise
    # reaches within a threshold window (localizer.search.scan.noise_contrast)
    contrast = max(s.local_contrast, s.noise_contrast * frame_noise(image, step))
    binary = threshold(lines, hi, lo, s.contrast_window, contrast, s.global_level)
    g, ln, line, xr = rle(binary)
    c.runs = ln.size
    if ln.size < 5:
        return SearchResult(counts, rows_out[:0], x_out[:0], np.zeros(0, CANDIDATE))
    idx, tx, reg = triples(ln, xr, line, lines.shape[1], runs)
    nt = idx.size
    if nt == 0:
        return SearchResult(counts, rows_out[:0], x_out[:0], np.zeros(0, CANDIDATE))
    tline = np.empty(nt, np.int64)
    ty = np.empty(nt, np.int64)
    tpos = np.empty(nt, np.bool_)
    for t in range(nt):
        tline[t] = line[idx[t]]
        ty[t] = step * tline[t]
        tpos[t] = not g[idx[t]]
    lv = levels(lines, tline, reg)
    seeds, top, bottom, thr_all, key = coarse_seeds(image, lv, ty, tx, tpos, s)
    ns = seeds.size
    c.seeds = ns
    if ns == 0:
        return SearchResult(counts, rows_out[:0], x_out[:0], np.zeros(0, CANDIDATE))
    order = np.argsort(key, kind="mergesort")
    nmax = min(ns, max_candidates)
    cand = np.zeros(nmax, CANDIDATE)
    taken = np.empty((nmax, 6), np.int64)  # (row0, row1, x0, x1, positive, verified)
    nc = 0
    nv = 0
    nrows = 0
    gap = 2 + max_row_gap  # a hit this near a stack's end belongs to it (blurred end lines)
    for o in range(ns):
        q = order[o]
        k = seeds[q]
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
        srows, sx, med, scanned = fine_stack(image, y, (tx[k, 0], tx[k, 1], tx[k, 2], tx[k, 3]), pk, thr_all[k],
                                             (top[q], bottom[q]), max_row_gap, runs)
        c.rows_scanned += scanned
        if srows.size == 0:
            c.rejected[Reject.FINE_SCAN] += 1
            continue
        c.candidates += 1
        m = srows.size
        while nrows + m > rows_out.size:
            grown = np.empty(2 * rows_out.size, np.int64)
            copy(rows_out, grown[:nrows])
            rows_out = grown
            xg = np.empty((2 * x_out.shape[0], 4), np.int64)
            copy_rows(x_out, xg[:nrows])
            x_out = xg
        copy(srows, rows_out[nrows:nrows + m])
        copy_rows(sx, x_out[nrows:nrows + m])
        v = verify(image, srows, med, pk, s)
        ok = v.reason == Reject.NONE
        cd = cand[nc]
        cd.start = nrows
        cd.stop = nrows + m
        cd.positive = pk
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
        taken[nc, 5] = 1 if ok else 0
        for k in range(4):
            cd.median_x[k] = med[k]
        if ok:
            cd.verified = True
            cd.top1 = v.top1
            cd.bottom1 = v.bottom1
            cd.top2 = v.top2
            cd.bottom2 = v.bottom2
            cd.dark = v.dark
            cd.bright = v.bright
            nv += 1
        else:
            c.rejected[v.reason] += 1
        nrows += m
        nc += 1
    return SearchResult(counts, rows_out[:nrows], x_out[:nrows], cand[:nc])


@jit
def coarse_seeds(image, lv, ty, tx, tpos, s):
    """The cheap part of the verification (§4.5.2) for every coarse triple, in one pass.

    (a) Grey levels ``lv`` (T, 7) of the triple on its own line (:func:`localizer.search.scan.triple_levels`):
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

    Args: ``image`` (H, W) uint8; ``lv`` (T, 7) grey levels; ``ty`` (T,) rows, ``tx`` (T, 4)
    run boundaries (columns), ``tpos`` (T,) polarities of the triples; ``s`` the
    :class:`~localizer._kernels.records.SearchSettings` record (``min_contrast``,
    ``min_contrast_ratio``, ``reject_periodic``, ``min_rows``, ``max_row_gap`` and
    ``aspect_lo``, the ``lo_ratio`` above).
    Returns ``(seeds, top, bottom, thr, key)``: indices (S,) of the triples that pass,
    the (exclusive) bounds (S,) of the rows their stacks span as far as looked, the
    midway grey level (T,) of every triple, and the shape key (S,) (max - min) / max of
    the three run lengths.
    """
    min_contrast, min_contrast_ratio, reject_periodic = s.min_contrast, s.min_contrast_ratio, s.reject_periodic
    min_rows, max_row_gap, lo_ratio = s.min_rows, s.max_row_gap, s.aspect_lo
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
