"""The one set of numba compilation flags of the localizer's kernels.

Every compiled kernel of :mod:`localizer` is decorated with :data:`jit`::

    from localizer._jit import jit

    @jit
    def kernel(image, ...):
        ...

The flags, in one place:

* ``nopython`` (what ``numba.njit`` means): no fallback to the Python interpreter;
* ``cache=True``: machine code is written to ``__pycache__`` beside the module on the
  first call in a fresh environment (a few seconds per kernel) and loaded from there
  afterwards (tens of milliseconds for the whole detector);
* ``nogil=True``: the kernels release the GIL, so that detectors on several camera
  threads run in parallel.

Nothing else (``fastmath``, ``parallel``, ``error_model``) is set: the results are those
of IEEE double arithmetic in the order the source is written, and a float division by
zero raises ``ZeroDivisionError`` as in Python.
"""
from __future__ import annotations

import numba

__all__ = ["jit"]

#: the decorator of every compiled kernel (module docstring)
jit = numba.njit(cache=True, nogil=True)
