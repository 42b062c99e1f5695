"""The blurred box-pixel step, the edge model shared by the clipped-edge fits
(:mod:`localizer._kernels.clipped`) and the photometric refinement
(:mod:`localizer._kernels.photometric`).

A pixel ``j`` covers ``[j - 0.5, j + 0.5]`` (:mod:`localizer.camera`); the image of an
ideal step at ``e`` is blurred by a Gaussian of sd ``s`` sampled on the pixel grid
(taps -3..3, normalised).
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import inline, jit

#: a pixel (or row-mean profile pixel) at or above this grey level is taken as clipped
CLIP = 254.5


@jit
def blur_weights(s):
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


@inline
def blurred_step(j, e, w, dw):
    """Fraction ``F`` of pixel ``j`` beyond an edge at ``e`` (box pixels ``[j - 0.5, j + 0.5]``)
    after the blur kernel ``w`` (:func:`blur_weights`), and its derivatives ``dF/de``, ``dF/ds``."""
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


@inline
def edge_fraction(j, e, w, dw):
    """:func:`blurred_step` of pixel ``j`` for an edge at ``e``, short-cut to ``(1, 0, 0)``
    (``(0, 0, 0)``) when the pixel lies wholly beyond (before) the edge: more than 4.5 px
    away, where the taps (3 px) cannot reach."""
    if j - e > 4.5:
        return 1.0, 0.0, 0.0
    if e - j > 4.5:
        return 0.0, 0.0, 0.0
    return blurred_step(j, e, w, dw)
