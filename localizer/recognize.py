"""Search (coarse + fine, §4.4.1), grouping and verification (§4.5.2) of candidates.

A candidate target is a *stack*: consecutive image rows each holding a
matching bar-gap-bar triple. The coarse scan thresholds, run-length codes and
searches every ``N``-th line in one batch (:mod:`localizer.scan`); each
triple's grey levels on its line are then checked for all triples at once
(contrast between the runs, uniform runs, light margins: the cheap part of
§4.5.2), so that only plausible seeds reach the fine search. The fine search
of the thesis walks up and down line by line from a coarse hit until no line
matches; here the lines that walk could visit are thresholded as one small
region of interest at the seed's own midway level, and on each line the three
runs around the seed's gap are found from the cumulative count of
transitions -- the same rows and runs, without a Python loop per line.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.camera import Camera
from localizer.params import DetectionStats, DetectorParams
from localizer.scan import near_equal, scan_lines, segment_levels
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
        return np.median(self.x, axis=0)


def _max_ratio(camera: Camera, target: TargetSpec, p: DetectorParams) -> float:
    """Largest plausible image height / width ratio of a target's active area."""
    ratio = target.active_height / target.active_width * camera.fy / camera.fx
    return ratio / math.cos(p.max_alpha) * (1.0 + p.aspect_tolerance)


def find_stacks(image: np.ndarray, camera: Camera, target: TargetSpec, p: DetectorParams,
                stats: DetectionStats) -> list[Stack]:
    """Coarse scan every ``coarse_step``-th row, check the hits' grey levels, fine-scan
    around each plausible new hit, and return the connected stacks (not yet verified)."""
    h, w = image.shape
    n = int(p.coarse_step)
    coarse_rows = np.arange(0, h, n)
    tri, lines, nruns = scan_lines(image, coarse_rows, p, int(p.threshold_window))
    stats.rows_scanned += coarse_rows.size
    stats.runs += nruns
    if len(tri) == 0:
        return []
    # grey levels of every triple on its own line (§4.5.2 (2), one line only: lenient)
    mean, std, marg, pmean = segment_levels(lines, tri, p)
    pos = tri.positive
    outer = 0.5 * (mean[:, 0] + mean[:, 2])
    dark = np.where(pos, outer, mean[:, 1])
    bright = np.where(pos, mean[:, 1], outer)
    sgn = np.where(pos, 1.0, -1.0)
    c = np.minimum(mean[:, 1] - mean[:, 0], mean[:, 1] - mean[:, 2]) * sgn
    need = np.minimum(p.min_contrast, p.min_contrast_ratio * bright)
    ok = (c >= need) & (c > 0) & (3.3 * std.max(axis=1) <= 1.5 * p.uniformity)
    # the margins next to the outer edges have the gap's shade
    mfrac = (marg - dark[:, None]) / np.maximum(bright - dark, 1.0)[:, None]
    ok &= np.where(pos, mfrac.min(axis=1) >= 0.35, mfrac.max(axis=1) <= 0.65)
    if p.reject_periodic:
        # a flagged run beyond a margin that has the bars' shade: five equal runs, a grating
        pfrac = (pmean - dark[:, None]) / np.maximum(bright - dark, 1.0)[:, None]
        with np.errstate(invalid="ignore"):
            barlike = np.where(pos[:, None], pfrac < 0.3, pfrac > 0.7) & ~np.isnan(pmean)
        ok &= ~barlike.any(axis=1)
    seeds = np.flatnonzero(ok)
    if seeds.size:
        lo_ratio = target.active_height / target.active_width * camera.fy / camera.fx * (1.0 - p.aspect_tolerance)
        seeds = seeds[_tall_enough(image, tri, seeds, dark, bright, p, lo_ratio)]
    stats.seeds += int(seeds.size)
    if seeds.size == 0:
        return []
    max_ratio = _max_ratio(camera, target, p)
    thr_all = 0.5 * (dark + bright)
    stacks: list[Stack] = []
    taken: list[tuple[int, int, int, int, bool]] = []  # (row0, row1, x0, x1, positive) of stacks found
    ys = tri.y.tolist()
    xbs = tri.x.tolist()
    g = 2 + int(p.max_row_gap)  # a hit this near a stack's end belongs to it (blurred end lines)
    for k in seeds.tolist():
        y = ys[k]
        xb = xbs[k]
        pk = bool(pos[k])
        if any(r0 - g <= y <= r1 + g and xb[1] < c1 and xb[2] > c0 and pp == pk for r0, r1, c0, c1, pp in taken):
            continue
        if len(stacks) >= p.max_candidates:
            break
        st = _fine_scan(image, y, xb, pk, float(thr_all[k]), p, max_ratio, stats)
        if st is None:
            continue
        stacks.append(st)
        stats.candidates += 1
        taken.append((int(st.rows[0]), int(st.rows[-1]), int(st.x[:, 0].min()), int(st.x[:, 3].max()), pk))
    return stacks


