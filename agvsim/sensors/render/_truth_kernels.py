"""The compiled parts of the frame truth (:mod:`agvsim.sensors.render.truth`): the image
geometry of the targets in front of the lens (from their projected points) and the
depth-buffer test.

IEEE double arithmetic in the order written (:data:`localizer._jit.jit`, no ``fastmath``): the
results are those of the NumPy expressions the docstring gives, bit for bit.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit

__all__ = ["image_geometry", "occluded_fraction"]


@jit
def occluded_fraction(px, z, depth, supersample, out):
    """Per target, the share of its face points behind something nearer in ``depth``.

    Args:
        px: ``(m, k, 2)`` float64 undistorted pixel x, y of the face points.
        z: ``(m, k)`` float64 their range (m along the optical axis, > 0).
        depth: ``(H * s, W * s)`` depth buffer (m, 0 = nothing) rendered with ``supersample`` s.
        out: ``(m,)`` float64, written: the fractions in [0, 1]; 1 for a target none of whose
            points falls in the buffer.

    A point samples the buffer at ``floor((px + 0.5) s)`` (column, row); it is hidden when the
    buffer there is nothing (0) or nearer than ``z - (0.004 + 0.0005 z)``.
    """
    h, w = depth.shape
    m, k = z.shape
    for t in range(m):
        n_ok = 0
        n_hidden = 0
        for q in range(k):
            col = np.int64(math.floor((px[t, q, 0] + 0.5) * supersample))
            row = np.int64(math.floor((px[t, q, 1] + 0.5) * supersample))
            if 0 <= col < w and 0 <= row < h:
                n_ok += 1
                zq = z[t, q]
                zb = depth[row, col]
                if zb >= 0 and zb < zq - (0.004 + 0.0005 * zq):
                    n_hidden += 1
        out[t] = n_hidden / n_ok if n_ok > 0 else 1.0


@jit
def image_geometry(px, rows, width, height, table, in_view):
    """The image geometry of the targets in front of the lens, from their projected points.

    Args:
        px: ``(m, 16, 2)`` float64 pixel x, y of each target's active-area corners TL, TR, BR, BL
            (points 0-3), printed-face corners (4-7), bar edges' tops (8-11) and bottoms (12-15)
            (:data:`agvsim.sensors.render.truth.IMAGE`).
        rows: ``(m,)`` int64, the targets' rows of ``table`` and ``in_view``.
        width, height: the image size (px).
        table: ``(n, 15)`` float64, written at ``rows``: active corners (0-7, x, y each), bbox of
            the printed face ``x0, y0, x1, y1`` (8-11), narrowest bar (px, 12), shortest bar (rows, 13).
        in_view: ``(n,)`` bool, written at ``rows``: the bbox lies inside the image.

    Minima, maxima, differences and comparisons only: the values of the NumPy expressions in
    :func:`~agvsim.sensors.render.truth.frame_truth`'s history, bit for bit (finite points).
    """
    for i in range(px.shape[0]):
        t = rows[i]
        for q in range(4):
            table[t, 2 * q] = px[i, q, 0]
            table[t, 2 * q + 1] = px[i, q, 1]
        x0 = x1 = px[i, 4, 0]
        y0 = y1 = px[i, 4, 1]
        for q in range(5, 8):
            x, y = px[i, q, 0], px[i, q, 1]
            x0 = min(x0, x)
            x1 = max(x1, x)
            y0 = min(y0, y)
            y1 = max(y1, y)
        table[t, 8] = x0
        table[t, 9] = y0
        table[t, 10] = x1
        table[t, 11] = y1
        in_view[t] = x0 >= -0.5 and y0 >= -0.5 and x1 <= width - 0.5 and y1 <= height - 0.5
        bar = abs(px[i, 9, 0] - px[i, 8, 0])  # bar q between edges 8 + q and 9 + q
        for q in range(9, 11):
            bar = min(bar, abs(px[i, q + 1, 0] - px[i, q, 0]))
        tall = px[i, 12, 1] - px[i, 8, 1]  # edge q: bottom 12 + q - top 8 + q
        for q in range(1, 4):
            tall = min(tall, px[i, 12 + q, 1] - px[i, 8 + q, 1])
        table[t, 12] = bar
        table[t, 13] = tall
