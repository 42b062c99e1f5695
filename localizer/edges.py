"""Edge detection around the rough edges of a verified stack (thesis §4.6).

Two detectors share the rough geometry:

* :func:`thesis_edges` -- the thesis's 1x2 / 2x1 gradient windows,
  ``|f(x) - f(x+1)|`` (eq 4-20), over a 9-pixel neighbourhood of each rough
  edge; the edge is put half way between the two pixels of the largest
  gradient (half-pixel rule, max error 0.5 px), averaged over rows (§4.6.2).
* :func:`subpixel_edges` -- the gradient peak located by its centroid inside
  a symmetric window re-centred on the estimate (two passes). For box-filter
  pixels the centroid of the differences of a blurred step is unbiased for
  any symmetric blur; clipping (saturation) and the truncation by nearby
  edges shift all edges towards their dark side by one common amount, which
  the exact pose fit estimates (:mod:`localizer.pose`). On saturated
  (clipped) targets with some blur the edges are then re-measured by a
  clipped, blurred-step model whose blur and levels are shared by all edges
  of the target (:func:`_fit_bar_profile`, :func:`_refine_clipped`).

Both return an :class:`EdgeMeasurements` in undistorted pixel coordinates.
Coordinates follow :mod:`localizer.camera` (pixel centres at integers).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np

from localizer.camera import Camera
from localizer.recognize import Stack
from localizer.recognize import _rough_ends as rough_ends
from localizer.smallmat import solve


@dataclass(frozen=True)
class EdgeMeasurements:
    """Edge positions of one target (pixels, undistorted).

    ``edges_x`` (4,): x of the bar edges, left to right, averaged over rows;
    ``edges_sigma`` (4,): their standard errors. ``top_y``/``bottom_y`` (2,):
    y of the bar tops/bottoms at the bar centre columns ``bar_cx`` (2,);
    ``top_sigma``/``bottom_sigma`` (2,). ``rows`` (first, last) image rows used
    for the vertical edges. :attr:`points` maps names to ``(N, 2)`` edge points for
    drawing.
    """

    edges_x: np.ndarray
    edges_sigma: np.ndarray
    bar_cx: np.ndarray
    top_y: np.ndarray
    bottom_y: np.ndarray
    top_sigma: np.ndarray
    bottom_sigma: np.ndarray
    rows: tuple[int, int]
    height_sign: int = 0  # thesis tie-break: sign of (h2 - h1) averaged over each bar's columns
    #: (x (n, 4), rows (n,), cols (m,), y (m,)): the edge points measured, for ``points``
    _raw: tuple | None = field(default=None, compare=False, repr=False)

    @property
    def bar_heights(self) -> np.ndarray:
        """(h1, h2) pixel heights of the left and right bar at their centres."""
        return self.bottom_y - self.top_y

    @property
    def points(self) -> dict:
        """``{"vertical": (4n, 2), "horizontal": (m, 2)}`` (x, y) edge points measured, for
        drawing."""
        if self._raw is None:
            return {}
        xs, rows, xcol, ys = self._raw
        return {"vertical": np.stack([xs.ravel(), np.repeat(rows, xs.shape[1]).astype(float)], 1),
                "horizontal": np.stack([xcol, ys], 1)}


def _rough_ends(image: np.ndarray, st: Stack, col: int, thr: float) -> tuple[int, int]:
    """First and last row of the bar crossing the stack at column ``col`` (see
    :func:`localizer.recognize._rough_ends`)."""
    return rough_ends(image, int(st.rows[0]), int(st.rows[-1]), st.n_rows, int(col), float(thr), bool(st.positive))


def _undistort_vertical(camera: Camera, xs: np.ndarray, rows: np.ndarray) -> np.ndarray:
    if not camera.has_distortion:
        return xs
    pts = np.stack([xs.ravel(), np.repeat(rows, xs.shape[1]).astype(float)], axis=1)
    return camera.undistort_points(pts)[:, 0].reshape(xs.shape)


@numba.njit(cache=True, nogil=True)
def _half_pixel_rows(image, rows, x, lim, half, window):
    """Half-pixel rule along each row of ``rows`` (n,) around each rough boundary ``x`` (n, 4)
    (first pixel of the next run): the 1x2 gradient ``|f(j) - f(j+1)|`` (eq 4-20) at
    ``j = x - 1 + o``, ``o = -half .. window - half - 1`` with ``|o| <= lim[k]`` (4,); the
    edge is half way between the two pixels of the largest (the first, on ties).
    Returns ``(n, 4)`` x (px)."""
    w = image.shape[1]
    out = np.empty((rows.size, 4))
    for i in range(rows.size):
        r = rows[i]
        for k in range(4):
            best = -2
            bj = 0
            for o in range(-half, window - half):
                j = min(max(x[i, k] - 1 + o, 0), w - 2)
                g = abs(np.int16(image[r, j]) - np.int16(image[r, j + 1])) if abs(o) <= lim[k] else -1
                if g > best:
                    best = g
                    bj = j
            out[i, k] = bj + 0.5
    return out


@numba.njit(cache=True, nogil=True)
def _half_pixel_cols(image, cols, j0, half, window):
    """Half-pixel rule down each column of ``cols`` (m,) around the boundary row ``j0``
    (between rows ``j0`` and ``j0 + 1``): the mean over the columns of the upper row of the
    largest 2x1 gradient within ``window`` rows (NaN if ``m`` is 0)."""
    h = image.shape[0]
    if cols.size == 0:
        return np.nan
    acc = 0.0
    for c in cols:
        best = -1
        bj = 0
        for o in range(-half, window - half):
            j = min(max(j0 + o, 0), h - 2)
            g = abs(np.int16(image[j, c]) - np.int16(image[j + 1, c]))
            if g > best:
                best = g
                bj = j
        acc += bj
    return acc / cols.size


def thesis_edges(image: np.ndarray, camera: Camera, st: Stack, window: int = 9) -> EdgeMeasurements:
    """Half-pixel-rule edges (§4.6.2) of a verified stack."""
    h, w = image.shape
    half = window // 2
    rows = st.rows
    # the neighbourhood stops half way to the next edge (narrow bars: 9 px would reach it)
    runs = np.diff(st.bounds)
    lim = np.maximum(1, np.floor(0.5 * np.minimum(np.r_[runs[0], runs], np.r_[runs, runs[-1]]))).astype(np.int64)
    xs = _half_pixel_rows(image, rows, np.ascontiguousarray(st.x, np.int64), lim, half, int(window))  # (n, 4)
    xs = _undistort_vertical(camera, xs, rows)
    edges = xs.mean(axis=0)
    sig = np.full(4, 0.5 / math.sqrt(3.0))  # half-pixel rule: uniform error of +-0.5 px
    thr = 0.5 * (st.dark + st.bright)
    tops, bots, cxs, mean_h = [], [], [], []
    for k in range(2):
        cx = 0.5 * (edges[2 * k] + edges[2 * k + 1])
        col = int(np.clip(round(cx), 0, w - 1))
        rt, rb = _rough_ends(image, st, col, thr)
        # boundary rows: (rt-1 | rt) and (rb | rb+1)
        one = np.array([col], np.int64)
        yt = _half_pixel_cols(image, one, rt - 1, half, int(window)) + 0.5
        yb = _half_pixel_cols(image, one, rb, half, int(window)) + 0.5
        if camera.has_distortion:
            pts = camera.undistort_points(np.array([[col, yt], [col, yb]], float))
            yt, yb, cx = pts[0, 1], pts[1, 1], pts[:, 0].mean()
        tops.append(yt)
        bots.append(yb)
        cxs.append(cx)
        # the same half-pixel rule on every interior column of the bar, averaged
        # (used only to break ties between h1 and h2 at the centre columns)
        cols = np.arange(int(math.ceil(edges[2 * k] + 1)), int(math.floor(edges[2 * k + 1] - 1)) + 1)
        cols = cols[(cols >= 0) & (cols < w)] if cols.size else one
        mean_h.append(_half_pixel_cols(image, cols, rb, half, int(window))
                      - _half_pixel_cols(image, cols, rt - 1, half, int(window)))
    diff = mean_h[1] - mean_h[0]
    return EdgeMeasurements(edges, sig, np.array(cxs), np.array(tops), np.array(bots),
                            np.full(2, 0.5 / math.sqrt(3.0)), np.full(2, 0.5 / math.sqrt(3.0)),
                            (int(rows[0]), int(rows[-1])), 0 if abs(diff) < 1e-9 else (1 if diff > 0 else -1),
                            (xs, rows, np.zeros(0), np.zeros(0)))


@numba.njit(cache=True, nogil=True)
def _centroid(d, centre, hw, j0):
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


@numba.njit(cache=True, nogil=True)
def _refine(image, fixed, j0, start, hw, sgn, length, vertical, d):
    """Gradient-peak centroid (:func:`_centroid`) of one edge, re-centred once on its own estimate.

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
    c = _centroid(d, start, hw, j0)
    c = min(max(c, start - hw), start + hw)
    c = _centroid(d, c, hw, j0)
    return min(max(c, start - hw - 0.5), start + hw + 0.5)