def _tall_enough(image: np.ndarray, tri, seeds: np.ndarray, dark: np.ndarray, bright: np.ndarray,
                 p: DetectorParams, lo_ratio: float) -> np.ndarray:
    """Minimum-height and aspect tests (§4.5.2 (1)) in advance, for all seeds at once.

    A stack of at least ``M`` rows through row ``y`` contains row ``y - k`` or row
    ``y + k``, ``k = (M - 1) // 2``; ``M`` is ``min_rows`` or, if more, the least
    height the aspect test allows for the seed's width (``lo_ratio`` times it). On those two rows the
    three segments at the seed's columns must have the seed's shades
    (normalised mean of the non-boundary pixels below 0.35 for a dark segment,
    above 0.65 for a light one). Returns a boolean mask over ``seeds``.
    """
    h, w = image.shape
    y = tri.y[seeds]
    width = tri.x[seeds, 3] - tri.x[seeds, 0]
    k = np.maximum(1, (np.maximum(int(p.min_rows), np.floor(lo_ratio * width).astype(int)) - 1) // 2)
    rows = np.concatenate([np.clip(y - k, 0, h - 1), np.clip(y + k, 0, h - 1)])
    v = image[rows].astype(np.int32)
    cs = np.zeros((rows.size, w + 1), np.int32)
    np.cumsum(v, axis=1, out=cs[:, 1:])
    xb = np.concatenate([tri.x[seeds], tri.x[seeds]])
    a = xb[:, :3]
    b = xb[:, 1:]
    mm = np.minimum(2, (b - a - 1) // 2)
    a2, b2 = a + mm, b - mm
    li = np.arange(rows.size)[:, None]
    mean = (cs[li, b2] - cs[li, a2]) / (b2 - a2)
    dk = np.concatenate([dark[seeds], dark[seeds]])[:, None]
    br = np.concatenate([bright[seeds], bright[seeds]])[:, None]
    f = (mean - dk) / np.maximum(br - dk, 1.0)
    pos = np.concatenate([tri.positive[seeds], tri.positive[seeds]])
    barf = np.where(pos, np.maximum(f[:, 0], f[:, 2]), 1.0 - np.minimum(f[:, 0], f[:, 2]))
    gapf = np.where(pos, f[:, 1], 1.0 - f[:, 1])
    good = (barf < 0.35) & (gapf > 0.65)
    n = seeds.size
    return good[:n] | good[n:]


def _fine_scan(image: np.ndarray, y: int, xb: list, positive: bool, thr: float, p: DetectorParams,
               max_ratio: float, stats: DetectionStats) -> Stack | None:
    """Fine search (§4.4.1) around the coarse hit at row ``y`` with run boundaries ``xb`` (4,).

    Every line of a region of interest around the hit is thresholded at ``thr``
    (midway between the hit's dark and bright levels, §4.4.2); on each line the
    two transitions either side of the hit's gap centre give that line's bar,
    gap, bar and margin runs, which must pass the §4.5.1 test and stay within
    half a bar of the hit's boundaries (the bars' vertical edges are vertical
    in the image of a level camera). The connected run of matching lines
    through the hit (at most ``max_row_gap`` lines missing in a row) is the stack.
    """
    h, w = image.shape
    n = int(p.coarse_step)
    width = xb[3] - xb[0]
    m = width / 3.0
    pad = int(m) + 3
    c0 = max(0, xb[0] - pad)
    c1 = min(w, xb[3] + pad)
    reach = int(math.ceil(max_ratio * width)) + 2
    r0 = max(0, y - 2 * n)
    r1 = min(h, y + reach + 1)
    for attempt in range(2):
        roi = image[r0:r1, c0:c1]
        stats.rows_scanned += r1 - r0
        bar = (roi < thr) if positive else (roi >= thr)
        xg = (xb[1] + xb[2]) // 2 - c0
        trans = bar[:, 1:] != bar[:, :-1]  # (R, C-1): a run starts at column j + 1
        cr = np.cumsum(trans[:, xg:], axis=1, dtype=np.int16)
        cl = np.cumsum(trans[:, xg - 1::-1], axis=1, dtype=np.int16) if xg > 0 else np.zeros((roi.shape[0], 1), np.int16)
        # column (ROI) where the k-th transition right / left of the gap centre puts a run start
        r_1 = xg + 1 + (cr < 1).sum(axis=1)
        r_2 = xg + 1 + (cr < 2).sum(axis=1)
        r_3 = xg + 1 + (cr < 3).sum(axis=1)
        l_1 = xg - (cl < 1).sum(axis=1)
        l_2 = xg - (cl < 2).sum(axis=1)
        l_3 = np.maximum(xg - (cl < 3).sum(axis=1), 0)
        r_3 = np.minimum(r_3, roi.shape[1])
        b1 = l_1 - l_2
        gp = r_1 - l_1
        b2 = r_2 - r_1
        s = b1 + gp + b2
        ok = ~bar[:, xg] & (cl[:, -1] >= 2) & (cr[:, -1] >= 2)
        ok &= (np.minimum(np.minimum(b1, gp), b2) >= p.min_bar_px) & near_equal(b1, gp, b2, p)
        ok &= 3.0 * np.minimum(l_2 - l_3, r_3 - r_2) >= p.min_margin_ratio * s
        tol = max(2.0, 0.5 * m)
        ok &= (np.abs(l_2 + c0 - xb[0]) <= tol) & (np.abs(r_2 + c0 - xb[3]) <= tol)
        ok &= (np.abs(l_1 + c0 - xb[1]) <= tol) & (np.abs(r_1 + c0 - xb[2]) <= tol)
        good = np.flatnonzero(ok)
        if good.size == 0:
            return None
        sy = y - r0
        seed = int(np.argmin(np.abs(good - sy)))
        if abs(int(good[seed]) - sy) > 1 + p.max_row_gap:
            return None
        gaps = np.flatnonzero(np.diff(good) > 1 + p.max_row_gap)
        lo = int(gaps[gaps < seed][-1]) + 1 if (gaps < seed).any() else 0
        hib = gaps[gaps >= seed]
        hi = int(hib[0]) if hib.size else good.size - 1
        sel = good[lo:hi + 1]
        if attempt == 0 and sel[0] == 0 and r0 > 0:
            r0 = max(0, y - reach)  # the target reaches higher than two coarse steps: look further up
            continue
        break
    x = np.stack([l_2[sel], l_1[sel], r_1[sel], r_2[sel]], axis=1) + c0
    return Stack(rows=sel + r0, x=x, positive=positive, dark=float("nan"), bright=float("nan"))


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
    return Stack(st.rows, st.x, st.positive, dark, bright, tuple(ends))
