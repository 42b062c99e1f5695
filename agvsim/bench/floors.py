"""The benchmarks' floors: one verdict record and one report line for each.

A floor is a bound a measured figure must meet (``BENCHMARKS.md`` records them). Every
benchmark states each of its floors with :func:`verdict` in its JSON (``{"value", "op",
"limit", "unit", "met"}``) and with :func:`floor_line` in its table, so that a reader sees
"met" or "NOT met" next to every floor, in both.
"""
from __future__ import annotations

import math

__all__ = ["OPS", "floor_line", "verdict"]

#: the comparisons a floor may use: the value must be at most (``<=``) or at least (``>=``) the limit
OPS = ("<=", ">=")


def verdict(value: float | None, op: str, limit: float, unit: str = "") -> dict:
    """The floor ``value op limit`` as a JSON-ready record; ``met`` is False for a missing
    (None) or NaN value."""
    if op not in OPS:
        raise ValueError(f"floor op must be one of {', '.join(OPS)}, got {op!r}")
    ok = value is not None and not (isinstance(value, float) and math.isnan(value))
    if ok:
        ok = value <= limit if op == "<=" else value >= limit
    return {"value": value, "op": op, "limit": limit, "unit": unit, "met": bool(ok)}


def floor_line(what: str, floor: dict, spec: str = ".0f", note: str = "") -> str:
    """``floor: <what> <op> <limit> <unit>: met (<value>)`` or ``... NOT met (<value>)``."""
    unit = f" {floor['unit']}" if floor.get("unit") else ""
    value = "no value" if floor["value"] is None else f"{format(floor['value'], spec)}{unit}"
    note = f"; {note}" if note else ""
    return (f"floor: {what} {floor['op']} {floor['limit']:g}{unit}: "
            f"{'met' if floor['met'] else 'NOT met'} ({value}{note})")