#: differences per edge profile (px): 12 pixels around each rough edge
_L = 11


@numba.njit(cache=True, nogil=True)
def _vertical_edges(image, rows, bounds, positive, length):
    """:func:`_refine` of the four vertical edges on every row of ``rows`` (n,) -> ``(n, 4)`` x (px).

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
            out[i, k] = _refine(image, rows[i], j0, start, hwk, sgn, length, False, d)
    return out


@numba.njit(cache=True, nogil=True)
def _column_stats(xs):
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


@numba.njit(cache=True, nogil=True)
def _horizontal_edges(image, edges, cxs, ends, positive, length):
    """:func:`_refine` down every interior column of each bar (1 px in from its ``edges`` (4,)),
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
                ys[i] = _refine(image, c, j0, pred, hw, sgn, length, True, d)
                i += 1
    return cols, grp, ys


@numba.njit(cache=True, nogil=True)
def _line_fits(grp, xcol, cxs, ys, sd_fallback):
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


@numba.njit(cache=True, nogil=True)
def _edge_rows(rows):
    """The rows (n,) of a stack's ``rows`` on which the vertical edges are measured: all but
    the first and last eighth (blur, slanted tops), unless fewer than 3 would be left."""
    nr = rows.size
    e = max(1, nr // 8) if nr >= 8 else 0
    return rows[e:nr - e] if nr - 2 * e >= 3 else rows


@numba.njit(cache=True, nogil=True)
def makes_target(e0, e1, e2, e3, h1, h2, width_tolerance, width_slack, min_rows):
    """Whether measured edges ``e0..e3`` and bar heights ``h1``, ``h2`` (px) still make a
    target: three near-equal runs (§4.5.1's tolerances, without the allowance for a common
    edge shift: subpixel edges are far better than the thresholded runs) and two bars at
    least half the minimum height."""
    w0, w1, w2 = e1 - e0, e2 - e1, e3 - e2
    hi = max(w0, w1, w2)
    lo = min(w0, w1, w2)
    return lo > 0 and hi - lo <= width_tolerance * hi + width_slack and min(h1, h2) >= 0.5 * min_rows


def edge_inputs(image: np.ndarray, st: Stack) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What :func:`subpixel_edges` measures a stack on: ``(rows (n,), bounds (4,), ends (2, 2))``,
    the stack's rows but the first and last eighth (blur, slanted tops), its median run
    boundaries and its rough bar ends (top, bottom row per bar; found at the rough bar
    centres for a stack that was not verified)."""
    rows = _edge_rows(st.rows)
    bounds = np.asarray(st.bounds, np.float64)
    ends = st.ends
    if not ends:
        thr = 0.5 * (st.dark + st.bright)
        cx0 = 0.5 * (bounds[:2].sum() - 1.0), 0.5 * (bounds[2:].sum() - 1.0)
        ends = [_rough_ends(image, st, int(np.clip(round(c), 0, image.shape[1] - 1)), thr) for c in cx0]
    return rows, bounds, np.asarray(ends, np.int64)


def subpixel_edges(image: np.ndarray, camera: Camera, st: Stack) -> EdgeMeasurements:
    """Subpixel edges (gradient-peak centroid, :func:`_refine`) of a verified stack.

    For box-filter pixels the centroid of the differences of a blurred step is
    unbiased for any symmetric blur. Clipping (saturation) moves every edge
    towards its dark side, by an amount that the exact pose fit estimates as a
    common ``delta`` (:mod:`localizer.pose`); what is left is a per-edge part that
    depends on the edge's pixel phase (up to about +-0.3 px for sharp saturated
    edges, where the clipped pixels hide where in them the edge lies), which the
    covariance allows for. When the target is clipped and blurred (fitted blur
    sd >= 0.3 px, mean run >= 8 px), the vertical edges are replaced by a joint
    clipped-erf fit of the row-mean profile (:func:`_fit_bar_profile`: four edges,
    one blur sd, one unclipped bright and one dark level) and each top/bottom
    point by a position-only fit with that blur and those levels
    (:func:`_refine_horizontal_clipped`), which removes most of that per-edge part.

    Vertical edges: on every stack row (but the first and last eighth) the
    differences ``f(x+1) - f(x)`` of an ``L = 11``-pixel window around each of the
    four rough edges (:func:`_vertical_edges`, compiled); one centroid per row
    and edge, averaged over rows (eq: ``X = sum
    x_i / n``, §4.6.2). Tops and bottoms: the same on every interior column of
    each bar, in a vertical window around the line through the rough bar ends;
    a straight line fitted per bar and side, evaluated at the bar's centre
    column. Returns pixel coordinates (undistorted when the camera has distortion).
    """
    rows, bounds, ends = edge_inputs(image, st)
    if not camera.has_distortion:
        edges, sd_e, cxs, icpt, sig, xs, xcol, ys = _subpixel(image, rows, bounds, ends, bool(st.positive))
    else:  # the same stages, with the measured points undistorted in between
        xs, shift = _vertical_stage(image, rows, bounds, bool(st.positive))
        xs = _undistort_vertical(camera, xs, rows)
        edges, sd_e, cxs, ccat, grp, ys, sd_fallback = _horizontal_stage(image, xs, shift, ends, bool(st.positive))
        und = camera.undistort_points(np.stack([ccat.astype(float), ys], 1))
        xcol, ys = und[:, 0].copy(), und[:, 1].copy()
        icpt, sig = _line_fits(grp, xcol, cxs, ys, sd_fallback)
    return EdgeMeasurements(edges, sd_e, cxs, icpt[:2], icpt[2:], sig[:2], sig[2:], (int(rows[0]), int(rows[-1])),
                            _raw=(xs, rows, xcol, ys))


@numba.njit(cache=True, nogil=True)
def _vertical_stage(image, rows, bounds, positive):
    """Vertical edges of :func:`subpixel_edges` on ``rows`` (n,): ``(xs (n, 4), shift (7,))``,
    the centroid edges per row and, on a clipped blurred target, the shift (px) of the
    clipped-erf edges of the row-mean profile (:func:`_fit_bar_profile`) from their mean
    followed by that fit's blur sd (px) and unclipped bright and dark levels (all NaN when
    the profile fit is not used)."""
    xs = _vertical_edges(image, rows, bounds, positive, _L)
    mean = np.empty(4)
    for k in range(4):
        mean[k] = xs[:, k].mean()
    clipped, pc = _fit_bar_profile(image, rows, bounds, mean, positive)
    shift = np.full(7, np.nan)
    if clipped:
        for k in range(4):
            shift[k] = pc[k] - mean[k]
        shift[4:] = pc[4:]
    return xs, shift


@numba.njit(cache=True, nogil=True)
def _horizontal_stage(image, xs, shift, ends, positive):
    """Edge positions (4,) and their standard errors from the per-row ``xs`` (n, 4) (plus
    ``shift`` (7,) from :func:`_vertical_stage` on clipped targets), the bar centre columns
    (2,), then the top and bottom points of both bars around their rough ``ends`` (2, 2).

    Returns ``(edges, sd_edges, cxs, cols (m,), group (m,), y (m,), sd_fallback)``."""
    edges, sd_v, sd_fallback = _column_stats(xs)
    clipped = not np.isnan(shift[0])
    if clipped:
        for k in range(4):
            edges[k] += shift[k]
    n = xs.shape[0]
    sd_e = sd_v / math.sqrt(max(n, 1))
    cxs = np.empty(2)
    cxs[0] = 0.5 * (edges[0] + edges[1])
    cxs[1] = 0.5 * (edges[2] + edges[3])
    ccat, grp, ys = _horizontal_edges(image, edges, cxs, ends, positive, _L)
    if clipped:
        hbar = float(min(ends[0, 1] - ends[0, 0] + 1, ends[1, 1] - ends[1, 0] + 1))
        ys = _refine_horizontal_clipped(image, ccat, grp, ys, positive, hbar, 0.25 * hbar, shift[4], shift[5],
                                        shift[6])
    return edges, sd_e, cxs, ccat, grp, ys, sd_fallback


@numba.njit(cache=True, nogil=True)
def _subpixel(image, rows, bounds, ends, positive):
    """:func:`subpixel_edges` for an undistorted camera as one compiled call: the three
    stages (:func:`_vertical_stage`, :func:`_horizontal_stage`, :func:`_line_fits`).
    Returns ``(edges (4,), sd (4,), cxs (2,), icpt (4,), sig (4,), xs (n, 4), cols (m,), y (m,))``."""
    xs, shift = _vertical_stage(image, rows, bounds, positive)
    edges, sd_e, cxs, ccat, grp, ys, sd_fallback = _horizontal_stage(image, xs, shift, ends, positive)
    xcol = ccat.astype(np.float64)
    icpt, sig = _line_fits(grp, xcol, cxs, ys, sd_fallback)
    return edges, sd_e, cxs, icpt, sig, xs, xcol, ys


# --- saturated targets: clipped, blurred-step (erf) edge model ------------------------------

_SQRT2 = math.sqrt(2.0)
_INV_SQRT2PI = 1.0 / math.sqrt(2.0 * math.pi)
#: a profile whose brightest (row-mean) pixel reaches this grey level is taken as clipped
_CLIP = 254.5
#: starts of the joint fit: unclipped bright level (dark + f * (255 - dark)) and edge shift
#: towards the bright side (px)
_B_STARTS = (1.5, 3.0)
_E_STARTS = (0.0, 0.4)
#: smallest fitted blur sd (px) for which the clipped-erf edges replace the centroids
_SIGMA_MIN = 0.3
#: narrowest mean run (px) of a target for the clipped-erf fit
_BAR_MIN = 8.0


@numba.njit(cache=True, nogil=True)
def _phi_cdf(z):
    return 0.5 * (1.0 + math.erf(z / _SQRT2))


@numba.njit(cache=True, nogil=True)
def _gint(z):
    """Integral of the normal cdf up to ``z``: ``z Phi(z) + phi(z)``."""
    return z * _phi_cdf(z) + _INV_SQRT2PI * math.exp(-0.5 * z * z)


@numba.njit(cache=True, nogil=True)
def _kernel(s):
    """Sampled Gaussian blur of sd ``s`` (px) on the pixel grid, taps -3..3, normalised:
    weights ``w`` (7,) and their derivatives ``dw/ds`` (7,)."""
    g = np.empty(7)
    dg = np.empty(7)
    sg = 0.0
    sdg = 0.0
    for k in range(-3, 4):
        g[k + 3] = math.exp(-0.5 * k * k / (s * s))
        dg[k + 3] = g[k + 3] * k * k / (s * s * s)
        sg += g[k + 3]
        sdg += dg[k + 3]
    w = g / sg
    dw = (dg * sg - g * sdg) / (sg * sg)
    return w, dw


@numba.njit(cache=True, nogil=True)
def _step(j, e, w, dw):
    """Fraction ``F`` of pixel ``j`` beyond an edge at ``e`` (box pixels ``[j - 0.5, j + 0.5]``)
    after the blur kernel ``w`` (:func:`_kernel`), and its derivatives ``dF/de``, ``dF/ds``."""
    f = 0.0
    ds = 0.0
    de = 0.0
    for k in range(-3, 4):
        c = min(max(j - k + 0.5 - e, 0.0), 1.0)
        f += w[k + 3] * c
        ds += dw[k + 3] * c
        if abs(j - k - e) < 0.5:
            de -= w[k + 3]
    return f, de, ds


@numba.njit(cache=True, nogil=True)
def _bar_model(prof, j0, idx, p, positive, J, res):
    """Residuals ``res`` (and Jacobian ``J``) of the clipped four-edge model over the pixels
    ``idx`` (m,) of the profile ``prof`` whose first pixel is at ``j0``.

    ``p`` = (e0, e1, e2, e3, sigma, bright, dark): the brightness is
    ``dark + (bright - dark) * b(x)`` with ``b`` the blurred box-pixel fraction of bright
    (gap and margins of a positive target, the bars of a negative one), clipped at 255.
    A pixel observed clipped is not penalised while the model is clipped too.
    Returns the residual sum of squares.
    """
    rss = 0.0
    kw, kdw = _kernel(p[4])
    for t in range(idx.size):
        i = idx[t]
        j = j0 + i
        acc = 0.0
        for c in range(7):
            J[t, c] = 0.0
        dsum = 0.0
        for k in range(4):
            if j - p[k] > 4.5:  # wholly beyond the edge (taps reach 3 px)
                f, de, ds = 1.0, 0.0, 0.0
            elif p[k] - j > 4.5:
                f, de, ds = 0.0, 0.0, 0.0
            else:
                f, de, ds = _step(j, p[k], kw, kdw)
            sg = 1.0 if k % 2 == 0 else -1.0  # F(e0) - F(e1) + F(e2) - F(e3): fraction inside the bars
            acc += sg * f
            J[t, k] = sg * de
            dsum += sg * ds
        if positive:
            b = 1.0 - acc
            for k in range(4):
                J[t, k] = -J[t, k]
            dsum = -dsum
        else:
            b = acc
        amp = p[5] - p[6]
        m = p[6] + amp * b
        for k in range(4):
            J[t, k] *= amp
        J[t, 4] = amp * dsum
        J[t, 5] = b
        J[t, 6] = 1.0 - b
        if m >= 255.0:
            if prof[i] >= _CLIP:
                r = 0.0
                for c in range(7):
                    J[t, c] = 0.0
            else:
                r = 255.0 - prof[i]
                for c in range(7):
                    J[t, c] = 0.0
        else:
            r = m - prof[i]
        res[t] = r
        rss += r * r
    return rss


@numba.njit(cache=True, nogil=True)
def _fit_bar_profile(image, rows, bounds, e_init, positive):
    """Joint clipped-erf fit of the row-mean profile across the four vertical edges.

    Returns ``(ok, p)`` with ``p`` = (e0..e3, sigma, bright, dark); ``ok`` is False when
    the profile is not clipped (the caller keeps the centroid edges) or the fit failed.
    """
    w = image.shape[1]
    r0, r1, r2 = bounds[1] - bounds[0], bounds[2] - bounds[1], bounds[3] - bounds[2]
    bar = (r0 + r1 + r2) / 3.0
    p = np.empty(7)
    if bar < _BAR_MIN:
        return False, p
    out = max(1.0, min(0.25 * bar, 3.0))  # half the (half-bar) margin, at most 3 px
    a = int(math.floor(e_init[0] - out + 0.5))
    bnd = int(math.ceil(e_init[3] + out - 0.5))
    a = max(a, 0)
    bnd = min(bnd, w - 1)
    n = bnd - a + 1
    if n < 12:
        return False, p
    prof = np.zeros(n)
    for r in rows:
        for i in range(n):
            prof[i] += image[r, a + i]
    pmax = 0.0
    pmin = 1e9
    for i in range(n):
        prof[i] /= rows.size
        pmax = max(pmax, prof[i])
        pmin = min(pmin, prof[i])
    if pmax < _CLIP:
        return False, p
    # the pixels within 5 px of an edge (the plateaus further in carry only the levels)
    keep = np.zeros(n, np.bool_)
    for k in range(4):
        for i in range(max(int(e_init[k]) - a - 5, 0), min(int(e_init[k]) - a + 6, n)):
            keep[i] = True
    idx = np.nonzero(keep)[0]
    best = np.empty(7)
    best_cost = np.inf
    for start in range(len(_B_STARTS) * len(_E_STARTS)):
        # edges start from the centroids moved towards their bright side (clipping biases
        # the centroids towards the dark side)
        de = _E_STARTS[start // len(_B_STARTS)]
        for k in range(4):
            out_k = 1.0 if (k % 2 == 0) != positive else -1.0  # bright side of edge k: +x when 1
            p[k] = e_init[k] + out_k * de
        p[4] = 0.5
        p[6] = pmin
        p[5] = pmin + _B_STARTS[start % len(_B_STARTS)] * (255.0 - pmin)
        cost = _lm_bar(prof, a, idx, p, positive, 6)
        if cost < best_cost:
            best_cost = cost
            best[:] = p
    p[:] = best
    _lm_bar(prof, a, idx, p, positive, 30)
    # sharp edges: the clipped pixels hide where in them each edge lies, and the model
    # has nothing to add to the centroids (whose common shift the pose fit takes out)
    if p[4] < _SIGMA_MIN:
        return False, p
    for k in range(4):
        if abs(p[k] - e_init[k]) > 1.5:
            return False, p
    return True, p


@numba.njit(cache=True, nogil=True)
def _lm_bar(prof, a, idx, p, positive, iterations):
    """Levenberg-Marquardt of :func:`_bar_model` from ``p`` (updated in place); returns the cost."""
    n = idx.size
    J = np.empty((n, 7))
    res = np.empty(n)
    lam = 1e-3
    cost = _bar_model(prof, a, idx, p, positive, J, res)
    q = np.empty(7)
    Jq = np.empty((n, 7))
    rq = np.empty(n)
    A = np.empty((7, 7))
    g = np.empty(7)
    for it in range(iterations):
        for a_ in range(7):  # J^T J and J^T res
            for b_ in range(a_, 7):
                acc = 0.0
                for t in range(n):
                    acc += J[t, a_] * J[t, b_]
                A[a_, b_] = acc
                A[b_, a_] = acc
            acc = 0.0
            for t in range(n):
                acc += J[t, a_] * res[t]
            g[a_] = acc
        for c in range(7):
            A[c, c] += lam * A[c, c] + 1e-9
        step = solve(A, g)
        for c in range(7):
            q[c] = p[c] - step[c]
        q[4] = min(max(q[4], 0.05), 3.0)
        q[5] = max(q[5], 255.0)
        cq = _bar_model(prof, a, idx, q, positive, Jq, rq)
        if cq < cost:
            conv = cost - cq < 1e-6 * (cost + 1e-9)
            p[:] = q
            J[:, :] = Jq
            res[:] = rq
            cost = cq
            lam = max(lam * 0.3, 1e-7)
            if conv:
                break
        else:
            lam *= 10.0
            if lam > 1e6:
                break
    return cost


@numba.njit(cache=True, nogil=True)
def _refine_clipped(image, fixed, start, hw_dark, hw_bright, sgn, vertical, s, bright, dark):
    """Position of one edge by a clipped erf fit with shared blur ``s`` and levels
    (Gauss-Newton on the position only), starting from ``start``; ``sgn`` the sign of
    ``f(j+1) - f(j)`` across the edge (dark to bright when positive). The window reaches
    ``hw_dark`` px into the dark side and ``hw_bright`` px into the bright side."""
    n_img = image.shape[0] if vertical else image.shape[1]
    if sgn > 0:
        lo = int(math.floor(start - hw_dark + 0.5))
        hi = int(math.ceil(start + hw_bright - 0.5))
    else:
        lo = int(math.floor(start - hw_bright + 0.5))
        hi = int(math.ceil(start + hw_dark - 0.5))
    lo = max(lo, 0)
    hi = min(hi, n_img - 1)
    e = start
    amp = bright - dark
    kw, kdw = _kernel(s)
    for it in range(6):
        a11 = 0.0
        g1 = 0.0
        for j in range(lo, hi + 1):
            v = np.float64(image[j, fixed]) if vertical else np.float64(image[fixed, j])
            f, de, ds = _step(j, e, kw, kdw)
            b = f if sgn > 0 else 1.0 - f
            dm = amp * (de if sgn > 0 else -de)
            m = dark + amp * b
            if m >= 255.0:  # clipped model: no position information (observed clipped or not)
                continue
            r = m - v
            a11 += dm * dm
            g1 += dm * r
        if a11 <= 1e-9:
            break
        stp = g1 / a11
        stp = min(max(stp, -0.5), 0.5)
        e -= stp
        if abs(stp) < 1e-4:
            break
    if abs(e - start) > 1.75:
        return start
    return e


@numba.njit(cache=True, nogil=True)
def _refine_horizontal_clipped(image, cols, grp, ys, positive, hbar, margin, s, bright, dark):
    """:func:`_refine_clipped` down each column ``cols`` around the centroid estimate ``ys``
    (group ``grp`` = 2 * side + bar); the window's dark side stops at half the margin."""
    out = np.empty(ys.size)
    pol = 1.0 if positive else -1.0
    hw_b = min(max(hbar / 8.0, 1.0), 4.0) + 1.0
    hw_d = hw_b
    if not positive:
        hw_d = min(hw_b, max(1.0, 0.5 * margin))
    for i in range(ys.size):
        side = grp[i] // 2
        sgn = -pol if side == 0 else pol
        out[i] = _refine_clipped(image, cols[i], ys[i], hw_d, hw_b, sgn, True, s, bright, dark)
    return out
