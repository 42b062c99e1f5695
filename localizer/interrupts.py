"""Ctrl-C held back over compiled calls: ``with deferred_interrupt(): ...``.

numba hands a kernel's results back through Python code: the class of a returned array is
unpickled by a Python function, a named tuple is built by its Python constructor. A Ctrl-C
arriving during a kernel's call makes Python run the SIGINT handler there, at the first
bytecode of that code, and the KeyboardInterrupt it raises is not expected by numba's boxing:
the interpreter crashes with a segmentation fault, or reports ``SystemError: ... returned a
result with an exception set`` (numba has no guard against it). Measured here with SIGINT sent every
millisecond: a loop over :func:`localizer.detect_targets` faulted within 12-53 signals, a loop
over ``agvsim/PlantFloor-v1`` steps within about 600.

Inside ``with deferred_interrupt():`` in the main thread, Python's SIGINT handler is
replaced by one that only notes the signal. When the outermost such block ends, the handler
that was there is put back, and if a SIGINT came meanwhile that handler is called: Python's
default one raises KeyboardInterrupt there, after the compiled call has returned. The
interrupt is therefore late by one block, a frame's detection or rendering, a millisecond or
so.

* Nothing is held back outside the main thread: Python runs signal handlers only there.
* A handler that is not a Python callable (``SIG_IGN``, ``SIG_DFL``, or one installed from C)
  is left alone: the block then holds nothing back.
* A block costs a pair of :func:`signal.signal` calls (about 9 us here, well under 1 % of a
  frame's detection or rendering).
* Unlike blocking the signal (``signal.pthread_sigmask``), this also holds when the
  operating system delivers SIGINT to another thread of the process, such as an OpenCV or BLAS
  worker: Python then still runs the handler in the main thread, which is the one noting it.
"""
from __future__ import annotations

import signal
import threading

__all__ = ["deferred_interrupt"]

_MAIN = threading.main_thread().ident


class _Held:
    """The state of the outermost block: depth, the handler it replaced, the signals noted."""

    depth = 0
    replaced = None
    noted = 0


def _note(signum, frame) -> None:
    _Held.noted += 1


class deferred_interrupt:  # noqa: N801 (used as a function: ``with deferred_interrupt():``)
    """A context manager: a SIGINT received in its block is raised when the outermost block
    ends (module docstring). Reentrant; not a decorator. Raises what the replaced handler
    raises (``KeyboardInterrupt`` for Python's default handler) on leaving the block, also
    when the block raised: the interrupt takes the block's exception as its context."""

    __slots__ = ()

    def __enter__(self) -> "deferred_interrupt":
        if threading.get_ident() != _MAIN:
            return self
        if _Held.depth == 0:
            current = signal.getsignal(signal.SIGINT)
            if not callable(current):
                return self  # SIG_IGN, SIG_DFL, a C handler: nothing to hold back
            _Held.replaced, _Held.noted = current, 0
            signal.signal(signal.SIGINT, _note)
        _Held.depth += 1
        return self

    def __exit__(self, *exc) -> bool:
        if _Held.depth == 0 or threading.get_ident() != _MAIN:
            return False
        _Held.depth -= 1
        if _Held.depth == 0:
            handler, noted = _Held.replaced, _Held.noted
            _Held.replaced, _Held.noted = None, 0
            signal.signal(signal.SIGINT, handler)
            if noted:
                handler(signal.SIGINT, None)
        return False
