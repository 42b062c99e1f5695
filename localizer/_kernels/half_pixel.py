"""Kernels of the thesis's half-pixel edges (§4.6.2, :func:`localizer.thesis_edges.thesis_edges`).

The 1x2 / 2x1 gradient windows ``|f(x) - f(x+1)|`` (eq 4-20) over a neighbourhood of a
rough edge; the edge is put half way between the two pixels of the largest gradient.
"""
from __future__ import annotations

import numpy as np

from localizer._jit import jit


@jit
def half_pixel_rows(image, rows, x, lim, half, window):
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


@jit
def half_pixel_cols(image, cols, j0, half, window):
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
