"""The thesis's edges (§4.6.2): the half-pixel rule around the rough edges of a stack.

The 1x2 / 2x1 gradient windows ``|f(x) - f(x+1)|`` (eq 4-20) over a 9-pixel
neighbourhood of each rough edge; the edge is put half way between the two pixels of the
largest gradient (half-pixel rule, max error 0.5 px), averaged over rows.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._kernels.half_pixel import half_pixel_cols, half_pixel_rows
from localizer.camera import Camera
from localizer.edges import EdgeMeasurements, rough_ends, undistort_vertical
from localizer.recognize import Stack


def thesis_edges(image: np.ndarray, camera: Camera, st: Stack, window: int = 9) -> EdgeMeasurements:
    """Half-pixel-rule edges (§4.6.2) of the verified stack ``st`` in ``image`` (H, W) uint8,
    with a ``window``-pixel neighbourhood of each rough edge (thesis: 9).

    The 1x2 / 2x1 gradient windows ``|f(x) - f(x+1)|`` (eq 4-20) over the neighbourhood
    (:mod:`localizer._kernels.half_pixel`); the edge is put half way between the two
    pixels of the largest gradient (max error 0.5 px), averaged over rows. Returns pixel
    coordinates (undistorted when the camera has distortion)."""
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
    tops, bots, cxs, mean_h = [], [], [], []
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
        # the same half-pixel rule on every interior column of the bar, averaged
        # (used only to break ties between h1 and h2 at the centre columns)
        cols = np.arange(int(math.ceil(edges[2 * k] + 1)), int(math.floor(edges[2 * k + 1] - 1)) + 1)
        cols = cols[(cols >= 0) & (cols < w)] if cols.size else one
        mean_h.append(half_pixel_cols(image, cols, rb, hv, wv) - half_pixel_cols(image, cols, rt - 1, hv, wv))
    diff = mean_h[1] - mean_h[0]
    return EdgeMeasurements(edges, sig, np.array(cxs), np.array(tops), np.array(bots),
                            np.full(2, 0.5 / math.sqrt(3.0)), np.full(2, 0.5 / math.sqrt(3.0)),
                            (int(rows[0]), int(rows[-1])), 0 if abs(diff) < 1e-9 else (1 if diff > 0 else -1),
                            (xs, rows, np.zeros(0), np.zeros(0)))
