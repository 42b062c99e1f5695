"""The ``agvsim`` command: one subcommand per module in :mod:`agvsim.commands`.

Each command module exposes ``register(subparsers)``, which adds its parser
and sets ``func`` (called with the parsed namespace, returns an exit code).
Registration only builds argparse parsers; heavy imports happen inside the
command functions, so ``agvsim --help`` stays fast and opens no GL context.

A user's mistake (a bad flag value, a file that cannot be read or written, an
unknown name) is one line on stderr naming the flag or file, the value and what
was expected, and exit status 2; ``--debug`` adds the traceback.
"""
from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading
import traceback

#: Subcommand modules under agvsim.commands, in the order --help lists them.
COMMAND_MODULES: tuple[str, ...] = ("demo", "map", "localize", "calibrate", "reproduce", "render", "bench", "drift", "sweep",
                                     "target", "plan", "warmup", "track")

#: The exit status of a user's mistake (argparse's own).
USAGE_ERROR = 2


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (no usage block): ``agvsim CMD: error: MESSAGE``."""

    def error(self, message: str):  # noqa: D102 (argparse's hook)
        self.exit(USAGE_ERROR, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="agvsim",
        description="Simulate vision-guided AGV navigation and localize two-bar wall targets.",
    )
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=_Parser)
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"agvsim.commands.{name}")
        except ModuleNotFoundError as exc:  # a command still being written
            if exc.name == f"agvsim.commands.{name}":
                continue
            raise
        module.register(sub)
    return parser


class _CtrlC:
    """Python's Ctrl-C (raise ``KeyboardInterrupt``), noting that it came: a library's compiled
    code may turn the interrupt raised inside it into an error of its own (matplotlib's path
    code reports ``ValueError: Invalid affine transformation matrix``), which is then no user's
    mistake but the interrupt. Installed by :func:`main` only over Python's own handler, in the
    main thread, and put back when it returns."""

    def __init__(self) -> None:
        self.came = False

    def __call__(self, signum, frame):
        self.came = True
        raise KeyboardInterrupt

    def __enter__(self) -> "_CtrlC":
        self.previous = None
        if threading.current_thread() is threading.main_thread() \
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            self.previous = signal.signal(signal.SIGINT, self)
        return self

    def __exit__(self, *exc) -> bool:
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
        return False


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv  # (also after the command's name)
    args = None
    with _CtrlC() as ctrl_c:
        try:
            parser = build_parser()
            args = parser.parse_args([a for a in argv if a != "--debug"])
            return int(args.func(args) or 0)
        except KeyboardInterrupt:  # Ctrl-C in a command that keeps nothing to resume (or while starting)
            print(f"{_name(args)}: interrupted", file=sys.stderr)
            return 130
        except BrokenPipeError:  # the reader went away (``agvsim ... | head``): nothing more to say
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 1
        except (ValueError, OSError) as exc:  # bad values, files that cannot be read or written
            if ctrl_c.came:  # a Ctrl-C that a library reported as an error of its own
                print(f"{_name(args)}: interrupted", file=sys.stderr)
                return 130
            if debug:
                traceback.print_exc()
            print(f"{_name(args)}: error: {_one_line(exc)}", file=sys.stderr)
            return USAGE_ERROR


def _name(args) -> str:
    """``agvsim COMMAND`` (``agvsim`` before the command line is parsed)."""
    return f"agvsim {args.command}" if args is not None else "agvsim"


def _one_line(exc: BaseException) -> str:
    """The error's message on one line (an ``OSError`` with its file name and reason)."""
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}"
    else:
        text = str(exc) or type(exc).__name__
    return " ".join(text.split())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
