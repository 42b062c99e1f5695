"""Search (coarse + fine, §4.4.1), grouping and verification (§4.5.2) of candidates.

A candidate target is a *stack*: consecutive image rows each holding a
matching bar-gap-bar triple. Work per frame, in order of cost:

1. coarse scan: every ``N``-th line thresholded, run-length coded and searched
   for triples in one batch (:mod:`localizer.scan`);
2. every triple's grey levels on its own line, all triples at once: contrast
   between the runs, light margins, no grating (the cheap part of §4.5.2);
3. the minimum height and aspect tests in advance (:func:`_tall_enough`): 11
   pixels across each surviving hit on every other line around it, all hits at once;
4. per remaining hit, the fine search of the thesis -- which walks up and down
   line by line from the hit until no line matches -- as one small region of
   interest thresholded at the hit's own midway level and run-length coded at
   once; on each line the runs around the hit's gap are looked up
   (:func:`_fine_scan`); then the full verification (:func:`verify_stack`).

Hits inside a stack already found are not searched again (the thesis's grouping).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.camera import Camera
from localizer.params import DetectionStats, DetectorParams
from localizer.scan import near_equal, scan_lines, triple_levels
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
                stats: DetectionStats) -> tuple[list[Stack], list[Stack]]:
    """Coarse scan every ``coarse_step``-th row, check the hits' grey levels, fine-scan
    around each plausible new hit and verify the stack found (:func:`verify_stack`).

    Returns ``(candidates, verified)``: every stack found, and the verified ones
    (with grey levels and bar ends filled in) top to bottom, left to right.
    """
    h, w = image.shape
    n = int(p.coarse_step)
    coarse_rows = np.arange(0, h, n)
    tri, lines, nruns = scan_lines(image, coarse_rows, p, int(p.threshold_window))
    stats.rows_scanned += coarse_rows.size
    stats.runs += nruns
    if len(tri) == 0:
        return [], []
    # grey levels of every triple on its own line (§4.5.2 (2)): contrast between the runs,
    # light margins, no bar-shaded run beyond a margin (five equal runs: a grating)
    lv = triple_levels(lines, tri)
    pos = tri.positive
    sgn = np.where(pos, 1.0, -1.0)[:, None]
    outer = 0.5 * (lv[:, 1] + lv[:, 3])
    dark = np.where(pos, outer, lv[:, 2])
    bright = np.where(pos, lv[:, 2], outer)
    span = np.maximum(bright - dark, 1.0)[:, None]
    f = (lv - dark[:, None]) / span  # 0 = dark level, 1 = bright level
    f = np.where(pos[:, None], f, 1.0 - f)  # 0 = bar shade, 1 = gap shade, either polarity
    c = np.minimum(lv[:, 2] - lv[:, 1], lv[:, 2] - lv[:, 3]) * sgn[:, 0]
    need = np.minimum(p.min_contrast, p.min_contrast_ratio * bright)
    with np.errstate(invalid="ignore"):
        ok = (c >= need) & (c > 0) & (np.minimum(f[:, 0], f[:, 4]) >= 0.35)
        if p.reject_periodic:
            ok &= ~(f[:, 5] < 0.3) & ~(f[:, 6] < 0.3)
    seeds = np.flatnonzero(ok)
    if seeds.size:
        lo_ratio = target.active_height / target.active_width * camera.fy / camera.fx * (1.0 - p.aspect_tolerance)
        tall, top, bottom = _tall_enough(image, tri, seeds, 0.5 * (dark + bright), bright - dark, p, lo_ratio)
        seeds, top, bottom = seeds[tall], top[tall], bottom[tall]
    stats.seeds += int(seeds.size)
    if seeds.size == 0:
        return [], []
    thr_all = 0.5 * (dark + bright)
    # best-shaped triples first (the runs most nearly equal): where a margin, a bar and the
    # gap pose as a triple of the other polarity, the true triple is then searched first
    l3 = np.diff(tri.x[seeds], axis=1)
    order = np.argsort((l3.max(axis=1) - l3.min(axis=1)) / l3.max(axis=1), kind="stable")
    seeds, top, bottom = seeds[order], top[order].tolist(), bottom[order].tolist()
    stacks: list[Stack] = []
    verified: list[Stack] = []
    taken: list[tuple[int, int, int, int, bool, bool]] = []  # (row0, row1, x0, x1, positive, verified)
    ys = tri.y.tolist()
    xbs = tri.x.tolist()
    g = 2 + int(p.max_row_gap)  # a hit this near a stack's end belongs to it (blurred end lines)
    for k, ya, yb in zip(seeds.tolist(), top, bottom):
        y = ys[k]
        xb = xbs[k]
        pk = bool(pos[k])
        # skip hits inside a stack already searched: of the same polarity, or of either
        # polarity once verified (a margin-bar-gap triple of a target looks like the other one)
        if any(r0 - g <= y <= r1 + g and xb[1] < c1 and xb[2] > c0 and (pp == pk or vv)
               for r0, r1, c0, c1, pp, vv in taken):
            continue
        if len(stacks) >= p.max_candidates or len(verified) >= p.max_targets:
            break
        st = _fine_scan(image, y, xb, pk, float(thr_all[k]), p, (ya, yb), stats)
        if st is None:
            continue
        stacks.append(st)
        stats.candidates += 1
        v = verify_stack(image, camera, target, st, p, stats)
        if v is not None:
            verified.append(v)
        taken.append((int(st.rows[0]), int(st.rows[-1]), int(st.x[:, 0].min()), int(st.x[:, 3].max()), pk,
                       v is not None))
    verified.sort(key=lambda s: (int(s.rows[0]), float(s.x[0, 0])))
    return stacks, verified


def _tall_enough(image: np.ndarray, tri, seeds: np.ndarray, thr: np.ndarray, span: np.ndarray,
                 p: DetectorParams, lo_ratio: float):
    """Minimum-height and aspect tests (§4.5.2 (1)) in advance, for all seeds at once.

    The stack through the seed's row ``y`` must be at least ``M`` rows tall: ``M``
    is ``min_rows`` or, if more, the least height the aspect test allows for the
    seed's width (``lo_ratio`` times it). On 8 rows either side of ``y``, spaced ``M / 8``
    (at least ``min_rows // 6``) apart, 11 pixels across
    the seed -- the middle of each margin, and the first, middle and last
    non-boundary pixel of each run -- thresholded at the seed's midway level
    ``thr`` must have the seed's shades (the margin pixels may be blurred grey, within a
    quarter of the contrast ``span`` of ``thr``, but not clearly of the bars' shade); the run of
    good sampled rows through ``y`` must be able to span ``M`` rows. One gather for
    all seeds and rows.
    Returns a boolean mask over ``seeds`` and ``(S,)`` bounds (exclusive) of the
    rows the stack spans as far as looked (within ``M`` of ``y``).
    """
    h, w = image.shape
    y = tri.y[seeds]
    xb = tri.x[seeds]
    width = xb[:, 3] - xb[:, 0]
    need = np.maximum(int(p.min_rows), (lo_ratio * width).astype(int))  # (S,) least stack height
    # sample every step-th row (the stack is connected), kmax samples each way: step grows with
    # the least height, at most min_rows // 6 (about 2 rows) for the smallest targets
    kmax = 8
    step = np.maximum(max(1, int(p.min_rows) // 6), -(-(need - 1) // kmax))  # (S,)
    off = np.arange(-kmax, kmax + 1)
    rows = y[:, None] + off[None, :] * step[:, None]  # (S, 2K+1)
    inside = (rows >= 0) & (rows < h)
    a = xb[:, :3]
    b = xb[:, 1:]
    e = np.minimum(1, (b - a - 1) // 2)
    mw = np.maximum(1, width // 12)
    cols = np.empty((seeds.size, 11), dtype=xb.dtype)
    cols[:, 0] = np.maximum(xb[:, 0] - (mw + 1) // 2, 0)
    cols[:, 1:10:3] = a + e
    cols[:, 2:10:3] = (a + b) // 2
    cols[:, 3:10:3] = b - 1 - e
    cols[:, 10] = np.minimum(xb[:, 3] + mw // 2, w - 1)
    v = np.take(image, (np.clip(rows, 0, h - 1) * w)[:, :, None] + cols[:, None, :])  # (S, 2K+1, 11), flat index
    pos = tri.positive[seeds]
    t = thr[seeds][:, None, None]
    light = v >= t
    pattern = np.where(pos[:, None], _PATTERN[None, :], ~_PATTERN[None, :])
    miss = light != pattern[:, None, :]
    # the margin pixels may be blurred grey, but not clearly of the bars' shade
    tol = (0.25 * span[seeds])[:, None]
    marg = v[:, :, [0, 10]].astype(np.float32)
    wrong = np.where(pos[:, None, None], marg < t - tol[:, :, None], marg > t + tol[:, :, None])
    bad = miss[:, :, 1:10].any(axis=2) | wrong.any(axis=2) | ~inside  # (S, 2K+1)
    # a single failing sampled row between good ones does not break a stack where rows are
    # sampled no further apart than max_row_gap
    iso = bad.copy()
    iso[:, 1:-1] &= ~bad[:, :-2] & ~bad[:, 2:]
    iso[:, [0, -1]] = False
    bad &= ~(iso & (step <= p.max_row_gap + 1)[:, None])
    # sampled rows of the connected run through y: up to the first failing one either way
    upb = bad[:, kmax::-1]
    dnb = bad[:, kmax:]
    n_up = np.where(upb.any(axis=1), upb.argmax(axis=1), kmax + 1)
    n_dn = np.where(dnb.any(axis=1), dnb.argmax(axis=1), kmax + 1)
    # n_up + n_dn - 1 good samples in a row: the run spans about that many times step rows
    return (n_up + n_dn - 1) * step >= need - 1, y - n_up * step, y + n_dn * step


#: shades (True = light) of the column test's pixels for a positive target
_PATTERN = np.array([True, False, False, False, True, True, True, False, False, False, True])


def _run_through(idx: np.ndarray, at: int, step: int):
    """The connected run of sorted indices ``idx`` through ``at`` (or within ``step`` of
    it), where consecutive members differ by at most ``step``; ``(first, last)`` or None.
    (A plain loop: ``idx`` holds a few dozen rows, less than numpy's call overhead.)"""
    v = idx.tolist()
    n = len(v)
    if n == 0:
        return None
    j = int(np.searchsorted(idx, at))
    if j < n and v[j] - at <= step:
        pass
    elif j > 0 and at - v[j - 1] <= step:
        j -= 1
    else:
        return None
    lo = j
    while lo > 0 and v[lo] - v[lo - 1] <= step:
        lo -= 1
    hi = j
    while hi < n - 1 and v[hi + 1] - v[hi] <= step:
        hi += 1
    return v[lo], v[hi]


def _fine_scan(image: np.ndarray, y: int, xb: list, positive: bool, thr: float, p: DetectorParams,
               span: tuple[int, int], stats: DetectionStats) -> Stack | None:
    """Fine search (§4.4.1) around the coarse hit at row ``y`` with run boundaries ``xb`` (4,),
    over the rows ``span`` (exclusive bounds, from :func:`_tall_enough`).

    Every line of a region of interest around the hit is thresholded at ``thr``
    (midway between the hit's dark and bright levels, §4.4.2); on each line the
    two transitions either side of the hit's gap centre give that line's bar,
    gap, bar and margin runs, which must pass the §4.5.1 test and stay within
    half a bar of the hit's boundaries (the bars' vertical edges are vertical
    in the image of a level camera). The connected run of matching lines
    through the hit (at most ``max_row_gap`` lines missing in a row) is the stack.
    """
    h, w = image.shape
    width = xb[3] - xb[0]
    m = width / 3.0
    pad = int(m) + 3
    c0 = max(0, xb[0] - pad)
    c1 = min(w, xb[3] + pad)
    r0 = max(0, span[0] - 1)
    r1 = min(h, span[1] + 1)
    for _ in range(8):  # grow the region while the stack reaches its top or bottom line
        roi = image[r0:r1, c0:c1]
        nrow, ncol = roi.shape
        stats.rows_scanned += nrow
        bar = (roi < thr) if positive else (roi >= thr)
        xg = (xb[1] + xb[2]) // 2 - c0
        # run-length code of the whole region at once: run starts (row * ncol + column), a
        # sentinel start at the end of each row; the gap run is the one holding column xg
        flat = bar.ravel()
        chg = np.empty(flat.size, bool)
        chg[0] = True
        np.not_equal(flat[1:], flat[:-1], out=chg[1:])
        chg[::ncol] = True
        starts = np.flatnonzero(chg)
        ends = np.arange(1, nrow + 1) * ncol  # row ends, as run starts of the next row
        key = np.concatenate([starts, ends])
        key.sort()
        key = np.concatenate([np.full(3, -ncol), key, np.full(3, (nrow + 2) * ncol)])
        rowb = np.arange(nrow) * ncol
        j = np.searchsorted(key, rowb + xg, side="right")  # first start right of xg
        # starts of the gap (l_1), bar 1 (l_2), left margin (l_3); ends of gap, bar 2, right margin
        l_1, l_2, l_3 = key[j - 1] - rowb, key[j - 2] - rowb, np.maximum(key[j - 3] - rowb, 0)
        r_1, r_2, r_3 = key[j] - rowb, key[j + 1] - rowb, np.minimum(key[j + 2] - rowb, ncol)
        b1 = l_1 - l_2
        gp = r_1 - l_1
        b2 = r_2 - r_1
        ok = ~bar[:, xg] & (l_2 >= 0) & (r_2 <= ncol) & (np.minimum(np.minimum(b1, gp), b2) >= p.min_bar_px)
        ok &= near_equal(b1, gp, b2, p) & (3.0 * np.minimum(l_2 - l_3, r_3 - r_2) >= p.min_margin_ratio * (b1 + gp + b2))
        tol = max(2.0, 0.5 * m)
        ok &= (np.abs(l_2 + (c0 - xb[0])) <= tol) & (np.abs(r_2 + (c0 - xb[3])) <= tol)
        ok &= (np.abs(l_1 + (c0 - xb[1])) <= tol) & (np.abs(r_1 + (c0 - xb[2])) <= tol)
        good = np.flatnonzero(ok)
        run = _run_through(good, y - r0, 1 + int(p.max_row_gap))
        if run is None:
            stats.reject("fine_scan")
            return None
        sel = good[(good >= run[0]) & (good <= run[1])]
        grow_up = sel[0] == 0 and r0 > 0
        grow_dn = sel[-1] == nrow - 1 and r1 < h
        if not (grow_up or grow_dn):
            break
        extra = max(2 * (sel[-1] - sel[0] + 1), 8)
        if grow_up:
            r0 = max(0, r0 - extra)
        if grow_dn:
            r1 = min(h, r1 + extra)
    x = np.stack([l_2[sel], l_1[sel], r_1[sel], r_2[sel]], axis=1) + c0
    xs = np.sort(x, axis=0)
    mid = sel.size // 2
    med = xs[mid].astype(float) if sel.size % 2 else 0.5 * (xs[mid - 1] + xs[mid])
    return Stack(rows=sel + r0, x=x, positive=positive, median_x=med)


def _rough_ends(image: np.ndarray, r0: int, r1: int, nr: int, col: int, thr: float, positive: bool) -> tuple[int, int]:
    """First and last row of the bar crossing rows ``r0..r1`` at column ``col``: walk
    up and down from the stack while the pixel keeps the bar's shade."""
    h = image.shape[0]
    up = image[max(0, r0 - nr):r0 + 1, col][::-1]
    dn = image[r1:min(h, r1 + nr + 1), col]
    if positive:
        nu = np.flatnonzero(up >= thr)
        nd = np.flatnonzero(dn >= thr)
    else:
        nu = np.flatnonzero(up < thr)
        nd = np.flatnonzero(dn < thr)
    top = r0 - (int(nu[0]) - 1 if nu.size else up.size - 1)
    bot = r1 + (int(nd[0]) - 1 if nd.size else dn.size - 1)
    return top, bot


def verify_stack(image: np.ndarray, camera: Camera, target: TargetSpec, st: Stack, p: DetectorParams,
                 stats: DetectionStats) -> Stack | None:
    """Pattern verification (§4.5.2) on the grey image; returns the stack with its
    grey levels and rough bar ends filled in, or None (the reason is counted in ``stats``).

    (1) minimum height (``min_rows``) and aspect ratio; (2) uniform grey within
    each segment (spread of non-boundary pixels, ``3.3 sd`` as a robust range,
    at most ``uniformity``; boundary = up to 2 px at each end, the thesis's
    5-pixel edge transition) and contrast between adjacent segments; (3)
    connectivity is built into the stack. Also, with ``check_margins``: the
    blank margin above and below each bar.
    """
    import cv2

    h, w = image.shape
    nr = st.n_rows
    if nr < p.min_rows:
        stats.reject("min_rows")
        return None
    xb = st.bounds
    width = xb[3] - xb[0]
    ratio = target.active_height / target.active_width * camera.fy / camera.fx
    lo = ratio * (1.0 - p.aspect_tolerance)
    hi = ratio / math.cos(p.max_alpha) * (1.0 + p.aspect_tolerance)
    if not lo <= nr / width <= hi:
        stats.reject("aspect_ratio")
        return None
    r0, r1 = int(st.rows[0]), int(st.rows[-1])
    e = max(1, nr // 8)  # skip rows near the bar ends (blur, slanted tops)
    ra, rb = r0 + e, r1 + 1 - e
    if rb - ra < 2:
        stats.reject("min_rows")
        return None
    xi = [int(v) for v in np.rint(xb)]
    means, spreads = [], []
    for s in range(3):
        a, b = xi[s], xi[s + 1]
        mm = min(2, (b - a - 1) // 2)
        mu, sd = cv2.meanStdDev(image[ra:rb, a + mm:b - mm])
        means.append(float(mu[0, 0]))
        spreads.append(3.3 * float(sd[0, 0]))
    if max(spreads) > p.uniformity:
        stats.reject("uniformity")
        return None
    if st.positive:
        dark, bright = 0.5 * (means[0] + means[2]), means[1]
        contrasts = (means[1] - means[0], means[1] - means[2])
    else:
        dark, bright = means[1], 0.5 * (means[0] + means[2])
        contrasts = (means[0] - means[1], means[2] - means[1])
    need = min(p.min_contrast, p.min_contrast_ratio * bright)
    if min(contrasts) < need or min(contrasts) <= 0:
        stats.reject("contrast")
        return None
    thr = 0.5 * (dark + bright)
    ends = []
    for k in range(2):
        col = min(max((xi[2 * k] + xi[2 * k + 1]) // 2, 0), w - 1)
        ends.append(_rough_ends(image, r0, r1, nr, col, thr, st.positive))
    # the stack ends where the shorter bar ends (a margin strip next to a bar, seen as a
    # bar of the other polarity, runs on past both ends of the stack)
    slack = 2 + 0.05 * nr
    if min(r0 - ends[0][0], r0 - ends[1][0]) > slack or min(ends[0][1] - r1, ends[1][1] - r1) > slack:
        stats.reject("bar_ends")
        return None
    # bar heights h1, h2 differ at most as the ranges of the bar centres do (|alpha| <= max_alpha):
    # |h1 - h2| / h <= 2 b sin(max_alpha) / Z with Z = fy H / h (eq 4.3), plus 2 rows of slack
    hs = [b - t + 1 for t, b in ends]
    hm = 0.5 * (hs[0] + hs[1])
    if abs(hs[0] - hs[1]) > 2.0 * target.bar_width / target.bar_height * math.sin(p.max_alpha) * hm * hm \
            / camera.fy + 2.0 + 0.03 * hm:
        stats.reject("bar_heights")
        return None
    if p.check_margins:
        # blank margin above and below each bar (thesis §3.4: s = H/4 tall)
        for k in range(2):
            t, b = ends[k]
            hb = b - t + 1
            ka = max(2, int(round(0.12 * hb)))
            kb = max(ka, int(round(0.17 * hb)))
            if t - kb < 0 or b + kb >= h:
                stats.reject("out_of_view")
                return None
            a, bb = xi[2 * k], xi[2 * k + 1]
            for band in (image[t - kb:t - ka + 1, a:bb], image[b + ka:b + kb + 1, a:bb]):
                frac_bg = float(np.count_nonzero(band >= thr) if st.positive else np.count_nonzero(band < thr))
                if frac_bg < 0.75 * band.size:
                    stats.reject("margins")
                    return None
    return Stack(st.rows, st.x, st.positive, dark, bright, tuple(ends), xb)
