"""Units of work (seeds, sweep points) on a pool of worker processes that a Ctrl-C or a kill
of the command does not outlive.

:func:`run_units` runs ``job(args)`` for each unit, in this process (one worker) or on a pool
of spawned processes, and hands each result to the caller the moment it arrives (the caller
saves it: :class:`agvsim.commands.run_folder.RunFolder`). The workers:

* ignore SIGINT: a terminal's Ctrl-C (sent to the whole process group) is the parent's to
  handle, which stops the pool and says what finished; the workers are started with SIGINT
  held back (:func:`sigint_blocked`), so one still starting up (importing, before it ignores
  the signal) prints no traceback, and the parent is not interrupted half-way through starting
  them (a worker left starting up alone);
* die with their parent on Linux (``PR_SET_PDEATHSIG``): a killed command leaves no worker
  computing on; a worker whose parent died before that was set exits at once.

Progress: a job puts numbers on ``args["queue"]`` (``put``); they reach ``progress(number)``
in the parent.
"""
from __future__ import annotations

import signal
from contextlib import contextmanager
from typing import Callable, Iterator

__all__ = ["MetreReporter", "run_after", "run_units", "sigint_blocked", "worker_init"]

_QUEUE = None  # a worker's progress queue (set by worker_init)


def worker_init(queue) -> None:
    """A pool worker's start: progress to ``queue``, SIGINT ignored, death with the parent."""
    global _QUEUE
    _QUEUE = queue
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):  # (started with SIGINT blocked: sigint_blocked)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    import multiprocessing as mp
    import os

    parent = mp.parent_process()
    if parent is not None and os.getppid() != parent.pid:  # the parent died before the line above
        os._exit(1)


def _call(task):
    job, args = task
    return job({**args, "queue": _QUEUE})


@contextmanager
def sigint_blocked() -> Iterator[None]:
    """A Ctrl-C held back while the block runs, and raised on leaving.

    :func:`localizer.interrupts.deferred_interrupt` (this process's handler only notes a
    SIGINT meanwhile, also one the operating system gives to another thread, as a BLAS
    thread), and SIGINT blocked in this thread, so that a worker started in the block (which
    inherits the mask) cannot receive it while it starts up: the block's work (a pool started
    and assigned, a frame localized and written) is never cut short half-way. Outside the main
    thread: nothing held back.
    """
    import threading

    from localizer.interrupts import deferred_interrupt

    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        yield
        return
    with deferred_interrupt():
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # (a SIGINT pending here is noted too)


class MetreReporter:
    """A run's progress in whole metres to its ``queue`` (``args["queue"]`` of a job; None: silent):
    :meth:`to` every ``every`` metres driven, :meth:`finish` the rest of ``total`` metres."""

    def __init__(self, queue, every: float = 5.0) -> None:
        self.queue, self.every, self.reported = queue, every, 0.0

    def to(self, metres: float) -> None:
        if self.queue is not None and metres - self.reported >= self.every:
            step = int(metres - self.reported)
            self.queue.put(step)
            self.reported += step

    def finish(self, total: float) -> None:
        if self.queue is not None:
            self.queue.put(max(int(round(total - self.reported)), 0))


class _Progress:
    """The in-process stand-in for a worker's progress queue."""

    def __init__(self, progress: Callable[[float], None]):
        self.put = progress


def run_units(job: Callable[[dict], tuple], units: list[dict], workers: int,
              finished: Callable[..., None], progress: Callable[[float], None]) -> None:
    """Run ``job(args)`` for each ``args`` of ``units`` (in this process, or on a pool of
    ``workers`` spawned processes; ``job`` a module-level function), calling ``finished(*result)``
    as each ends (in the order they end) and ``progress(number)`` for what the jobs report.

    A Ctrl-C (``KeyboardInterrupt``) or an error stops the workers at once and is raised.
    """
    import multiprocessing as mp
    import queue as queue_mod

    if not units:
        return
    if workers == 1:
        for args in units:
            finished(*job({**args, "queue": _Progress(progress)}))
        return
    ctx = mp.get_context("spawn")
    reports = ctx.Queue()
    pool = None
    try:
        with sigint_blocked():  # (the pool is assigned before a Ctrl-C meanwhile is raised)
            pool = ctx.Pool(min(workers, len(units)), initializer=worker_init, initargs=(reports,))
        results = pool.imap_unordered(_call, [(job, args) for args in units])
        for _ in units:
            while True:
                try:
                    result = results.next(timeout=0.5)
                    break
                except mp.TimeoutError:
                    pass
                finally:
                    try:
                        while True:
                            progress(reports.get_nowait())
                    except queue_mod.Empty:
                        pass
            finished(*result)
        pool.close()
    except BaseException:
        if pool is not None:
            pool.terminate()  # (Ctrl-C, or a unit's error: the workers stop now)
        raise
    finally:
        if pool is not None:
            pool.join()


def run_after(job: Callable[[dict], tuple], units: list[dict], waits: list[set[int]], workers: int,
              finished: Callable[..., None]) -> None:
    """:func:`run_units` for units that wait for others: unit ``i`` starts once every unit of
    ``waits[i]`` (indices into ``units``, each earlier in the list) has finished; a free worker
    takes the first unit, in the list's order, that waits for nothing. ``finished(*result)`` as
    each ends. A Ctrl-C or an error stops the workers at once and is raised.
    """
    import multiprocessing as mp
    import time

    if any(j >= i for i, w in enumerate(waits) for j in w):
        raise ValueError("a unit can only wait for units before it")
    if workers == 1 or len(units) == 1:  # (the list's order keeps every wait)
        for args in units:
            finished(*job({**args, "queue": None}))
        return
    ctx = mp.get_context("spawn")
    pool = None
    try:
        with sigint_blocked():
            pool = ctx.Pool(min(workers, len(units)), initializer=worker_init, initargs=(ctx.Queue(),))
        todo, running, done = list(range(len(units))), {}, set()
        while todo or running:
            while todo and len(running) < workers:
                ready = next((i for i in todo if waits[i] <= done), None)
                if ready is None:
                    break
                todo.remove(ready)
                running[ready] = pool.apply_async(_call, ((job, units[ready]),))
            for i in [i for i, r in running.items() if r.ready()]:
                result = running.pop(i).get()
                done.add(i)
                finished(*result)
            time.sleep(0.05)
        pool.close()
    except BaseException:
        if pool is not None:
            pool.terminate()
        raise
    finally:
        if pool is not None:
            pool.join()
