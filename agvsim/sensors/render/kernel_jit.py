"""The JIT flags of the simulator's frame kernels (the raycaster, its sensor and truth), in one place.

* :data:`kernel`: a kernel called from Python (:data:`localizer._jit.fast_jit`: ``fastmath``,
  NumPy's error model, cached, no GIL).
* :data:`helper`: a function called only from other kernels: the same flags, without the
  CPython and C wrappers numba otherwise builds for every function (the code that unboxes
  each argument from a Python object: for a record of records of arrays, as
  :class:`~agvsim.sensors.render.ray_records.Scene`, thousands of instructions, and a
  third of the raycaster's cold compile). A helper cannot be called from Python; a test
  that needs one calls a kernel that calls it.

None is ``inline="always"``: numba's inliner types and lowers an inlined body again in
every caller (the raycaster's frame kernel took two minutes to compile that way), while
LLVM inlines the small helpers anyway, after each is compiled once. Each helper is
compiled for one signature: callers pass ``np.int64(0)``, not a literal ``0`` (numba
compiles a literal argument as a type of its own), and the truth's depth buffer in one layout.
"""
from __future__ import annotations

import numba

from localizer._jit import fast_jit

__all__ = ["exact_helper", "helper", "kernel"]

#: a kernel called from Python (module docstring)
kernel = fast_jit
#: a function called only from other kernels (module docstring)
helper = numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy", no_cpython_wrapper=True,
                    no_cfunc_wrapper=True)
#: :data:`helper` of the truth's kernels, which keep :data:`localizer._jit.jit` (IEEE arithmetic in the order written)
exact_helper = numba.njit(cache=True, nogil=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)
