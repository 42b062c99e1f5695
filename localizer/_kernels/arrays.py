"""Element-wise copies and fills, the kernels' way of assigning arrays to slices.

``dst[:] = src`` (an array into a slice) compiles, in numba, a shape check whose error
message is built at run time: about 1,700 LLVM instructions of string code (concatenation,
``str.join``, integer formatting), linked into every top-level kernel whose call tree has
one such assignment. A kernel loaded from the cache keeps its whole LLVM module in memory
(numba parses it for linking), ~270 bytes per instruction: 0.5 MB per kernel for that
message alone. These loops copy the same values (each element converted to ``dst``'s
dtype, as the slice assignment converts it) and compile to a few dozen instructions; the
caller guarantees the sizes (``src`` holds at least ``dst``'s elements), as it did for the
slice assignment. Assigning a scalar (``dst[:] = 0.0``) has no shape to check and stays.
"""
from __future__ import annotations

from localizer._jit import jit

__all__ = ["copy", "copy_rows", "fill"]


@jit
def copy(src, dst):
    """``dst[:] = src[:dst.size]`` for 1-D arrays (a loop that vectorises)."""
    for i in range(dst.size):
        dst[i] = src[i]


@jit
def copy_rows(src, dst):
    """``dst[:, :] = src[:dst.shape[0], :dst.shape[1]]`` for 2-D arrays, a row at a time (the
    nested loop compiles to ~1,600 instructions, vectorised for every case of its strides)."""
    for i in range(dst.shape[0]):
        copy(src[i], dst[i])


@jit
def fill(dst, v):
    """``dst[:] = v``."""
    for i in range(dst.size):
        dst[i] = v
