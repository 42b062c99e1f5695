"""Output conventions shared by the subcommands.

With ``--json`` a command prints exactly one JSON object on stdout; every
progress bar and log line goes to stderr.
"""
from __future__ import annotations

import json
import math
import sys
from typing import Any

import numpy as np


def clean_json(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): clean_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [clean_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return clean_json(value.tolist())
    if isinstance(value, np.generic):
        return clean_json(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def doc_help(doc: str) -> str:
    """A module docstring's first paragraph as help text: one line, without reST's backticks."""
    return " ".join(doc.strip().split("\n\n")[0].replace("``", "").replace("`", "").split())


def plural(count: int, noun: str, plural_form: str | None = None) -> str:
    """``"1 seed"``, ``"2 seeds"``: ``count`` and ``noun``, pluralised (``plural_form`` if not
    ``noun + "s"``)."""
    return f"{count} {noun if count == 1 else plural_form or noun + 's'}"


def emit_json(obj: dict[str, Any]) -> None:
    """Print ``obj`` as one JSON object on stdout (NaN/inf become null)."""
    json.dump(clean_json(obj), sys.stdout, indent=2, sort_keys=False)
    sys.stdout.write("\n")
    sys.stdout.flush()


def log(message: str) -> None:
    """A human-readable line on stderr."""
    print(message, file=sys.stderr, flush=True)


def add_json_flag(parser: Any) -> None:
    parser.add_argument("--json", action="store_true",
                        help="print exactly one JSON object on stdout (logs go to stderr)")
