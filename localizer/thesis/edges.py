"""The thesis's edges (§4.6.2): the half-pixel rule around the rough edges of a stack.

The 1x2 / 2x1 gradient windows ``|f(x) - f(x+1)|`` (eq 4-20) over a 9-pixel
neighbourhood of each rough edge; the edge is put half way between the two pixels of the
largest gradient (half-pixel rule, max error 0.5 px), averaged over rows. The sign of
alpha (which root of eq 4.13, §4.2.2) is read from the bars' heights measured finer than
that (:func:`height_sign`).
"""
from __future__ import annotations

import math

import numpy as np

from localizer._kernels.half_pixel import centroid_cols, half_pixel_cols, half_pixel_rows
from localizer.model.camera import Camera
from localizer.measure.edges import EdgeMeasurements, rough_ends, undistort_vertical
from localizer.search.recognize import Stack


def thesis_edges(image: np.ndarray, camera: Camera, st: Stack, window: int = 9) -> EdgeMeasurements:
    """Half-pixel-rule edges (§4.6.2) of the verified stack ``st`` in ``image`` (H, W) uint8,
    with a ``window``-pixel neighbourhood of each rough edge (thesis: 9).

    The 1x2 / 2x1 gradient windows ``|f(x) - f(x+1)|`` (eq 4-20) over the neighbourhood
    (:mod:`localizer._kernels.half_pixel`); the edge is put half way between the two
    pixels of the largest gradient (max error 0.5 px), averaged over rows. Returns pixel
    coordinates (undistorted when the camera has distortion), with the sign of alpha's
    root (:func:`height_sign`) and the subpixel ``h2 - h1`` it was read from
    (:func:`bar_height_difference`)."""
    h, w = image.shape
    half = window // 2
    rows = st.rows
    # the neighbourhood stops half way to the next edge (narrow bars: 9 px would reach it)
    runs = np.diff(st.bounds)
    lim = np.maximum(1, np.floor(0.5 * np.minimum(np.r_[runs[0], runs], np.r_[runs, runs[-1]]))).astype(np.int64)
    xs = half_pixel_rows(image, rows, np.ascontiguousarray(st.x, np.int64), lim, half, int(window))  # (n, 4)
    xs = undistort_vertical(camera, xs, rows)
    edges = xs.mean(axis=0)
    sig = np.full(4, 0.5 / math.sqrt(3.0))  # half-pixel rule: uniform error of +-0.5 px
    thr = 0.5 * (st.dark + st.bright)
    tops, bots, cxs, bars = [], [], [], []
    for k in range(2):
        cx = 0.5 * (edges[2 * k] + edges[2 * k + 1])
        col = int(np.clip(round(cx), 0, w - 1))
        rt, rb = rough_ends(image, st, col, thr)
        # boundary rows: (rt-1 | rt) and (rb | rb+1); the neighbourhood stops half way to the
        # bar's other end (a window taller than that would find the other end's edge)
        hv, wv = half, int(window)
        if hv > max(1, (rb - rt + 1) // 2):
            hv = max(1, (rb - rt + 1) // 2)
            wv = 2 * hv + 1
        one = np.array([col], np.int64)
        yt = half_pixel_cols(image, one, rt - 1, hv, wv) + 0.5
        yb = half_pixel_cols(image, one, rb, hv, wv) + 0.5
        if camera.has_distortion:
            pts = camera.undistort_points(np.array([[col, yt], [col, yb]], float))
            yt, yb, cx = pts[0, 1], pts[1, 1], pts[:, 0].mean()
        tops.append(yt)
        bots.append(yb)
        cxs.append(cx)
        # the columns whose centres are on the bar (the sign of alpha, below)
        cols = np.arange(int(math.ceil(edges[2 * k])), int(math.floor(edges[2 * k + 1])) + 1)
        cols = cols[(cols >= 0) & (cols < w)]
        bars.append((cols if cols.size else one, rt, rb, hv, wv))
    diff, sd = bar_height_difference(image, camera, bars)
    sign = height_sign(diff, sd, bots[1] - tops[1] - (bots[0] - tops[0]))
    return EdgeMeasurements(edges, sig, np.array(cxs), np.array(tops), np.array(bots),
                            np.full(2, 0.5 / math.sqrt(3.0)), np.full(2, 0.5 / math.sqrt(3.0)),
                            (int(rows[0]), int(rows[-1])), sign,
                            (xs, rows, np.zeros(0), np.zeros(0)), (diff, sd))


def bar_height_difference(image: np.ndarray, camera: Camera, bars) -> tuple[float, float]:
    """``(h2 - h1, sd)`` (px): the right bar's height less the left's, each averaged over the
    bar's columns, and its standard error from the pixel noise.

    ``bars``: per bar ``(cols, rt, rb, half, window)``, the columns whose centres are on it,
    its rough top and bottom rows and the half-pixel neighbourhood. On every column the top
    and bottom are
    the half-pixel rule's pair refined by the centroid of the 2x1 gradients around it
    (:func:`localizer._kernels.half_pixel.centroid_cols`: unbiased for box-filter pixels
    and any symmetric blur, so that a difference of a fraction of a pixel, where the
    half-pixel heights tie, is measured), undistorted; the columns are averaged with the
    inverse of their variances (the columns a vertical edge's blur crosses have less
    contrast, the same centroid and more noise). The pixel noise is measured on the
    bars' dark interiors (the median absolute difference of vertically adjacent pixels),
    at least the 8-bit rounding's ``1/sqrt(12)``. NaN if a bar has no column measured."""
    heights, variances, steps = [], [], []
    for cols, rt, rb, hv, wv in bars:
        hw = max(1, hv - 1)
        top = centroid_cols(image, cols, rt - 1, hv, wv, hw)
        bot = centroid_cols(image, cols, rb, hv, wv, hw)
        yt, yb = top[:, 0], bot[:, 0]
        if camera.has_distortion:
            x = cols.astype(float)
            yt = camera.undistort_points(np.stack([x, yt], 1))[:, 1]
            yb = camera.undistort_points(np.stack([x, yb], 1))[:, 1]
        ok = np.isfinite(yt) & np.isfinite(yb)
        if not ok.any():
            return math.nan, math.nan
        wt = 1.0 / (top[ok, 1] ** 2 + bot[ok, 1] ** 2)  # columns by the inverse of their variance
        heights.append(float(np.sum(wt * (yb[ok] - yt[ok])) / np.sum(wt)))
        variances.append(1.0 / float(np.sum(wt)))
        inner = image[rt + hv:rb - hv + 1, cols].astype(np.float64)
        if inner.shape[0] >= 2:
            steps.append(np.diff(inner, axis=0).ravel())
    noise = 1.0 / math.sqrt(12.0)
    if steps:
        d = np.concatenate(steps)
        noise = max(noise, 1.4826 * float(np.median(np.abs(d - np.median(d)))) / math.sqrt(2.0))
    return heights[1] - heights[0], noise * math.sqrt(variances[0] + variances[1])


def height_sign(diff: float, sd: float, centre_diff: float) -> int:
    """The sign of ``h2 - h1`` that chooses between the roots of eq 4.13 (§4.2.2): +1 if the
    right bar is the taller (right edge nearer, alpha > 0), -1 if the left, 0 if undecided.

    Eq 4.13 (like A.14, whose ``acos`` has the same two branches) gives
    ``alpha = beta' +- phi``: alpha1 (4.14) and alpha2 (4.15), of opposite signs unless
    alpha is within ``0 .. 2 beta'``. §4.2.2 chooses by the relative heights of the bars:
    each bar's height is ``f H / z`` at its own distance (eqs 4.3, 4.11), so the nearer bar
    is the taller whatever beta' (the nearer bar is also the wider, by the square of the
    distance ratio: the bar widths' perspective ratio carries the same sign). The
    difference is a fraction of a pixel where alpha is small or the target far (thesis
    point 17: 8.15 m at -20 deg on the 50 mm lens, 0.4 px; point 9 at 70 deg, 0.7 px),
    where the half-pixel heights of §4.6.2 (max error 1 px each) tie or reverse; a tie
    fell to the rule "turned towards the camera" and took the root of the wrong sign
    (+21.9 deg for point 17). ``diff``: that difference measured to a fraction of a pixel,
    averaged over each bar's columns (:func:`bar_height_difference`); its sign is taken,
    within its noise too, being the finer measurement of the same heights (whether it is
    beyond its noise, :data:`localizer.measure.edges.SIGN_SIGMAS` standard errors ``sd``, is
    :attr:`localizer.measure.edges.EdgeMeasurements.height_sign_sure`: otherwise the estimate is
    ambiguous). Where it was not measured (NaN) or is 0: the sign of ``centre_diff``, the
    half-pixel heights' difference at the bar centres (the thesis's own measurement),
    otherwise 0 (the tie rule of :func:`localizer.thesis.pose.thesis_alpha`)."""
    if math.isfinite(diff) and diff != 0.0:
        return 1 if diff > 0 else -1
    if abs(centre_diff) < 1e-9:
        return 0
    return 1 if centre_diff > 0 else -1
