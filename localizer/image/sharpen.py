"""The sharpened copy of a frame that :func:`localizer.detect_targets` searches a second time.

A strongly blurred target seen at a steep angle has narrow bars, gap and margins (a 75 mm bar
at 4.5 m and 58 deg is about 8 px wide at 512 x 480, its margin 4 px). Under a blur of sd 3 px
the gap's contrast falls below the search's contrast test, a margin no longer crosses the
midway threshold on every row (the rows of the stack break apart) and the bar ends smear: the
row-scanning search (thesis §4.4-4.5) loses the target although its edges can still be
measured. Unsharp masking (the frame plus ``amount`` times its difference from a Gaussian-blurred
copy) gives the narrow runs their contrast back and leaves wide areas as they are, so the search
of the copy finds such targets again; their edges and pose are measured on the frame's own
pixels (an unsharp mask would bias them).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["GAINS", "unsharp", "unsharp_copies"]

#: the copies searched in turn, their gains as multiples of ``sharpen_amount``: the second where the
#: first finds nothing (of 5 steep, blurred targets that gain 1 loses, gain 2 finds 4 and loses one that
#: gain 1 finds; envelope benchmark, blur3 at 512 x 480 and 1280 x 1024)
GAINS = (1.0, 2.0)


def unsharp(image: np.ndarray, sigma: float, amount: float) -> np.ndarray:
    """``image + amount * (image - G_sigma * image)``, rounded and clipped to uint8.

    Args:
        image: ``(H, W)`` uint8 grey frame.
        sigma: sd (px) of the Gaussian (taps to +-3 sd, as OpenCV's ``GaussianBlur`` takes for an
            8-bit image; borders reflected), > 0.
        amount: gain of the detail added back (0: the frame unchanged).
    Returns:
        ``(H, W)`` uint8, C-contiguous.
    """
    return next(unsharp_copies(image, sigma, (amount,)))


def unsharp_copies(image: np.ndarray, sigma: float, amounts: tuple[float, ...]):
    """:func:`unsharp` of ``image`` at each of ``amounts`` in turn (a generator: the Gaussian is
    taken once, on the first copy asked for; each copy made when asked for).

    The Gaussian is applied as two passes of its 1-D kernel (``sepFilter2D``): the same filter
    as ``GaussianBlur``'s, in half its time at sd 3 px (0.37 against 0.77-0.84 ms on a 512 x 480
    frame, one thread: ``GaussianBlur`` keeps 8-bit images bit-exact in fixed point), the result
    within one grey level of it (on 0.5-2 % of the pixels of envelope frames)."""
    import cv2

    kernel = cv2.getGaussianKernel(2 * math.ceil(3.0 * sigma) + 1, sigma)
    blurred = cv2.sepFilter2D(image, -1, kernel, kernel, borderType=cv2.BORDER_REFLECT_101)
    for amount in amounts:
        yield np.ascontiguousarray(cv2.addWeighted(image, 1.0 + amount, blurred, -amount, 0.0))
