"""The project's one angle wrap and its one validation helpers.

Everything in :mod:`localizer`, :mod:`agvsim` and :mod:`envs` that wraps an angle
or checks a user-supplied number or choice goes through these functions, so
every message has the same shape::

    SimConfig.control_rate must be a finite number > 0 (Hz), got -1.0
    EnvConfig.task must be one of goto, localize; got 'gotoo' (did you mean 'goto'?)

They live in :mod:`localizer` because the localizer must not import the
simulator, while the simulator may import the localizer.
"""
from __future__ import annotations

import difflib
import math
import numbers
from typing import Iterable, Sequence

import numpy as np

__all__ = ["TWO_PI", "check_choice", "check_number", "check_numbers", "wrap_angle"]

TWO_PI = 2.0 * math.pi


def wrap_angle(a):
    """Angle(s) wrapped to [-π, π) (rad): a float for a float, an array for an array.

    ``(a + π) mod 2π - π``, the form the filter has always used; values already in
    range come back within one rounding of themselves.
    """
    if isinstance(a, float):
        return (a + math.pi) % TWO_PI - math.pi
    return (np.asarray(a, dtype=float) + math.pi) % TWO_PI - math.pi


def _describe(low, high, low_open: bool, high_open: bool) -> str:
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {low:g}")
    if high is not None:
        parts.append(f"{'<' if high_open else '<='} {high:g}")
    return " and ".join(parts)


def check_number(where: str, value, *, low: float | None = None, high: float | None = None,
                 low_open: bool = False, high_open: bool = False, unit: str = "",
                 integer: bool = False) -> float:
    """``value`` as a float (an int with ``integer=True``) or one clear ``ValueError``.

    Args:
        where: what is being set, as the user names it (``"SimConfig.control_rate"``,
            ``"--distance"``, ``"maps/x.yaml: targets[3].height"``).
        value: the value given; bools and non-numbers are refused.
        low, high: bounds (None: unbounded); ``low_open``/``high_open`` make them strict.
        unit: unit named in the message ("m", "Hz", ...).
        integer: require a whole number and return an ``int``.

    Raises:
        ValueError: ``"<where> must be a finite number > 0 (Hz), got -1.0"``.
    """
    ok = not isinstance(value, bool) and isinstance(value, numbers.Real)
    if ok:
        x = float(value)
        ok = math.isfinite(x)
        if ok and integer:
            ok = x == round(x)
        if ok and low is not None:
            ok = x > low if low_open else x >= low
        if ok and high is not None:
            ok = x < high if high_open else x <= high
    if not ok:  # the message is built only for the error
        kind = "a whole number" if integer else "a finite number"
        bounds = _describe(low, high, low_open, high_open)
        expected = kind + (f" {bounds}" if bounds else "") + (f" ({unit})" if unit else "")
        raise ValueError(f"{where} must be {expected}, got {value!r}")
    return int(round(x)) if integer else x


def check_numbers(where: str, values, n: int, **bounds) -> tuple[float, ...]:
    """``n`` numbers, each checked by :func:`check_number` with ``bounds``; a tuple of floats."""
    try:
        items = tuple(values)
    except TypeError:
        raise ValueError(f"{where} must be {n} numbers, got {values!r}") from None
    if len(items) != n:
        raise ValueError(f"{where} must be {n} numbers, got {values!r}")
    return tuple(check_number(f"{where}[{i}]", v, **bounds) for i, v in enumerate(items))


def check_choice(where: str, value, choices: Sequence[str] | Iterable[str]) -> str:
    """``value`` if it is one of ``choices``, else one ``ValueError`` naming them (and the nearest)."""
    options = tuple(choices)
    if isinstance(value, str) and value in options:
        return value
    hint = ""
    if isinstance(value, str):
        close = difflib.get_close_matches(value, options, n=1)
        if close:
            hint = f" (did you mean {close[0]!r}?)"
    raise ValueError(f"{where} must be one of {', '.join(options)}; got {value!r}{hint}")
