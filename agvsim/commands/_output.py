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


#: significant digits a float keeps in JSON output: far beyond any measurement's precision (and
#: float64's 15-17), short of the binary noise of sums such as 40.400000000000006
JSON_DIGITS = 12


def clean_json(value: Any) -> Any:
    """``value`` as plain JSON data: numpy arrays and scalars as lists and numbers, NaN and
    infinities as None, floats rounded to :data:`JSON_DIGITS` significant digits."""
    if isinstance(value, dict):
        return {str(k): clean_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [clean_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return clean_json(value.tolist())
    if isinstance(value, np.generic):
        return clean_json(value.item())
    if isinstance(value, float):
        return float(f"{value:.{JSON_DIGITS}g}") if math.isfinite(value) else None
    return value


def doc_help(doc: str) -> str:
    """A module docstring's first paragraph as help text: one line, without reST's backticks."""
    return " ".join(doc.strip().split("\n\n")[0].replace("``", "").replace("`", "").split())


def plural(count: int, noun: str, plural_form: str | None = None) -> str:
    """``"1 seed"``, ``"2 seeds"``: ``count`` and ``noun``, pluralised (``plural_form`` if not
    ``noun + "s"``)."""
    return f"{count} {noun if count == 1 else plural_form or noun + 's'}"


class DistanceBar:
    """A progress bar in metres on stderr: ``driving:  52%|####  | 97/186 m [01:30<01:22, 1.08 m/s]``.

    The rate is always metres of route per wall-clock second (tqdm alone flips to ``s/m`` below
    1 m/s, which reads like a speed). :meth:`to` moves it to a route position, :meth:`add`
    adds metres, :meth:`finish` ends it at what was really covered: the total becomes that
    figure, so a run that stops short of the nominal total (the follower arrives within its
    arrival radius; the route's corners are cut) still ends at ``n/n``.
    """

    FORMAT = "{desc}: {percentage:3.0f}%|{bar}| {n:.0f}/{total:.0f} m [{elapsed}<{remaining}, {rate_noinv_fmt}]"

    def __init__(self, total_m: float, disable: bool = False, desc: str = "driving") -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=float(total_m), unit=" m", desc=desc, disable=disable, leave=False,
                        file=sys.stderr, bar_format=self.FORMAT)
        self._shown = 0.0

    @property
    def n(self) -> float:
        return self._shown

    @property
    def total(self) -> float:
        return float(self.bar.total)

    def add(self, metres: float) -> None:
        """``metres`` more covered."""
        if metres > 0:
            self._shown += metres
            self.bar.update(metres)

    def to(self, position_m: float) -> None:
        """Covered up to ``position_m`` (never backwards; redrawn at whole metres)."""
        if position_m >= self._shown + 1.0:
            self.add(position_m - self._shown)

    def finish(self, covered_m: float | None = None) -> None:
        """End at ``covered_m`` (the total becomes it), or at the total; close the bar."""
        end = self.total if covered_m is None else float(covered_m)
        self.bar.total = end
        self.bar.n = end
        self._shown = end
        self.bar.refresh()
        self.bar.close()

    def close(self) -> None:
        """Close the bar where it stands (an interrupted run)."""
        self.bar.close()


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
