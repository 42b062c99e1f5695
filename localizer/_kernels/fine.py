"""Kernels of the fine search (thesis §4.4.1) around one coarse hit.

The thesis walks up and down line by line from a coarse hit until no line matches;
here one small region of interest around the hit is thresholded at the hit's own
midway level and tested line by line (:func:`fine_rows`), and the connected run of
matching lines through the hit is the stack (:func:`fine_stack`).
"""
from __future__ import annotations

import numpy as np

from localizer._jit import jit
from localizer._kernels.scan import near_equal


@jit
def fine_rows(image, rows, cols, thr, positive, xg, hit, tol, runs):
    """The per-line test of the fine search (§4.4.1, §4.5.1) over rows ``rows = (r0, r1)``
    (``r0:r1``) and columns ``cols = (c0, c1)`` (``c0:c1``) of ``image`` (H, W) uint8,
    thresholded at ``thr`` (grey level; a pixel is of the bars' shade when ``< thr`` for
    ``positive`` targets, ``>= thr`` for negative ones).

    On each line the gap run holding column ``xg`` (relative to ``c0``) and the runs
    either side of it are found by walking out from ``xg``: left margin start ``l3``,
    bar 1 start ``l2``, gap start ``l1``, gap end ``r1``, bar 2 end ``r2``, right margin
    end ``r3`` (the margins are cut at the region's sides). A line matches when the
    three runs are at least ``min_bar_px`` long and near-equal
    (:func:`localizer._kernels.scan.near_equal`), its margins are at least
    ``min_margin_ratio`` of the mean run (both of the run test ``runs``,
    :class:`~localizer._kernels.records.RunTest`), and its four boundaries are within
    ``tol`` px of the coarse hit's ``hit = (xa, xb1, xb2, xc)`` (relative to ``c0``).
    Returns ``ok`` ``(r1 - r0,)`` bool and ``(r1 - r0, 4)`` boundaries ``l2, l1, r1, r2``
    (columns relative to ``c0``).
    """
    r0, r1 = rows
    c0, c1 = cols
    xa, xb1, xb2, xc = hit
    min_bar_px, width_tolerance, width_slack = runs.min_bar_px, runs.width_tolerance, runs.width_slack
    max_edge_shift, min_margin_ratio = runs.max_edge_shift, runs.min_margin_ratio
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
        if not near_equal(float(b1), float(gp), float(b2), width_tolerance, width_slack, max_edge_shift):
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


@jit
def fine_stack(image, y, hit, positive, thr, span, max_row_gap, runs):
    """Fine search (§4.4.1) around the coarse hit at row ``y`` with run boundaries
    ``hit = (xa, xb1, xb2, xc)`` (columns), over the rows ``span = (span0, span1)``
    (``span0:span1``, from :func:`localizer._kernels.search.coarse_seeds`); ``runs`` the
    :class:`~localizer._kernels.records.RunTest`.

    Every line of a region of interest around the hit is thresholded at ``thr``
    (midway between the hit's dark and bright levels, §4.4.2); on each line the
    two transitions either side of the hit's gap centre give that line's bar,
    gap, bar and margin runs, which must pass the §4.5.1 test and stay within
    half a bar of the hit's boundaries (the bars' vertical edges are vertical
    in the image of a level camera) (:func:`fine_rows`). The connected run of matching lines
    through the hit (at most ``max_row_gap`` lines missing in a row) is the stack;
    the region grows while the stack reaches its top or bottom line.

    Returns ``(rows (n,), x (n, 4), median_x (4,), rows_scanned)``; ``n`` is 0 when no
    matching line connects to the hit's row ``y``."""
    xa, xb1, xb2, xc = hit
    span0, span1 = span
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
        ok, bnd = fine_rows(image, (r0, r1), (c0, c1), thr, positive, xg, (xa - c0, xb1 - c0, xb2 - c0, xc - c0),
                            tol, runs)
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
