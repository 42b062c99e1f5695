"""The flags that keep a copy of a run as it is made, shared by the commands that drive:
``--record FILE.rrd`` (a Rerun recording, :mod:`agvsim.record`), ``--record-every N``, and for
``agvsim demo`` ``--export-log DIR`` / ``--export-bag FILE.mcap`` (the drive as a log that
``agvsim track`` reads back, :mod:`agvsim.replay`)."""
from __future__ import annotations

from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Iterator

from agvsim.commands._args import number

__all__ = ["add_capture_flags", "captures", "check_extra"]

#: the optional extras, by module: what to install when one is missing
EXTRAS = {"rerun": "record", "rosbags": "rosbag"}


def check_extra(module: str, flag: str) -> None:
    """Raise one line naming ``flag`` and the extra to install when ``module`` is missing."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise ValueError(f"{flag} needs the {module!r} package: pip install 'agvsim[{EXTRAS[module]}]'")


def add_capture_flags(parser, exports: bool = False) -> None:
    """``--record``, ``--record-every`` and (``exports``) ``--export-log``, ``--export-bag``."""
    parser.add_argument("--record", type=Path, default=None, metavar="FILE.rrd",
                        help="write a Rerun recording of the run (open it with `rerun FILE.rrd`; "
                             "the 'record' extra); agvsim drift: one per seed, FILE-seedNNN.rrd (default: none)")
    parser.add_argument("--record-every", type=number(1, integer=True), default=1, metavar="N",
                        help="--record: every N-th camera frame (default: %(default)s, all)")
    if exports:
        parser.add_argument("--export-log", type=Path, default=None, metavar="DIR",
                            help="write the drive as a log folder (frames, odometry, truth) for agvsim track (default: none)")
        parser.add_argument("--export-bag", type=Path, default=None, metavar="FILE.mcap",
                            help="write the drive as a ROS 2 bag (MCAP) for agvsim track (the 'rosbag' extra; default: none)")


def check_capture_flags(args) -> None:
    """Refuse, before a run starts, what could not be written at its end."""
    if args.record is not None:
        check_extra("rerun", "--record")
        if args.record.suffix != ".rrd":
            raise ValueError(f"--record {str(args.record)!r}: expected a file name ending in .rrd")
    if getattr(args, "export_bag", None) is not None:
        check_extra("rosbags", "--export-bag")
        if args.export_bag.suffix != ".mcap":
            raise ValueError(f"--export-bag {str(args.export_bag)!r}: expected a file name ending in .mcap")
        if args.export_bag.exists():
            raise ValueError(f"--export-bag {str(args.export_bag)!r}: exists already; expected a new file")


@contextmanager
def captures(args, world_map, start, recording_id: str = "run") -> Iterator:
    """The observer (``run_mission(..., observer=)``) that writes what the flags ask for, or None.
    When the block ends the recording is closed and the exported logs' files renamed into place;
    an error other than Ctrl-C removes the exports' unfinished files (an interrupted run keeps
    what it wrote)."""
    observers, sinks = [], []
    with ExitStack() as stack:
        if args.record is not None:
            from agvsim.record import LoopRecorder, RunRecording

            rec = stack.enter_context(RunRecording(args.record, recording_id, world_map, args.record_every))
            observers.append(LoopRecorder(rec))
        for flag, make in (("export_log", _folder_sink), ("export_bag", _bag_sink)):
            path = getattr(args, flag, None)
            if path is not None:
                from agvsim.replay.export import LogExporter

                sinks.append(make(path))
                observers.append(LogExporter(sinks[-1], start))
        if not observers:
            yield None
            return

        def observer(loop, step) -> None:
            for o in observers:
                o(loop, step)

        keep = False
        try:
            yield observer
            keep = True
        except KeyboardInterrupt:
            keep = True
            raise
        finally:
            for sink in sinks:
                sink.close(keep=keep)


def _folder_sink(path):
    from agvsim.replay.folder import FolderWriter

    return FolderWriter(path)


def _bag_sink(path):
    from agvsim.replay.bag import BagWriter

    return BagWriter(path)
