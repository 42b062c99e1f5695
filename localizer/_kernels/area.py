"""Area-averaged levels of a large frame (:func:`localizer.image.pyramid.level_image`): the mean of
each aligned 2 x 2 block, rounded to 8 bits, once (:func:`area_half`) or twice in one pass
(:func:`area_quarter`, a 4 x 4 block).

The values are OpenCV's (``cv2.resize`` with ``INTER_AREA`` by exactly one half, its fast path
for 8 bits): ``(a + b + c + d + 2) >> 2`` per 2 x 2 block; :func:`area_quarter` is two such
halvings, the first one's rounding kept, without writing the intermediate level (a 2448 x 2048
frame to 612 x 512 in ~0.25 ms when the frame is in the cache, against ~0.32 ms for two
``cv2.resize`` calls; both read the frame's 5 MB once, the rest is arithmetic). A frame in
memory rather than in the cache (as a camera's driver leaves it) streams through the hardware's
prefetchers: ~0.67 ms (one core of the 2-vCPU machine of BENCHMARKS.md).

Both read a window of a C-contiguous ``(H, W)`` uint8 image starting at row ``y0``, column
``x0`` (a crop is not copied first) and fill ``out`` ``(h, w)`` uint8: level pixel ``(i, j)``
is the block of image rows ``y0 + k i .. y0 + k i + k - 1`` and columns likewise (``k`` = 2
or 4); the caller guarantees the window lies in the image.
"""
from __future__ import annotations

import numpy as np

from localizer._jit import jit

__all__ = ["area_half", "area_quarter"]


@jit
def area_half(image, y0, x0, out):
    """``out[i, j]`` = the rounded mean of ``image``'s 2 x 2 block at row ``y0 + 2 i``, column
    ``x0 + 2 j`` (module docstring). ``image`` ``(H, W)`` uint8, ``out`` ``(h, w)`` uint8 with
    ``y0 + 2 h <= H``, ``x0 + 2 w <= W``."""
    h, w = out.shape
    two = np.uint16(2)
    for y in range(h):
        r0 = image[y0 + 2 * y, x0:]
        r1 = image[y0 + 2 * y + 1, x0:]
        o = out[y]
        for x in range(w):
            c = 2 * x
            o[x] = np.uint8((np.uint16(r0[c]) + np.uint16(r1[c]) + np.uint16(r0[c + 1]) + np.uint16(r1[c + 1])
                             + two) >> two)


@jit
def area_quarter(image, y0, x0, out):
    """``out[i, j]`` = ``image``'s 4 x 4 block at row ``y0 + 4 i``, column ``x0 + 4 j`` halved twice
    (each 2 x 2 mean rounded as :func:`area_half`'s: the values of two halvings). ``image``
    ``(H, W)`` uint8, ``out`` ``(h, w)`` uint8 with ``y0 + 4 h <= H``, ``x0 + 4 w <= W``.

    A row of the output at a time: the two rows of the first halving (``(2 w,)`` uint16
    buffers, each a loop that vectorises), then their 2 x 2 means."""
    h, w = out.shape
    two = np.uint16(2)
    a = np.empty(2 * w, np.uint16)
    b = np.empty(2 * w, np.uint16)
    for y in range(h):
        r0 = image[y0 + 4 * y, x0:]
        r1 = image[y0 + 4 * y + 1, x0:]
        r2 = image[y0 + 4 * y + 2, x0:]
        r3 = image[y0 + 4 * y + 3, x0:]
        for x in range(2 * w):
            c = 2 * x
            a[x] = (np.uint16(r0[c]) + np.uint16(r1[c]) + np.uint16(r0[c + 1]) + np.uint16(r1[c + 1]) + two) >> two
            b[x] = (np.uint16(r2[c]) + np.uint16(r3[c]) + np.uint16(r2[c + 1]) + np.uint16(r3[c + 1]) + two) >> two
        o = out[y]
        for x in range(w):
            o[x] = np.uint8((a[2 * x] + a[2 * x + 1] + b[2 * x] + b[2 * x + 1] + two) >> two)
