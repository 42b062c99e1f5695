"""The numba compilation flags, in one place: the localizer's kernels (:data:`jit`, :data:`inline`)
and the simulator's frame kernels (:data:`fast_jit`, at the end).

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

The first compilation in a process of one of this project's kernels prints
:data:`COMPILE_NOTICE` on stderr (a fresh install's first call waits for it; set
``AGVSIM_QUIET_COMPILE=1`` to silence it); :class:`CompileCounter` counts compilations (the
warmup reports them).
"""
from __future__ import annotations

import os
import sys
import threading

import numba
import numba.core.event


__all__ = ["COMPILE_NOTICE", "CompileCounter", "fast_jit", "inline", "jit", "quiet_compile_notice"]

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


# ------------------------------------------------------------------ first compilation
#: printed on stderr (once per process) when a kernel of this project is compiled rather than
#: loaded from the cache: the first call of a fresh install waits for it
COMPILE_NOTICE = ("compiling the localizer's and simulator's numba kernels for this machine: the first "
                  "run waits one to two minutes of a core (most of it LLVM), later runs load them from the cache "
                  "in about a second (`agvsim warmup` or `python -m localizer.warmup` compiles them ahead)")
_PACKAGES = ("localizer.", "agvsim.", "envs.")


def _ours(event) -> bool:
    dispatcher = event.data.get("dispatcher") if isinstance(event.data, dict) else None
    module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
    return module.startswith(_PACKAGES)


class _Notice(numba.core.event.Listener):
    """Prints :data:`COMPILE_NOTICE` at the first compilation of one of this project's kernels.
    Set ``AGVSIM_QUIET_COMPILE=1`` (or call :func:`quiet_compile_notice`) to silence it."""

    def __init__(self) -> None:
        self.given = bool(os.environ.get("AGVSIM_QUIET_COMPILE"))

    def on_start(self, event) -> None:
        if not self.given and _ours(event):
            self.given = True
            print(COMPILE_NOTICE, file=sys.stderr, flush=True)

    def on_end(self, event) -> None:
        pass


_NOTICE = _Notice()
numba.core.event.register("numba:compile", _NOTICE)


def quiet_compile_notice() -> None:
    """No :data:`COMPILE_NOTICE` in this process (a tool that reports compilation itself)."""
    _NOTICE.given = True


class CompileCounter(numba.core.event.Listener):
    """Counts this project's kernels that numba compiles (not those loaded from the cache)
    while installed: ``with CompileCounter() as c: ...; c.count``."""

    def __init__(self) -> None:
        self.count = 0
        self._lock = threading.Lock()

    def on_start(self, event) -> None:
        if _ours(event):
            with self._lock:
                self.count += 1

    def on_end(self, event) -> None:
        pass

    def __enter__(self) -> "CompileCounter":
        numba.core.event.register("numba:compile", self)
        return self

    def __exit__(self, *exc) -> None:
        numba.core.event.unregister("numba:compile", self)
