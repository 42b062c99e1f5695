"""The numba compilation flags, in one place: the localizer's kernels (:data:`jit`, :data:`inline`)
and the simulator's frame kernels (:data:`fast_jit`, :data:`fast_inline`, at the end).

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

:data:`inline` is the same with ``inline="always"``: for the few-line helpers called in
the innermost loops (the edge projection, the blurred step, the pivoting step of the
small solves), numba inserts their body into the caller before compiling it, as if
written there (the arithmetic and its order are unchanged; a call per pixel and a
loop over a matrix size known only at run time would cost several per cent).
"""
from __future__ import annotations

import numba
import numba.extending

__all__ = ["borrowed", "fast_inline", "fast_jit", "inline", "jit"]

#: the decorator of every compiled kernel (module docstring)
jit = numba.njit(cache=True, nogil=True)
#: the decorator of the small helpers inlined into their callers (module docstring)
inline = numba.njit(cache=True, nogil=True, inline="always")

#: the simulator's frame kernels (the raycaster and its sensor, ``agvsim.sensors.render``):
#: as :data:`jit` plus ``fastmath`` (LLVM may reorder and fuse float arithmetic and assume
#: no NaN or infinity) and NumPy's error model (a float division by zero gives inf, no
#: check per division). Those loops run per pixel; the reordering changes results in the
#: last bits between machines or numba versions, never between two runs on one machine, so
#: the same seed still gives the same frame bit for bit. The localizer keeps :data:`jit`.
fast_jit = numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy")
#: :data:`fast_jit` inlined into its callers
fast_inline = numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy", inline="always")


# ------------------------------------------------------------------ borrowed arrays
@numba.extending.intrinsic
def borrowed(typingctx, x):
    """``x`` (an array, or a tuple or named tuple of arrays and scalars) with every array's
    reference to its owner dropped: the same data, shape and strides, no meminfo.

    A numba array carries a pointer to its owner's reference count, which numba increments
    and decrements (atomically: ``lock`` instructions) every time the array is copied into a
    variable: passing a record of arrays to an inlined helper costs two atomic operations per
    array, per call, and in a kernel's innermost loops that is a tenth of its time. A borrowed
    array has no owner to count: those operations become a test for a null pointer.

    The owner must outlive every use of the borrowed arrays: borrow a kernel's arguments (the
    caller holds them for the call), never an array allocated in the kernel, and never return
    one or store it anywhere that outlives the call.
    """
    if not isinstance(x, (numba.types.Array, numba.types.BaseTuple)):
        return None

    def codegen(context, builder, signature, args):
        def strip(ty, val):
            if isinstance(ty, numba.types.Array):
                ary = context.make_array(ty)(context, builder, value=val)
                ary.meminfo = context.get_constant_null(numba.types.MemInfoPointer(ty.dtype))
                ary.parent = context.get_constant_null(numba.types.pyobject)
                return ary._getvalue()
            if isinstance(ty, numba.types.BaseTuple):
                out = val
                for k, member in enumerate(ty):
                    out = builder.insert_value(out, strip(member, builder.extract_value(val, k)), k)
                return out
            return val

        return strip(signature.args[0], args[0])

    return x(x), codegen
