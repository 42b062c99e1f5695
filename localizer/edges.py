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
  the exact pose fit estimates (:mod:`localizer.pose`).

Both return an :class:`EdgeMeasurements` in undistorted pixel coordinates.
Coordinates follow :mod:`localizer.camera` (pixel centres at integers).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from localizer.camera import Camera
from localizer.recognize import Stack
from localizer.recognize import _rough_ends as rough_ends


@dataclass(frozen=True)
class EdgeMeasurements:
    """Edge positions of one target (pixels, undistorted).

    ``edges_x`` (4,): x of the bar edges, left to right, averaged over rows;
    ``edges_sigma`` (4,): their standard errors. ``top_y``/``bottom_y`` (2,):
    y of the bar tops/bottoms at the bar centre columns ``bar_cx`` (2,);
    ``top_sigma``/``bottom_sigma`` (2,). ``rows`` (first, last) image rows used
    for the vertical edges. ``points`` maps names to ``(N, 2)`` edge points for
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
    points: dict = field(default_factory=dict, compare=False, repr=False)
    height_sign: int = 0  # thesis tie-break: sign of (h2 - h1) averaged over each bar's columns

    @property
    def bar_heights(self) -> np.ndarray:
        """(h1, h2) pixel heights of the left and right bar at their centres."""
        return self.bottom_y - self.top_y


def _rough_ends(image: np.ndarray, st: Stack, col: int, thr: float) -> tuple[int, int]:
    """First and last row of the bar crossing the stack at column ``col`` (see
    :func:`localizer.recognize._rough_ends`)."""
    return rough_ends(image, int(st.rows[0]), int(st.rows[-1]), st.n_rows, col, thr, st.positive)


def _undistort_vertical(camera: Camera, xs: np.ndarray, rows: np.ndarray) -> np.ndarray:
    if not camera.has_distortion:
        return xs
    pts = np.stack([xs.ravel(), np.repeat(rows, xs.shape[1]).astype(float)], axis=1)
    return camera.undistort_points(pts)[:, 0].reshape(xs.shape)


def thesis_edges(image: np.ndarray, camera: Camera, st: Stack, window: int = 9) -> EdgeMeasurements:
    """Half-pixel-rule edges (§4.6.2) of a verified stack."""
    img = image.astype(np.int16)
    h, w = image.shape
    half = window // 2
    rows = st.rows
    # 1x2 window positions j (gradient between pixels j and j+1), around boundary j0 = x - 1
    off = np.arange(-half, window - half)
    j = (st.x - 1)[:, :, None] + off[None, None, :]
    j = np.clip(j, 0, w - 2)
    g = np.abs(img[rows[:, None, None], j] - img[rows[:, None, None], j + 1])
    # the neighbourhood stops half way to the next edge (narrow bars: 9 px would reach it)
    runs = np.diff(st.bounds)
    lim = np.maximum(1, np.floor(0.5 * np.minimum(np.r_[runs[0], runs], np.r_[runs, runs[-1]]))).astype(int)
    g = np.where(np.abs(off)[None, None, :] <= lim[None, :, None], g, -1)
    xs = np.take_along_axis(j, g.argmax(axis=2)[:, :, None], axis=2)[:, :, 0] + 0.5  # (n, 4)
    xs = _undistort_vertical(camera, xs, rows)
    edges = xs.mean(axis=0)
    sig = np.full(4, 0.5 / math.sqrt(3.0))  # half-pixel rule: uniform error of +-0.5 px
    thr = 0.5 * (st.dark + st.bright)
    tops, bots, cxs, mean_h = [], [], [], []
    for k in range(2):
        cx = 0.5 * (edges[2 * k] + edges[2 * k + 1])
        col = int(np.clip(round(cx), 0, w - 1))
        rt, rb = _rough_ends(image, st, col, thr)
        ys = []
        for j0 in (rt - 1, rb):  # boundary rows: (rt-1 | rt) and (rb | rb+1)
            jj = np.clip(j0 + np.arange(-half, window - half), 0, h - 2)
            gg = np.abs(img[jj, col] - img[jj + 1, col])
            ys.append(float(jj[int(gg.argmax())]) + 0.5)
        yt, yb = ys
        if camera.has_distortion:
            pts = camera.undistort_points(np.array([[col, yt], [col, yb]], float))
            yt, yb, cx = pts[0, 1], pts[1, 1], pts[:, 0].mean()
        tops.append(yt)
        bots.append(yb)
        cxs.append(cx)
        # the same half-pixel rule on every interior column of the bar, averaged
        # (used only to break ties between h1 and h2 at the centre columns)
        cols = np.arange(int(math.ceil(edges[2 * k] + 1)), int(math.floor(edges[2 * k + 1] - 1)) + 1)
        cols = cols[(cols >= 0) & (cols < w)] if cols.size else np.array([col])
        hs = []
        for j0 in (rt - 1, rb):
            jj = np.clip(j0 + np.arange(-half, window - half), 0, h - 2)
            gg = np.abs(img[jj[:, None], cols[None, :]] - img[jj[:, None] + 1, cols[None, :]])
            hs.append(jj[gg.argmax(axis=0)].mean())
        mean_h.append(hs[1] - hs[0])
    diff = mean_h[1] - mean_h[0]
    return EdgeMeasurements(edges, sig, np.array(cxs), np.array(tops), np.array(bots),
                            np.full(2, 0.5 / math.sqrt(3.0)), np.full(2, 0.5 / math.sqrt(3.0)),
                            (int(rows[0]), int(rows[-1])),
                            {"vertical": np.stack([xs.ravel(), np.repeat(rows, 4)], 1)},
                            0 if abs(diff) < 1e-9 else (1 if diff > 0 else -1))


def _centroid(profiles: np.ndarray, centre: np.ndarray, hw: np.ndarray, j0: np.ndarray) -> np.ndarray:
    """Centroid of signed differences ``profiles`` (..., L) located at ``j0 + i + 0.5``,
    weighted by a trapezoid window of half-width ``hw`` centred at ``centre``."""
    pos = j0[..., None] + np.arange(profiles.shape[-1]) + 0.5
    wgt = np.minimum(np.maximum(hw[..., None] + 0.5 - np.abs(pos - centre[..., None]), 0.0), 1.0)
    d = profiles * wgt
    s = d.sum(axis=-1)
    s = np.where(np.abs(s) < 1e-9, 1e-9, s)
    return (d * pos).sum(axis=-1) / s


def _refine(diff: np.ndarray, j0: np.ndarray, start: np.ndarray, hw: np.ndarray) -> np.ndarray:
    """Gradient-peak centroid (:func:`_centroid`) re-centred once on its own estimate."""
    c = _centroid(diff, start, hw, j0)
    c = np.minimum(np.maximum(c, start - hw), start + hw)
    c = _centroid(diff, c, hw, j0)
    return np.minimum(np.maximum(c, start - hw - 0.5), start + hw + 0.5)


def subpixel_edges(image: np.ndarray, camera: Camera, st: Stack) -> EdgeMeasurements:
    """Subpixel edges (gradient-peak centroid, :func:`_refine`) of a verified stack.

    For box-filter pixels the centroid of the differences of a blurred step is
    unbiased for any symmetric blur. Clipping (saturation) moves every edge
    towards its dark side, by an amount that the exact pose fit estimates as a
    common ``delta`` (:mod:`localizer.pose`); what is left is a per-edge part that
    depends on the edge's pixel phase (up to about +-0.3 px for sharp saturated
    edges, where the clipped pixels hide where in them the edge lies), which the
    covariance allows for.

    Vertical edges: on every stack row (but the first and last eighth) the
    differences ``f(x+1) - f(x)`` of an ``L = 11``-pixel window around each of the
    four rough edges, fetched for all rows and edges with one indexing
    operation; one centroid per row and edge, averaged over rows (eq: ``X = sum
    x_i / n``, §4.6.2). Tops and bottoms: the same on every interior column of
    each bar, in a vertical window around the line through the rough bar ends;
    a straight line fitted per bar and side, evaluated at the bar's centre
    column. Returns pixel coordinates (undistorted when the camera has distortion).
    """
    h, w = image.shape
    nr = st.rows.size
    e = max(1, nr // 8) if nr >= 8 else 0
    rows = st.rows[e:nr - e] if nr - 2 * e >= 3 else st.rows
    bounds = np.asarray(st.bounds, float)
    runs = np.diff(bounds)  # bar, gap, bar widths
    bar = float(runs.mean())
    # symmetric half-windows: half the neighbouring run; the side margins are ~b/2 wide
    hw_edge = np.array([min(runs[0], 0.5 * bar), min(runs[0], runs[1]), min(runs[1], runs[2]),
                        min(runs[2], 0.5 * bar)]) / 2.0
    hw_edge = np.clip(hw_edge, 1.0, 4.0)
    pol = 1.0 if st.positive else -1.0
    sgn = np.array([-pol, pol, -pol, pol], np.float32)  # sign of f(x+1)-f(x) across each edge
    L = 11
    start = bounds - 0.5  # (4,) rough edge: between the last pixel of one run and the first of the next
    j0 = np.clip(np.rint(start - 0.5).astype(int) - L // 2, 0, w - L - 1)  # (4,) first difference position
    cols = (j0[:, None] + np.arange(L + 1)).ravel()
    vals = np.take(image, rows[:, None] * w + cols[None, :]).astype(np.float32).reshape(rows.size, 4, L + 1)
    diff = (vals[..., 1:] - vals[..., :-1]) * sgn[None, :, None]
    n = rows.size
    xs = _refine(diff, np.broadcast_to(j0, (n, 4)), np.broadcast_to(start, (n, 4)),
                 np.broadcast_to(hw_edge, (n, 4)))  # (n, 4)
    xs = _undistort_vertical(camera, xs, rows)
    edges = xs.mean(axis=0)
    sd_v = xs.std(axis=0, ddof=1) if n > 1 else np.full(4, 0.5)
    # tops and bottoms: the top (bottom) line of both bars is one straight image line
    cxs = 0.5 * (edges[0::2] + edges[1::2])
    ends = st.ends
    if not ends:
        thr = 0.5 * (st.dark + st.bright)
        ends = [_rough_ends(image, st, int(np.clip(round(c), 0, w - 1)), thr) for c in cxs]
    hbar = min(b - t + 1 for t, b in ends)
    hw_v = float(np.clip(math.floor(hbar / 8.0), 1.0, 4.0))
    # every interior column of each bar (1 px in from its edges), for the tops then the bottoms
    bar_cols = []
    for k in range(2):
        a = int(math.ceil(edges[2 * k] + 1.0))
        b = int(math.floor(edges[2 * k + 1] - 1.0))
        if b < a:
            a = b = int(round(cxs[k]))
        bar_cols.append(np.arange(max(a, 0), min(b, w - 1) + 1))
    n0, n1 = bar_cols[0].size, bar_cols[1].size
    ccat = np.concatenate(bar_cols + bar_cols)
    grp = np.repeat(np.arange(4), [n0, n1, n0, n1])  # 2 * side + bar; side 0 = top, 1 = bottom
    side = grp >> 1
    rough = np.array([[t - 0.5 for t, _ in ends], [b + 0.5 for _, b in ends]])  # (side, bar)
    slope = (rough[:, 1] - rough[:, 0]) / max(cxs[1] - cxs[0], 1e-6)
    pred = rough[side, 0] + slope[side] * (ccat - cxs[0])
    vsg = np.where(side == 0, -pol, pol).astype(np.float32)  # sign of f(y+1)-f(y)
    j0v = np.clip(np.rint(pred - 0.5).astype(int) - L // 2, 0, h - L - 1)
    cv = np.take(image, (j0v[:, None] + np.arange(L + 1)) * w + ccat[:, None]).astype(np.float32)
    dv = (cv[:, 1:] - cv[:, :-1]) * vsg[:, None]
    ys = _refine(dv, j0v, pred, np.full(pred.shape, hw_v))
    xcol = ccat.astype(float)
    if camera.has_distortion:
        und = camera.undistort_points(np.stack([xcol, ys], 1))
        xcol, ys = und[:, 0], und[:, 1]
    # straight line per (side, bar) group, evaluated at the bar centre column (closed form)
    cxg = cxs[grp % 2]
    u = xcol - cxg
    cnt = np.bincount(grp, minlength=4).astype(float)
    su = np.bincount(grp, u, 4)
    sy = np.bincount(grp, ys, 4)
    suu = np.bincount(grp, u * u, 4)
    suy = np.bincount(grp, u * ys, 4)
    det = cnt * suu - su * su
    okf = (cnt >= 3) & (det > 1e-9)
    safe = np.where(okf, det, 1.0)
    slope_g = np.where(okf, (cnt * suy - su * sy) / safe, 0.0)
    icpt = np.where(okf, (sy - slope_g * su) / np.maximum(cnt, 1.0), sy / np.maximum(cnt, 1.0))
    res = ys - icpt[grp] - slope_g[grp] * u
    rss = np.bincount(grp, res * res, 4)
    dof = float(np.sum(np.where(okf, cnt - 2, 0)))
    if dof >= 4:
        sd_h = math.sqrt(float(np.sum(np.where(okf, rss, 0.0))) / dof)
    else:
        sd_h = float(np.sqrt(np.mean(sd_v ** 2)))
    sig = sd_h / np.sqrt(np.maximum(cnt, 1.0))
    return EdgeMeasurements(edges, sd_v / math.sqrt(max(n, 1)), cxs, icpt[:2].copy(), icpt[2:].copy(),
                            sig[:2].copy(), sig[2:].copy(), (int(rows[0]), int(rows[-1])),
                            {"vertical": np.stack([xs.ravel(), np.repeat(rows, 4).astype(float)], 1),
                             "horizontal": np.stack([xcol, ys], 1)})
