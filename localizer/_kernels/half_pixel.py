"""Kernels of the thesis's half-pixel edges (§4.6.2, :func:`localizer.thesis.edges.thesis_edges`).

The 1x2 / 2x1 gradient windows ``|f(x) - f(x+1)|`` (eq 4-20) over a neighbourhood of a
rough edge; the edge is put half way between the two pixels of the largest gradient.
:func:`centroid_cols` refines that pair by the centroid of the gradients around it (the
bar heights of the sign of alpha, §4.2.2).
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


@jit
def centroid_cols(image, cols, j0, half, window, hw):
    """The half-pixel rule down each column of ``cols`` (m,) as :func:`half_pixel_cols`, then
    the centroid of the signed 2x1 gradients ``s (f(j+1) - f(j))`` (``s`` the sign of the
    largest) of the ``2 hw`` pairs centred on that pair (``hw >= 1``).

    For box-filter pixels the centroid of the differences of a blurred step is its
    position (any symmetric blur; a truncated tail pulls it towards the largest pair).
    Returns ``(m, 2)``: the edge y (px, pixel centres at integers; NaN where the
    gradients sum to <= 0) and ``k``, its standard error per grey level of pixel noise:
    the centroid is ``sum_j p_j d_j / S`` with ``p_j`` the pair's offset from it and
    ``S = sum_j d_j``, i.e. ``(p_b f_b+1 - p_a f_a - sum_a<i<=b f_i) / S``, so
    ``k = sqrt(p_a^2 + p_b^2 + 2 hw - 1) / S``."""
    h = image.shape[0]
    out = np.empty((cols.size, 2))
    for i in range(cols.size):
        c = cols[i]
        best = -1
        bj = 0
        for o in range(-half, window - half):
            j = min(max(j0 + o, 0), h - 2)
            g = abs(np.int16(image[j, c]) - np.int16(image[j + 1, c]))
            if g > best:
                best = g
                bj = j
        a = max(bj - hw + 1, 0)
        b = min(bj + hw, h - 2)
        sgn = 1.0 if np.int16(image[bj + 1, c]) >= np.int16(image[bj, c]) else -1.0
        s = 0.0
        m1 = 0.0
        for j in range(a, b + 1):
            d = sgn * (float(image[j + 1, c]) - float(image[j, c]))
            s += d
            m1 += (j + 0.5) * d
        if s <= 0.0:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
            continue
        y = m1 / s
        pa = a + 0.5 - y
        pb = b + 0.5 - y
        out[i, 0] = y
        out[i, 1] = np.sqrt(pa * pa + pb * pb + (b - a)) / s
    return out
