"""Kernels of the subpixel edges (:func:`localizer.measure.subpixel_edges.subpixel_edges`).

The gradient peak of each edge located by its centroid inside a symmetric window
re-centred on the estimate (two passes, :func:`centroid_edge`); the vertical edges on
every row of a stack, the tops and bottoms on every interior column of each bar, then
a straight line per bar and side (:func:`line_fits`). Saturated targets:
:mod:`localizer._kernels.clipped`.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import inline, jit
from localizer._kernels.blur import CLIP
from localizer._kernels.clipped import SIGMA_BLURRED, fit_bar_profile, profile_blur, refine_horizontal_clipped
from localizer._kernels.records import MeasuredEdges, ProfileFit

#: differences per edge profile (px): 12 pixels around each rough edge
PROFILE_LENGTH = 11


@jit
def edge_rows(image, rows, bounds):
    """The rows (n,) of a stack's ``rows`` on which the vertical edges are measured: all but
    the first and last eighth (blur, slanted tops), unless fewer than 3 would be left; on a
    blurred target (:func:`rows_blur` at least
    :data:`~localizer._kernels.clipped.SIGMA_BLURRED`) also the rows within 2.5 blur sd of
    those ends, where the blurred ends of the bars (slanted, unless the target faces the
    camera) move the edges of the row-mean profile, leaving at least a quarter of the rows.
    ``bounds`` (4,): the stack's median run boundaries (columns)."""
    nr = rows.size
    e = max(1, nr // 8) if nr >= 8 else 0
    if nr - 2 * e < 3:
        return rows
    s = rows_blur(image, rows[e:nr - e], bounds)
    t = int(math.ceil(2.5 * s)) if s >= SIGMA_BLURRED else 0
    extra = min(max(t - e, 0), max((nr - 2 * e - max(3, nr // 4)) // 2, 0))
    return rows[e + extra:nr - e - extra]


#: model error (px) of a blurred target's edges per px of blur sd (the profile fit assumes a
#: Gaussian blur shared by all four edges, and the centroids of the tops and bottoms see the
#: bars' blurred corners): added in quadrature to each edge's error from blur
#: :data:`~localizer._kernels.clipped.SIGMA_BLURRED` on
BLUR_EDGE_SIGMA = 0.06


#: :func:`rows_blur` (the contrast between the runs' middles over the steepest step) of three
#: equal runs ``w`` px wide blurred by a Gaussian of sd ``s``: ``s`` times ``[D(0) + D(2w) -
#: 2 D(w)] / [1 - 2 exp(-u^2 / 2) + exp(-2 u^2)]`` (``u = w / s``, ``D(a)`` a run's blurred
#: coverage ``a`` px from its middle), which is ~0.25 w for every u from 1.8 to 3.3 (s from 0.3 w
#: to 0.55 w): a measured blur of at least NARROW_SHARE of the mean run may be up to
#: ``w / NARROW_RUNS`` (the thesis camera's 3 px at 512 x 480 on bars of 7-10 px: measured
#: 1.8-2.6 px)
NARROW_SHARE = 0.22
NARROW_RUNS = 1.8


@jit
def blur_floor(s, bounds, floor):
    """The per-edge error floor (px) of a stack of row-mean blur sd ``s`` (px, :func:`rows_blur`
    on the rows its edges are measured on) and run boundaries ``bounds`` (4,): ``floor``, or on a
    blurred target (``s`` at least :data:`~localizer._kernels.clipped.SIGMA_BLURRED`)
    ``hypot(floor, BLUR_EDGE_SIGMA sd (1 + (2 sd / w)^2))`` with ``w`` the narrowest of its three
    runs (px): where the blur is as wide as a bar, the edges of the bar and of the gap next to it
    are measured from their blurred sum."""
    wm = (bounds[3] - bounds[0]) / 3.0
    if s >= NARROW_SHARE * wm:  # the profile cannot tell the blur: the largest it may be
        s = max(s, wm / NARROW_RUNS)
    if s >= SIGMA_BLURRED:
        w = max(min(bounds[1] - bounds[0], bounds[2] - bounds[1], bounds[3] - bounds[2]), 1.0)
        q = 2.0 * s / w
        return math.hypot(floor, BLUR_EDGE_SIGMA * s * (1.0 + q * q))
    return floor


@jit
def rows_blur(image, rows, bounds):
    """Blur sd (px) of the row-mean profile of ``image`` over ``rows`` (n,) across a stack
    with run boundaries ``bounds`` (4,) (:func:`localizer._kernels.clipped.profile_blur`)."""
    w = image.shape[1]
    a = max(int(bounds[0]) - 4, 0)
    b = min(int(bounds[3]) + 4, w)
    prof = np.zeros(max(b - a, 1))
    for r in rows:
        for i in range(b - a):
            prof[i] += image[r, a + i]
    edges = np.empty(4)
    for k in range(4):
        edges[k] = bounds[k] - 0.5
    return profile_blur(prof, a, edges, True)


@inline
def centroid(d, centre, hw, j0):
    """Centroid of signed differences ``d`` (L,) located at ``j0 + i + 0.5``, weighted by
    a trapezoid window of half-width ``hw`` centred at ``centre`` (all px)."""
    s = 0.0
    sp = 0.0
    for i in range(d.size):
        pos = j0 + i + 0.5
        wgt = min(max(hw + 0.5 - abs(pos - centre), 0.0), 1.0)
        v = d[i] * wgt
        s += v
        sp += v * pos
    if abs(s) < 1e-9:
        s = 1e-9
    return sp / s


@jit
def centroid_edge(image, fixed, j0, start, hw, sgn, length, vertical, d):
    """Gradient-peak centroid (:func:`centroid`) of one edge, re-centred once on its own estimate
    ``start`` (px), with a window of half-width ``hw`` (px).

    The profile is the ``length + 1`` pixels from ``j0`` along row ``fixed`` (or along
    column ``fixed`` when ``vertical``); ``d`` (length,) float32 scratch receives the
    differences ``(f(j+1) - f(j)) * sgn``. Returns the edge position (px), within
    ``hw + 0.5`` of ``start``.
    """
    for i in range(length):
        if vertical:
            d[i] = (np.float32(image[j0 + i + 1, fixed]) - np.float32(image[j0 + i, fixed])) * sgn
        else:
            d[i] = (np.float32(image[fixed, j0 + i + 1]) - np.float32(image[fixed, j0 + i])) * sgn
    c = centroid(d, start, hw, j0)
    c = min(max(c, start - hw), start + hw)
    c = centroid(d, c, hw, j0)
    return min(max(c, start - hw - 0.5), start + hw + 0.5)


@jit
def vertical_edges(image, rows, bounds, positive, length):
    """:func:`centroid_edge` of the four vertical edges on every row of ``rows`` (n,) -> ``(n, 4)`` x (px).

    ``bounds`` (4,) the stack's median run boundaries (first pixel of bar 1, gap, bar 2,
    one past bar 2). The window half-widths are half the neighbouring run (the side
    margins are taken as half a bar), clipped to 1..4 px.
    """
    w = image.shape[1]
    r0, r1, r2 = bounds[1] - bounds[0], bounds[2] - bounds[1], bounds[3] - bounds[2]
    bar = (r0 + r1 + r2) / 3.0
    hw = np.array([min(r0, 0.5 * bar), min(r0, r1), min(r1, r2), min(r2, 0.5 * bar)]) / 2.0
    pol = np.float32(1.0 if positive else -1.0)
    out = np.empty((rows.size, 4))
    d = np.empty(length, np.float32)
    for k in range(4):
        hwk = min(max(hw[k], 1.0), 4.0)
        start = bounds[k] - 0.5  # rough edge: between the last pixel of one run and the first of the next
        j0 = min(max(int(np.rint(start - 0.5)) - length // 2, 0), w - length - 1)
        sgn = -pol if k % 2 == 0 else pol  # sign of f(x+1) - f(x) across the edge
        for i in range(rows.size):
            out[i, k] = centroid_edge(image, rows[i], j0, start, hwk, sgn, length, False, d)
    return out


@jit
def column_stats(xs):
    """Mean ``(4,)`` and sample standard deviation ``(4,)`` of the ``(n, 4)`` edge positions
    (0.5 px if ``n < 2``), and the root mean square of those deviations (px)."""
    n = xs.shape[0]
    mean = np.empty(4)
    sd = np.full(4, 0.5)
    for k in range(4):
        s = 0.0
        for i in range(n):
            s += xs[i, k]
        mean[k] = s / n
        if n > 1:
            ss = 0.0
            for i in range(n):
                ss += (xs[i, k] - mean[k]) ** 2
            sd[k] = math.sqrt(ss / (n - 1))
    return mean, sd, math.sqrt((sd * sd).mean())


@jit
def horizontal_edges(image, edges, cxs, ends, positive, length):
    """:func:`centroid_edge` down every interior column of each bar (1 px in from its ``edges`` (4,)),
    around the straight line through the rough bar ends ``ends`` (2, 2) ((top, bottom) row
    per bar) for the tops, then the bottoms; ``cxs`` (2,) the bar centre columns.

    Returns ``(cols (m,), group (m,), y (m,))``, group = 2 * side + bar (side 0 = top).
    The window half-width is an eighth of the shorter bar, clipped to 1..4 px.
    """
    h, w = image.shape
    hbar = min(ends[0, 1] - ends[0, 0] + 1, ends[1, 1] - ends[1, 0] + 1)
    hw = min(max(math.floor(hbar / 8.0), 1.0), 4.0)
    ca = np.empty(2, np.int64)
    cb = np.empty(2, np.int64)
    for k in range(2):
        a = int(math.ceil(edges[2 * k] + 1.0))
        b = int(math.floor(edges[2 * k + 1] - 1.0))
        if b < a:
            a = b = int(np.rint(cxs[k]))
        ca[k] = max(a, 0)
        cb[k] = min(b, w - 1) + 1
    n0, n1 = max(cb[0] - ca[0], 0), max(cb[1] - ca[1], 0)
    m = 2 * (n0 + n1)
    cols = np.empty(m, np.int64)
    grp = np.empty(m, np.int64)
    ys = np.empty(m)
    d = np.empty(length, np.float32)
    pol = np.float32(1.0 if positive else -1.0)
    dx = max(cxs[1] - cxs[0], 1e-6)
    i = 0
    for side in range(2):
        # rough line of the tops (bottoms): between the last background row and the first bar row
        y0 = ends[0, side] - 0.5 if side == 0 else ends[0, side] + 0.5
        y1 = ends[1, side] - 0.5 if side == 0 else ends[1, side] + 0.5
        slope = (y1 - y0) / dx
        sgn = -pol if side == 0 else pol  # sign of f(y+1) - f(y)
        for k in range(2):
            for c in range(ca[k], cb[k]):
                pred = y0 + slope * (c - cxs[0])
                j0 = min(max(int(np.rint(pred - 0.5)) - length // 2, 0), h - length - 1)
                cols[i] = c
                grp[i] = 2 * side + k
                ys[i] = centroid_edge(image, c, j0, pred, hw, sgn, length, True, d)
                i += 1
    return cols, grp, ys


@jit
def line_fits(grp, xcol, cxs, ys, sd_fallback):
    """Least-squares line ``y = icpt + slope u`` per group ``grp`` (m,) in 0..3 (closed form),
    ``u = xcol - cxs[grp % 2]`` the columns ``xcol`` (m,) relative to their bar's centre
    column ``cxs`` (2,) (px).

    A group with fewer than 3 points or degenerate abscissae gets slope 0 and its mean as
    intercept. Returns ``(icpt (4,), sigma (4,))``: the intercepts and their standard
    errors, from the pooled residual sd of the fitted groups (``sd_fallback`` px when they
    have fewer than 4 degrees of freedom).
    """
    cnt = np.zeros(4)
    su = np.zeros(4)
    sy = np.zeros(4)
    suu = np.zeros(4)
    suy = np.zeros(4)
    u = xcol - cxs[grp % 2]
    for i in range(grp.size):
        g = grp[i]
        cnt[g] += 1.0
        su[g] += u[i]
        sy[g] += ys[i]
        suu[g] += u[i] * u[i]
        suy[g] += u[i] * ys[i]
    icpt = np.empty(4)
    slope = np.zeros(4)
    okf = np.zeros(4, np.bool_)
    for g in range(4):
        det = cnt[g] * suu[g] - su[g] * su[g]
        okf[g] = cnt[g] >= 3 and det > 1e-9
        if okf[g]:
            slope[g] = (cnt[g] * suy[g] - su[g] * sy[g]) / det
        icpt[g] = (sy[g] - slope[g] * su[g]) / max(cnt[g], 1.0)
    rss = 0.0
    dof = 0.0
    for i in range(grp.size):
        g = grp[i]
        if okf[g]:
            r = ys[i] - icpt[g] - slope[g] * u[i]
            rss += r * r
    for g in range(4):
        if okf[g]:
            dof += cnt[g] - 2
    sd_h = math.sqrt(rss / dof) if dof >= 4 else sd_fallback
    sig = np.empty(4)
    for g in range(4):
        sig[g] = sd_h / math.sqrt(max(cnt[g], 1.0))
    return icpt, sig


@jit
def vertical_stage(image, rows, bounds, positive):
    """Vertical edges of :func:`localizer.measure.subpixel_edges.subpixel_edges` on ``rows`` (n,) of
    ``image``, from the stack's median run boundaries ``bounds`` (4,): ``(xs (n, 4), fit)``,
    the centroid edges per row (px) and the
    :class:`~localizer._kernels.records.ProfileFit` of the row-mean profile
    (:func:`localizer._kernels.clipped.fit_bar_profile`): on a clipped blurred target the
    shift (px) of its clipped-erf edges from the centroid means, its blur sd (px) and
    unclipped bright and dark levels (all NaN and ``clipped`` False when the profile fit
    is not used)."""
    xs = vertical_edges(image, rows, bounds, positive, PROFILE_LENGTH)
    mean = np.empty(4)
    for k in range(4):
        mean[k] = xs[:, k].mean()
    clipped, pc = fit_bar_profile(image, rows, bounds, mean, positive)
    shift = np.full(4, np.nan)
    sigma, bright, dark = np.nan, np.nan, np.nan
    if clipped:
        for k in range(4):
            shift[k] = pc[k] - mean[k]
        sigma, bright, dark = pc[4], pc[5], pc[6]
    return xs, ProfileFit(not np.isnan(shift[0]), shift, sigma, bright, dark)


@jit
def horizontal_stage(image, xs, fit, ends, positive):
    """Edge positions (4,) and their standard errors from the per-row ``xs`` (n, 4) (moved by
    ``fit.shift`` on clipped targets, ``fit`` from :func:`vertical_stage`), the bar centre
    columns (2,), then the top and bottom points of both bars around their rough ``ends``
    (2, 2) ((top, bottom) row per bar).

    Returns ``(edges, sd_edges, cxs, cols (m,), group (m,), y (m,), sd_fallback)``."""
    edges, sd_v, sd_fallback = column_stats(xs)
    if fit.clipped:
        for k in range(4):
            edges[k] += fit.shift[k]
    n = xs.shape[0]
    sd_e = sd_v / math.sqrt(max(n, 1))
    cxs = np.empty(2)
    cxs[0] = 0.5 * (edges[0] + edges[1])
    cxs[1] = 0.5 * (edges[2] + edges[3])
    ccat, grp, ys = horizontal_edges(image, edges, cxs, ends, positive, PROFILE_LENGTH)
    if fit.clipped and fit.bright >= CLIP:  # (a fit of a blurred target that is not clipped: the centroids)
        hbar = float(min(ends[0, 1] - ends[0, 0] + 1, ends[1, 1] - ends[1, 0] + 1))
        ys = refine_horizontal_clipped(image, ccat, grp, ys, positive, hbar, 0.25 * hbar, fit)
    return edges, sd_e, cxs, ccat, grp, ys, sd_fallback


@jit
def subpixel(image, rows, bounds, ends, positive):
    """:func:`localizer.measure.subpixel_edges.subpixel_edges` for an undistorted camera as one
    compiled call: the three stages (:func:`vertical_stage`, :func:`horizontal_stage`,
    :func:`line_fits`) on the rows ``rows`` (n,) of ``image``, from the stack's median run
    boundaries ``bounds`` (4,) and rough bar ends ``ends`` (2, 2) int64.

    Returns ``(edges, xs (n, 4), cols (m,), y (m,))``: the
    :class:`~localizer._kernels.records.MeasuredEdges` and the edge points measured."""
    xs, fit = vertical_stage(image, rows, bounds, positive)
    edges, sd_e, cxs, ccat, grp, ys, sd_fallback = horizontal_stage(image, xs, fit, ends, positive)
    xcol = ccat.astype(np.float64)
    icpt, sig = line_fits(grp, xcol, cxs, ys, sd_fallback)
    return MeasuredEdges(edges, sd_e, cxs, icpt[:2], icpt[2:], sig[:2], sig[2:]), xs, xcol, ys
