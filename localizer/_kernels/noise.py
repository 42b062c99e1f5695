"""Kernel of the frame's sensor-noise estimate, for the noise-scaled contrast test of the
line thresholding (thesis §4.4.2; :func:`localizer.search.scan.noise_contrast`).
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit

#: grey-level bands (of ``256 / NOISE_BANDS`` levels each, by the mean of a pixel pair) in which
#: the noise is measured apart: shot noise grows with the signal, and the bright paper of a
#: target (its margins, its gap or its bars) is where a flat run is noisiest
NOISE_BANDS = 4
#: least share of the sampled pairs a band must hold for its noise to count: a band that holds
#: little but the pairs straddling horizontal edges (about 2 % of the pairs) is not flat
NOISE_BAND_SHARE = 0.1
#: every this many columns of a line is sampled (a quarter of the pixels: enough pairs for the median of
#: each band, ~6 us on a 512 x 480 frame)
NOISE_STRIDE = 4
#: median of ``|d| / s`` for a Gaussian difference ``d`` of two pixels of noise sd ``s``
#: (``0.6745 sqrt(2)``)
MEDIAN_ABS_DIFF = 0.6744897501960817 * math.sqrt(2.0)


@jit
def frame_noise(image, step):
    """Noise sd (grey levels) of ``image`` (H, W) uint8 measured on the coarse scan lines of
    §4.4.1 (every ``step``-th row; every :data:`NOISE_STRIDE`-th column): the vertical
    difference of each line's pixels to the row below (the bars' edges are vertical, so a
    target adds almost nothing to it), binned by the pair's
    mean level into :data:`NOISE_BANDS` bands; in each band holding at least
    :data:`NOISE_BAND_SHARE` of the pairs, the median of ``|d|`` (interpolated within its
    integer grey level, so that it is not quantised to whole levels) over
    :data:`MEDIAN_ABS_DIFF`; the largest of them (the noisiest well-populated band: the
    bright paper under shot noise). The median makes edges, lettering and other structure in a
    band's pairs count little. 0 on a frame of fewer than 2 rows."""
    h, w = image.shape
    # four histograms, pixel c into the (c % 4)-th: an increment then never waits on the one
    # before it (most pairs fall in a few bins)
    parts = np.zeros((4, NOISE_BANDS * 256), np.int32)
    flat = parts.ravel()
    shift = 9 - int(round(math.log2(NOISE_BANDS)))  # (a + b) >> shift: the band of the pair's mean
    n = 0
    for r in range(0, h - 1, step):
        a = image[r, ::NOISE_STRIDE]
        b = image[r + 1, ::NOISE_STRIDE]
        for c in range(a.size):
            x = np.int32(a[c])
            y = np.int32(b[c])
            flat[(c & 3) * (NOISE_BANDS * 256) + ((x + y) >> shift) * 256 + abs(x - y)] += 1
        n += a.size
    hist = (parts[0] + parts[1] + parts[2] + parts[3]).reshape((NOISE_BANDS, 256))
    sd = 0.0
    for k in range(NOISE_BANDS):
        m = 0
        for v in range(256):
            m += hist[k, v]
        if m < 32 or m < NOISE_BAND_SHARE * n:
            continue
        half = 0.5 * m
        acc = 0
        for v in range(256):
            cnt = hist[k, v]
            if acc + cnt >= half:
                # |d| = v covers [v - 1/2, v + 1/2) of the underlying continuous value ([0, 1/2) for 0)
                lo = max(v - 0.5, 0.0)
                med = lo + (min(v + 0.5, 255.0) - lo) * (half - acc) / cnt
                sd = max(sd, med / MEDIAN_ABS_DIFF)
                break
            acc += cnt
    return sd
