"""Kernels of the pattern verification (thesis §4.5.2) of one stack, and the rough bar ends.

A *stack* is consecutive image rows each holding a matching bar-gap-bar triple
(:class:`localizer.search.recognize.Stack`); verification checks its height, aspect ratio,
grey levels and margins.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit
from localizer._kernels.records import Reject, Verification


@jit
def verify(image, rows, xb, positive, s):
    """Pattern verification (§4.5.2) of the stack on ``rows`` (n,) with median run boundaries
    ``xb`` (4,): (1) minimum height (``min_rows``) and aspect ratio (rows spanned / width
    within ``aspect_lo .. aspect_hi``); (2) uniform grey within each segment (spread of
    non-boundary pixels about their least-squares plane, ``3.3 sd`` as a robust range, at most
    ``uniformity``, or ``hypot(uniformity, 3.3 noise)`` with the noise measured down the
    segments (:func:`vertical_noise`, at most :data:`NOISE_CONTRAST` of the contrast); boundary = up
    to 2 px at each end, the thesis's 5-pixel edge transition) and contrast between adjacent
    segments (:func:`verify_grey`); (3) connectivity is built into the stack. Also, with
    ``s.check_margins``: the blank margins around the bars and the gap between them.

    Args: ``image`` (H, W) uint8; ``rows`` (n,) int64 image rows of the stack, increasing;
    ``xb`` (4,) float columns; ``positive``: black bars on white; ``s``: the
    :class:`~localizer._kernels.records.SearchSettings` (its record) (``min_rows``, ``aspect_lo``,
    ``aspect_hi``, ``uniformity``, ``min_contrast``, ``min_contrast_ratio``,
    ``height_term``, ``check_margins``).
    Returns a :class:`~localizer._kernels.records.Verification` (``reason`` is
    ``Reject.NONE`` when verified)."""
    r0, r1 = rows[0], rows[rows.size - 1]
    nr = r1 - r0 + 1
    if nr < s.min_rows:
        return Verification(Reject.MIN_ROWS, 0.0, 0.0, 0, 0, 0, 0)
    ratio = nr / (xb[3] - xb[0])
    if not (s.aspect_lo <= ratio <= s.aspect_hi):
        return Verification(Reject.ASPECT_RATIO, 0.0, 0.0, 0, 0, 0, 0)
    e = max(1, nr // 8)  # skip rows near the bar ends (blur, slanted tops)
    ra, rb = r0 + e, r1 + 1 - e
    if rb - ra < 2:
        return Verification(Reject.MIN_ROWS, 0.0, 0.0, 0, 0, 0, 0)
    return verify_grey(image, (r0, r1), (ra, rb), xb, positive, s)


@jit
def verify_grey(image, span, sample, xb, positive, s):
    """The grey-level part of :func:`verify` for the stack on rows ``span = (r0, r1)``
    (first, last) with median run boundaries ``xb`` (4,) (columns), its segments sampled
    on rows ``sample = (ra, rb)`` (``ra:rb``); ``s`` the
    :class:`~localizer._kernels.records.SearchSettings` (its record).

    Uniform segments (``3.3 sd`` of the non-boundary pixels at most ``uniformity``),
    contrast between them, the rough bar ends (:func:`rough_ends`) at each bar's centre
    column near the stack's ends, bar heights differing by at most ``height_term * h^2``
    plus slack (``height_term = 2 (b / H) sin(max_alpha) / fy``), and (``check_margins``)
    the blank margins above and below both bars, the side margins beside them
    (:data:`SIDE_SHARE`) and the gap between them, both over the bars' whole height and into
    the margins above and below (:data:`GAP_SHARE`). Returns a
    :class:`~localizer._kernels.records.Verification`: ``Reject.NONE`` when passed, else
    ``UNIFORMITY``, ``CONTRAST``, ``BAR_ENDS``, ``BAR_HEIGHTS``, ``OUT_OF_VIEW`` or ``MARGINS``.
    """
    r0, r1 = span
    ra, rb = sample
    nr = r1 - r0 + 1
    uniformity, min_contrast, min_contrast_ratio = s.uniformity, s.min_contrast, s.min_contrast_ratio
    height_term, check_margins = s.height_term, s.check_margins
    h, w = image.shape
    xi = np.empty(4, np.int64)
    for k in range(4):
        xi[k] = int(np.rint(xb[k]))
    means = np.empty(3)
    # each segment's pixels but its edges' transitions: 2 px (the thesis's 5-pixel edge), or
    # as far as a blurred edge reaches (edge_reach, beyond SHARP_REACH), leaving at least the
    # segment's middle fifth
    reach = edge_reach(image, ra, rb, xi)
    # ... and on a blurred target the rows as far as its blurred ends reach (the stack starts and
    # ends about where the bars' ends are, blurred: half their contrast), leaving a quarter of them
    rr = max(reach[0], reach[1], reach[2], reach[3])
    if rr > SHARP_REACH:
        extra = min(max(rr - (ra - r0), 0), max((rb - ra - max(3, nr // 4)) // 2, 0))
        ra, rb = ra + extra, rb - extra
    sds = np.empty(3)
    noise = np.empty(3)  # the noise down each segment (a bar is the same down a column)
    for s in range(3):
        a, b = xi[s], xi[s + 1]
        mm = min(2, (b - a - 1) // 2)
        keep = max((b - a) // 5, 1)
        lo = mm if reach[s] <= SHARP_REACH else max(mm, min(reach[s], (b - a - keep) // 2))
        hi = mm if reach[s + 1] <= SHARP_REACH else max(mm, min(reach[s + 1], b - a - keep - lo))
        means[s], sds[s] = mean_sd_planar(image, ra, rb, a + lo, b - hi)
        noise[s] = vertical_noise(image, ra, rb, a + lo, b - hi)
    # the sensor's noise is not texture: the spread allowed grows with the noise measured down
    # each segment (at most a tenth of the contrast between the segments)
    cap = NOISE_CONTRAST * abs(means[1] - 0.5 * (means[0] + means[2]))
    for s in range(3):
        if 3.3 * sds[s] > math.hypot(uniformity, 3.3 * min(noise[s], cap)):
            return Verification(Reject.UNIFORMITY, 0.0, 0.0, 0, 0, 0, 0)
    if positive:
        dark, bright = 0.5 * (means[0] + means[2]), means[1]
        c = min(means[1] - means[0], means[1] - means[2])
    else:
        dark, bright = means[1], 0.5 * (means[0] + means[2])
        c = min(means[0] - means[1], means[2] - means[1])
    need = min(min_contrast, min_contrast_ratio * bright)
    if c < need or c <= 0:
        return Verification(Reject.CONTRAST, dark, bright, 0, 0, 0, 0)
    thr = 0.5 * (dark + bright)
    t0, b0 = rough_ends(image, r0, r1, nr, min(max((xi[0] + xi[1]) // 2, 0), w - 1), thr, positive)
    t1, b1 = rough_ends(image, r0, r1, nr, min(max((xi[2] + xi[3]) // 2, 0), w - 1), thr, positive)
    # the stack ends where the shorter bar ends (a margin strip next to a bar, seen as a
    # bar of the other polarity, runs on past both ends of the stack)
    slack = 2 + 0.05 * nr
    if min(r0 - t0, r0 - t1) > slack or min(b0 - r1, b1 - r1) > slack:
        return Verification(Reject.BAR_ENDS, dark, bright, t0, b0, t1, b1)
    # bar heights h1, h2 differ at most as the ranges of the bar centres do (|alpha| <= max_alpha):
    # |h1 - h2| / h <= 2 b sin(max_alpha) / Z with Z = fy H / h (eq 4.3), plus 2 rows of slack
    h0, h1 = b0 - t0 + 1, b1 - t1 + 1
    hm = 0.5 * (h0 + h1)
    if abs(h0 - h1) > height_term * hm * hm + 2.0 + 0.03 * hm:
        return Verification(Reject.BAR_HEIGHTS, dark, bright, t0, b0, t1, b1)
    if check_margins:
        # blank margin above and below each bar (thesis §3.4: s = H/4 tall)
        for k in range(2):
            t, b = (t0, b0) if k == 0 else (t1, b1)
            hb = b - t + 1
            ka = max(2, int(np.rint(0.12 * hb)))
            kb = max(ka, int(np.rint(0.17 * hb)))
            if t - kb < 0 or b + kb >= h:
                return Verification(Reject.OUT_OF_VIEW, dark, bright, t0, b0, t1, b1)
            a, bb = xi[2 * k], xi[2 * k + 1]
            for ya, yb in ((t - kb, t - ka + 1), (b + ka, b + kb + 1)):
                if count_shade(image, ya, yb, a, bb, thr, positive) < 0.75 * (yb - ya) * max(bb - a, 0):
                    return Verification(Reject.MARGINS, dark, bright, t0, b0, t1, b1)
        # the side margins run the bars' whole height and on into the margins above and below: a
        # letter's stroke turns into a bowl, a foot or a hat (U, L, J) next to it, where the rows
        # of the stack stop short of the bar's end
        mw = max(1, int(np.rint(0.25 * (xi[3] - xi[0]) / 3.0))) + 1
        for k in range(2):
            t, b = (t0, b0) if k == 0 else (t1, b1)
            ka = max(2, int(np.rint(0.12 * (b - t + 1))))
            c0 = xi[0] - mw if k == 0 else xi[3]
            n = b - t + 1 + 2 * ka
            if rows_with_shade(image, t - ka, b + ka + 1, c0, c0 + mw, thr, positive) < SIDE_SHARE * n:
                return Verification(Reject.MARGINS, dark, bright, t0, b0, t1, b1)
        # the gap runs the bars' whole height and on into the margins: a letter's counter (an O's,
        # a 0's) closes before its strokes end
        ka = max(2, int(np.rint(0.12 * min(h0, h1))))
        g0 = (xi[1] + xi[2]) // 2
        gw = max((xi[2] - xi[1]) // 4, 0)
        ya, yb = max(min(t0, t1) - ka, 0), min(max(b0, b1) + ka + 1, h)
        if count_shade(image, ya, yb, g0 - gw, g0 + gw + 1, thr, positive) < GAP_SHARE * (yb - ya) * (2 * gw + 1):
            return Verification(Reject.MARGINS, dark, bright, t0, b0, t1, b1)
    return Verification(Reject.NONE, dark, bright, t0, b0, t1, b1)


@jit
def rough_ends(image, r0, r1, nr, col, thr, positive):
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


#: how far a blurred edge's transition reaches from it, in sd of its blur (Gaussian: 0.6 % of
#: the step is left beyond 2.5 sd)
EDGE_REACH_SD = 2.5
#: the share of the gap's middle columns, over the bars' height and a little into the margins,
#: that must have the gap's shade (``check_margins``)
GAP_SHARE = 0.9
#: the share of the rows of each bar (and a little into the margins above and below) whose side
#: margin, the pixels just outside the bar's outer edge (a quarter of a bar wide, and one more),
#: must hold a pixel of the gap's shade (``check_margins``)
SIDE_SHARE = 0.95
#: the largest reach (px) of an edge taken as sharp (the thesis's 2 px kept): blur sd up to
#: 1.2 px, and a sharp edge that falls mid-pixel (two half steps: about 0.8 px)
SHARP_REACH = 3


@jit
def edge_reach(image, r0, r1, xi):
    """How far (px, int (4,)) the transition of each of the four run boundaries ``xi`` (4,)
    (columns) of a stack reaches into its segments, on rows ``r0:r1``: ``EDGE_REACH_SD``
    times the blur sd of the edge, ``C / (sqrt(2 pi) g)`` for a step of contrast ``C`` (the
    gap's middle third against the bars') whose steepest change between neighbouring
    columns of the row-mean profile within 3 px of it is ``g`` (a Gaussian-blurred step of
    box pixels; a sharp edge gives about 0.4 px: reach 1)."""
    h, w = image.shape
    c0 = max(xi[0] - 4, 0)
    c1 = min(xi[3] + 4, w)
    n = c1 - c0
    out = np.zeros(4, np.int64)
    if n < 3 or r1 <= r0:
        return out
    prof = np.zeros(n)
    for r in range(r0, r1):
        for i in range(n):
            prof[i] += image[r, c0 + i]
    for i in range(n):
        prof[i] /= r1 - r0
    lv = np.empty(3)
    for s in range(3):
        a, b = xi[s] - c0, xi[s + 1] - c0
        t = (b - a) // 3
        lo, hi = a + t, max(b - t, a + t + 1)
        acc = 0.0
        for i in range(lo, hi):
            acc += prof[i]
        lv[s] = acc / (hi - lo)
    contrast = abs(lv[1] - 0.5 * (lv[0] + lv[2]))
    for k in range(4):
        g = 0.0
        for i in range(max(xi[k] - c0 - 4, 0), min(xi[k] - c0 + 3, n - 1)):
            g = max(g, abs(prof[i + 1] - prof[i]))
        if g > 0.0:
            out[k] = int(math.ceil(EDGE_REACH_SD * contrast / (math.sqrt(2.0 * math.pi) * g)))
    return out


#: the largest sensor noise (grey levels sd) :func:`verify_grey`'s uniformity allows for, as a
#: share of the contrast between the segments
NOISE_CONTRAST = 0.1


@jit
def vertical_noise(image, r0, r1, c0, c1):
    """The noise sd (grey levels) of ``image[r0:r1, c0:c1]`` from its vertical neighbour
    differences: ``sqrt(pi) / 2`` times their mean absolute value (a Gaussian noise of sd ``s``
    gives differences of sd ``s sqrt(2)``, mean absolute value ``2 s / sqrt(pi)``)."""
    if r1 - r0 < 2 or c1 <= c0:
        return 0.0
    acc = 0
    for r in range(r0, r1 - 1):
        a = image[r, c0:c1]
        b = image[r + 1, c0:c1]
        for c in range(c1 - c0):
            acc += abs(np.int32(a[c]) - np.int32(b[c]))
    return 0.5 * math.sqrt(math.pi) * acc / ((r1 - r0 - 1) * (c1 - c0))


@jit
def mean_sd_planar(image, r0, r1, c0, c1):
    """Mean (grey levels) of ``image[r0:r1, c0:c1]`` and the (population) standard deviation of
    its pixels about the least-squares plane ``a + b x + c y`` through them: a smooth shading
    across the block (vignetting, a lamp's falloff) is not counted as non-uniform."""
    nr, nc = r1 - r0, c1 - c0
    if nr <= 0 or nc <= 0:
        return 0.0, 0.0
    xm, ym = 0.5 * (nc - 1), 0.5 * (nr - 1)
    s = 0.0
    ss = 0.0
    sx = 0.0
    sy = 0.0
    for r in range(nr):
        seg = image[r0 + r, c0:c1]
        rs = 0.0
        for c in range(nc):
            v = float(seg[c])
            rs += v
            ss += v * v
            sx += (c - xm) * v
        s += rs
        sy += (r - ym) * rs
    n = nr * nc
    mu = s / n
    var = ss / n - mu * mu
    # sum over the block of (x - xm)^2 and (y - ym)^2 (the centred grid's x and y are orthogonal)
    sxx = nr * nc * (nc * nc - 1) / 12.0
    syy = nc * nr * (nr * nr - 1) / 12.0
    if sxx > 0.0:
        var -= sx * sx / sxx / n
    if syy > 0.0:
        var -= sy * sy / syy / n
    return mu, math.sqrt(max(var, 0.0))


@jit
def count_shade(image, r0, r1, c0, c1, thr, light):
    """Pixels of ``image[r0:r1, c0:c1]`` that are ``>= thr`` (``light``) or ``< thr``."""
    n = 0
    for r in range(r0, r1):
        for c in range(c0, c1):
            if (image[r, c] >= thr) == light:
                n += 1
    return n


@jit
def rows_with_shade(image, r0, r1, c0, c1, thr, light):
    """Rows of ``r0:r1`` whose pixels ``c0:c1`` include one that is ``>= thr`` (``light``) or
    ``< thr``; rows and columns outside the image count as without."""
    h, w = image.shape
    a, b = max(c0, 0), min(c1, w)
    n = 0
    for r in range(max(r0, 0), min(r1, h)):
        for c in range(a, b):
            if (image[r, c] >= thr) == light:
                n += 1
                break
    return n
