"""The ``agvsim`` command: one subcommand per module in :mod:`agvsim.commands`.

Each command module exposes ``register(subparsers)``, which adds its parser
and sets ``func`` (called with the parsed namespace, returns an exit code).
Registration only builds argparse parsers; heavy imports happen inside the
command functions, so ``agvsim --help`` stays fast and opens no GL context.
"""
from __future__ import annotations

import argparse
import importlib
import sys

#: Subcommand modules under agvsim.commands, in the order --help lists them.
COMMAND_MODULES: tuple[str, ...] = ("demo", "map", "localize", "reproduce", "render", "bench", "drift")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="agvsim",
        description="Simulate vision-guided AGV navigation and localize two-bar wall targets.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"agvsim.commands.{name}")
        except ModuleNotFoundError as exc:  # a command still being written
            if exc.name == f"agvsim.commands.{name}":
                continue
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as exc:
        print(f"agvsim {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
