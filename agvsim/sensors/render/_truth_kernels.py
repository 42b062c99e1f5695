"""The compiled part of the frame truth (:mod:`agvsim.sensors.render.truth`): the depth-buffer test.

IEEE double arithmetic in the order written (:data:`localizer._jit.jit`, no ``fastmath``): the
results are those of the NumPy expressions the docstring gives, bit for bit.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit

__all__ = ["occluded_fraction"]


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
