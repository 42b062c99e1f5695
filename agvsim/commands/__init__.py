"""Subcommands of the ``agvsim`` command (see :mod:`agvsim.cli`)."""
