"""The JIT flags of the simulator's frame kernels (the raycaster, its sensor and truth), in one place.

All are :data:`localizer._jit.fast_jit`'s (``fastmath``, NumPy's error model, cached, no GIL),
and for a kernel that allocates nothing, without reference counts:

* :data:`kernel`: a kernel called from Python that allocates (``fast_jit`` itself: :func:`bin_solids
  <agvsim.sensors.render._raycast_kernels.bin_solids>`, ``nearest_depth``).
* :data:`frame_kernel`: a kernel called from Python that allocates nothing (the frame, exposure,
  motion blur): compiled without numba's reference counting (``_nrt=False``). Numba counts
  references to an array (atomically) each time one is copied into a variable or an argument,
  and the raycaster hands records of arrays (:class:`~agvsim.sensors.render.ray_records.Scene`,
  ``FrameScratch``) to its helpers per ray, column and span: counted, that was most of a frame.
  Every array such a kernel touches is an argument, held by the caller for the call; allocating
  in one is a compile error ("Only accept returning of array passed into the function").
* :data:`helper`: a function called only from other kernels, likewise, and without the CPython
  and C wrappers numba otherwise builds for every function (the code that unboxes each argument
  from a Python object: for a record of records of arrays, thousands of instructions, and a third
  of the raycaster's cold compile). A helper cannot be called from Python.
* :data:`span_helper`: a :data:`helper` called per column or span with records of arrays:
  ``forceinline`` (LLVM's ``alwaysinline``, applied by LLVM to the compiled function, not numba's
  ``inline="always"``, which types and lowers the body again in every caller: the frame kernel
  took two minutes to compile that way). Called, such a helper would take each record's arrays as
  hundreds of argument words, copied on every call (measured: 2.9 ms a frame instead of 1.9).
  The floor pass and the ray passes, called once per frame, stay :data:`helper`: inlined into the
  column pass, LLVM no longer vectorised the floor's loops (0.8 ms instead of 0.35).

Each is compiled for one signature: callers pass ``np.int64(0)``, not a literal ``0`` (numba
compiles a literal argument as a type of its own), and the truth's depth buffer in one layout.
"""
from __future__ import annotations

import numba

from localizer._jit import fast_jit

__all__ = ["exact_helper", "frame_kernel", "helper", "kernel", "span_helper"]

#: a kernel called from Python that allocates (module docstring)
kernel = fast_jit
#: a kernel called from Python that allocates nothing: compiled without reference counts (module docstring)
frame_kernel = numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy", _nrt=False, no_cfunc_wrapper=True)
#: a function called only from other kernels (module docstring)
helper = numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
                    no_cfunc_wrapper=True)
#: a :data:`helper` called per ray, column or span with records of arrays: inlined by LLVM into its
#: callers (``forceinline``: LLVM's ``alwaysinline``, after numba has compiled it once), so that the
#: records' arrays are not copied into its arguments at every call (module docstring)
span_helper = numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
                         no_cfunc_wrapper=True, forceinline=True)
#: a helper of the truth's kernels, which keep :data:`localizer._jit.jit` (IEEE arithmetic in the
#: order written) and allocate (reference counted)
exact_helper = numba.njit(cache=True, nogil=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)
