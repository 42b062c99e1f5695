"""A recording written by a process of its own: :class:`RunRecording` (the same calls as
:class:`~agvsim.record.recording.RecordingWriter`, queued; Rerun's import, the JPEG encoding and
the logging run on another core, not in the run's time)."""
from __future__ import annotations

import os
from typing import Iterable, Sequence

import numpy as np

from agvsim.record.recording import RecordingWriter, map_layers

__all__ = ["CALL_BATCH", "RunRecording"]

#: calls a :class:`RunRecording` gathers before it queues them for its process
CALL_BATCH = 32


def _serve(queue, errors, args) -> None:
    """The recording process: :class:`RecordingWriter` calls from ``queue`` (lists of them) until
    ``None``; the first error's message on ``errors`` (Ctrl-C is the parent's: it closes the
    recording)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    state = _start(args, errors)
    while True:
        batch = queue.get()
        if batch is None:
            break
        for item in batch:
            state = _apply(*state, item, errors)
    if state[0] is not None:
        state[0].close()


def _start(args, errors):
    """``(writer, failed, args)`` of a new recording (its error's message on ``errors``)."""
    try:
        return RecordingWriter(*args), False, args
    except Exception as exc:  # (reported at close)
        errors.put(f"{args[0]}: {exc}")
        return None, True, args


class _Here:
    """The recording process's queue, served in this process as each batch is put: for a
    process that may not start one of its own (a worker of a pool, which is daemonic)."""

    def __init__(self, args) -> None:
        self.errors: list[str] = []
        self.state = _start(args, self)

    def put(self, batch) -> None:  # (also the errors' queue: a message)
        if isinstance(batch, str):
            self.errors.append(batch)
        elif batch is None:
            if self.state[0] is not None:
                self.state[0].close()
        else:
            for item in batch:
                self.state = _apply(*self.state, item, self)


def _apply(writer, failed, args, item, errors):
    """One queued call on the recording process's writer: ``(writer, failed, args)`` after it."""
    if item[0] == "restart":  # (a new file: the last one closed, the same map and thinning)
        if writer is not None:
            writer.close()
        args = (item[1], item[2], *args[2:])
        writer, failed = None, False
        item = ("__init__",)
    if failed:
        return writer, failed, args
    try:
        if item[0] == "__init__":
            writer = RecordingWriter(*args)
        else:
            getattr(writer, item[0])(*item[1:])
    except Exception as exc:
        errors.put(f"{args[0]}: {type(exc).__name__}: {exc}")
        failed = True
    return writer, failed, args


class RunRecording:
    """One run's recording, written to ``path`` by a process of its own: each call here queues
    its arguments and returns, the process makes the :class:`RecordingWriter` calls (Rerun's
    import, the JPEG encoding and the logging run on another core, not in the run's time). The
    same methods and arguments as :class:`RecordingWriter`.

    Args:
        path: the ``.rrd`` file (written; its folder is made).
        recording_id: the recording's id (e.g. ``"seed-3"``); the application id is ``"agvsim"``.
        world_map: the map whose walls, targets and stations are logged static (None: no map).
        every: log every ``every``-th camera frame (1: all of them); the poses and metrics of
            every step whatever it is.

    Use as a context manager, or call :meth:`close` (which waits for everything queued to be
    written and raises ``ValueError`` with what the writing raised). Ctrl-C in the run does not
    stop the recording process: closing the recording keeps what it holds. In a process that
    may not start another (a pool's worker, as ``agvsim drift`` runs its seeds on), the calls
    are written in this process instead, a batch at a time.
    """

    def __init__(self, path: str | os.PathLike, recording_id: str, world_map=None, every: int = 1) -> None:
        import multiprocessing

        from localizer.numeric import check_number

        self.path = os.fspath(path)
        every = int(check_number("record every", every, low=1, integer=True))
        layers = None if world_map is None else map_layers(world_map)
        args = (self.path, recording_id, layers, every)
        self._calls: list[tuple] = []
        self._process = None
        if multiprocessing.current_process().daemon:  # (a pool's worker: written here)
            self._queue = self._here = _Here(args)
            return
        self._here = None
        context = multiprocessing.get_context("spawn")
        self._queue = context.Queue()
        self._errors = context.Queue()
        self._process = context.Process(target=_serve, args=(self._queue, self._errors, args),
                                        name="agvsim-recording", daemon=True)
        self._process.start()

    def poses(self, t: float, poses: dict[str, Sequence[float]], covariance=None, status: str | None = None) -> None:
        """:meth:`RecordingWriter.poses`, queued."""
        self._put(("poses", float(t), {k: tuple(float(v) for v in p) for k, p in poses.items()},
                   None if covariance is None else np.array(covariance, dtype=float), status))

    def frame(self, t: float, image: np.ndarray | None, detections: Iterable = ()) -> None:
        """:meth:`RecordingWriter.frame`, queued (the image copied)."""
        self._put(("frame", float(t), None if image is None else np.array(image), tuple(detections)))

    def fused(self, t: float, nis: Sequence[float], accepted: int) -> None:
        """:meth:`RecordingWriter.fused`, queued."""
        self._put(("fused", float(t), tuple(float(v) for v in nis), int(accepted)))

    def _put(self, item: tuple) -> None:
        """Queue one call, :data:`CALL_BATCH` at a time (one pickle and one wake-up of the queue's
        thread per batch, not per call)."""
        self._calls.append(item)
        if len(self._calls) >= CALL_BATCH:
            self._queue.put(self._calls)
            self._calls = []

    def restart(self, path: str | os.PathLike, recording_id: str) -> None:
        """Close this file and go on in a new one (the same map and thinning; the same process:
        an agent's next episode starts without waiting for Rerun's import)."""
        self.path = os.fspath(path)
        self._calls.append(("restart", self.path, recording_id))
        self._queue.put(self._calls)
        self._calls = []

    def close(self) -> None:
        """Wait for everything queued to be written, close the file; ``ValueError`` with what the
        writing raised."""
        import queue

        if self._queue is None:
            return
        if self._calls:
            self._queue.put(self._calls)
            self._calls = []
        self._queue.put(None)
        if self._here is not None:
            message = self._here.errors[0] if self._here.errors else None
        else:
            self._queue.close()
            self._queue.join_thread()
            self._process.join()
            try:
                message = self._errors.get_nowait()
            except queue.Empty:
                message = None
        self._queue = self._process = self._here = None
        if message is not None:
            raise ValueError(f"the recording failed: {message}")

    def __enter__(self) -> "RunRecording":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
