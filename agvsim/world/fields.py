"""Reading hand-written YAML values with precise error messages.

Every error is a :class:`MapError` naming the file, the path to the field
(``targets[3].height``), the problem, the bad value and what was expected.
Nothing here knows about walls or targets: :mod:`agvsim.world.map` says
which keys each section has and which reader checks each value.
"""
from __future__ import annotations

import difflib
import math
import os
import re
import reprlib
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from localizer.numeric import check_number

#: Every number in a map lies within ±WORLD_LIMIT (m for lengths): a floor at most 20 km across.
WORLD_LIMIT = 10_000.0
#: Longest field path or shown value in an error message (characters).
MESSAGE_PART_CHARS = 120

#: Marks "no value to show" in an error message (a missing key).
MISSING: Any = object()

#: A reader turns a raw YAML value at a field path into a checked Python value.
Reader = Callable[["Context", str, Any], Any]


class MapError(ValueError):
    """A map file is malformed or describes an impossible floor.

    The message reads ``"<file>: <field path>: <problem> (got <value!r>;
    expected <what>)"``. The parts are also attributes, for programs.

    Attributes:
        file: the map file (or ``"<map>"`` for data not read from a file).
        path: the field, e.g. ``"targets[3].height"``; ``""`` for the whole file.
        problem: what is wrong.
        value: the offending value (:data:`MISSING` if there was none).
        expected: what would have been accepted.
    """

    def __init__(self, file: str, path: str, problem: str, value: Any = MISSING,
                 expected: str = "") -> None:
        self.file = file
        self.path = path
        self.problem = problem
        self.value = value
        self.expected = expected
        super().__init__(self._format())

    def _format(self) -> str:
        """One line; the path and the value are shortened (a map may hold huge or hostile values)."""
        path = _shorten(" ".join(self.path.split()))
        where = f"{self.file}: {path}" if path else self.file
        details = []
        if self.value is not MISSING:
            details.append(f"got {short_repr(self.value)}")
        if self.expected:
            details.append(f"expected {self.expected}")
        suffix = f" ({'; '.join(details)})" if details else ""
        return " ".join(f"{where}: {self.problem}{suffix}".split("\n"))


def _shorten(text: str, limit: int = MESSAGE_PART_CHARS) -> str:
    return text if len(text) <= limit else text[:limit - 3] + "..."


class _ShortRepr(reprlib.Repr):
    """reprlib with small limits; numpy values shown as plain Python (``[1.0, 2.0]``)."""

    def __init__(self) -> None:
        super().__init__()
        self.maxlevel, self.maxlist, self.maxtuple, self.maxdict = 3, 6, 6, 4
        self.maxstring, self.maxother, self.maxlong = 60, 60, 40

    def repr_int(self, x: int, level: int) -> str:
        if x.bit_length() > 200:  # repr() of a huge int is slow (and refused past 4300 digits)
            return f"<an integer of about {int(x.bit_length() * 0.30103) + 1} digits>"
        return super().repr_int(x, level)

    def repr_ndarray(self, x: np.ndarray, level: int) -> str:
        return self.repr1(x.ravel()[:self.maxlist + 1].tolist() if x.ndim <= 1 else
                          [row for row in x[:self.maxlist + 1].tolist()], level)

    def repr_instance(self, x: Any, level: int) -> str:
        if isinstance(x, np.generic):
            return self.repr1(x.item(), level)
        return super().repr_instance(x, level)


_SHORT = _ShortRepr()


def short_repr(value: Any) -> str:
    """``repr(value)`` cut to about :data:`MESSAGE_PART_CHARS` characters, whatever its size."""
    return _shorten(_SHORT.repr(value))


@dataclass(frozen=True)
class Context:
    """Where values come from: the file label used in every error."""

    file: str

    def error(self, path: str, problem: str, value: Any = MISSING, expected: str = "") -> MapError:
        return MapError(self.file, path, problem, value, expected)


def join(path: str, key: str | int) -> str:
    """``join("targets", 3)`` -> ``"targets[3]"``; ``join("targets[3]", "at")`` -> ``"targets[3].at"``."""
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


# ---------------------------------------------------------------- mappings

def mapping(ctx: Context, path: str, raw: Any, readers: Mapping[str, Reader],
            required: tuple[str, ...] = (), what: str = "a mapping") -> dict[str, Any]:
    """Check ``raw`` is a mapping with known keys, read every value.

    Args:
        readers: key -> reader for every allowed key.
        required: keys that must be present.
        what: how to describe the expected mapping in an error.

    Returns:
        key -> read value, for the keys present.

    Raises:
        MapError: not a mapping, an unknown key (with the closest valid key
            suggested), a missing required key, or a bad value.
    """
    if not isinstance(raw, dict):
        raise ctx.error(path or "(top level)", "wrong type", raw, what)
    for key in raw:
        if not isinstance(key, str):
            raise ctx.error(join(path, str(key)), "keys must be strings", key,
                            f"one of {_listing(readers)}")
        if key not in readers:
            raise unknown_key(ctx, path, key, readers)
    for key in required:
        if key not in raw:
            raise ctx.error(join(path, key), "missing required key",
                            expected=_describe(readers[key]))
    return {key: readers[key](ctx, join(path, key), value) for key, value in raw.items()}


def unknown_key(ctx: Context, path: str, key: str, valid: Mapping[str, Any]) -> MapError:
    """A MapError for a typo'd key, suggesting the closest valid one."""
    close = difflib.get_close_matches(key, list(valid), n=1, cutoff=0.6) if len(key) <= 100 else []
    hint = f", did you mean {close[0]!r}?" if close else ""
    return ctx.error(join(path, key), f"unknown key{hint}", key, f"one of {_listing(valid)}")


def _listing(keys) -> str:
    return ", ".join(sorted(keys))


def _describe(reader: Reader) -> str:
    return getattr(reader, "expected", "a value")


def expects(description: str) -> Callable[[Reader], Reader]:
    """Decorator attaching the human description a reader expects."""
    def mark(reader: Reader) -> Reader:
        reader.expected = description  # type: ignore[attr-defined]
        return reader
    return mark


def sequence(ctx: Context, path: str, raw: Any, what: str, min_len: int = 0) -> list[Any]:
    """Check ``raw`` is a YAML list of at least ``min_len`` items."""
    if not isinstance(raw, list):
        raise ctx.error(path, "wrong type", raw, what)
    if len(raw) < min_len:
        raise ctx.error(path, f"too few items ({len(raw)})", raw,
                        f"{what} with at least {min_len} items")
    return raw


# ---------------------------------------------------------------- scalars

def number(ctx: Context, path: str, raw: Any, unit: str = "", *, positive: bool = False,
           non_negative: bool = False) -> float:
    """A finite real number (YAML int or float, not a bool), checked by
    :func:`localizer.numeric.check_number`; a :class:`MapError` naming the field otherwise."""
    kind = "a positive number" if positive else (
        "a number >= 0" if non_negative else "a finite number")
    expected = f"{kind}, {unit}" if unit else kind
    if isinstance(raw, bool) or not isinstance(raw, (int, float)):
        raise ctx.error(path, "wrong type", raw, expected)
    limit = f"{WORLD_LIMIT:g}"
    out_of_range = f"out of range: beyond ±{limit}" + (" m (a map is at most 20 km across)" if unit == "m" else "")
    within = (f"a positive number <= {limit}" if positive else f"a number from 0 to {limit}" if non_negative
              else f"a number from -{limit} to {limit}") + (f", {unit}" if unit else "")
    if isinstance(raw, int) and abs(raw) > WORLD_LIMIT:  # (a huge int overflows float())
        raise ctx.error(path, out_of_range, raw, within)
    try:
        value = check_number(path, raw, low=0.0 if (positive or non_negative) else None, low_open=positive)
    except ValueError:
        if not math.isfinite(raw):
            reason = "not a finite number"
        else:
            reason = "must be positive" if positive else "must not be negative"
        raise ctx.error(path, reason, raw, expected) from None
    if abs(value) > WORLD_LIMIT:
        raise ctx.error(path, out_of_range, raw, within)
    return value


_ID = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]*$")


def identifier(ctx: Context, path: str, raw: Any) -> str:
    """A non-empty id: letters, digits, ``_ . -``; numbers must be quoted."""
    expected = "a string id of letters, digits, '_', '.', '-' (quote ids that look like numbers)"
    if not isinstance(raw, str):
        raise ctx.error(path, "wrong type", raw, expected)
    if not _ID.match(raw):
        raise ctx.error(path, "not a valid id", raw, expected)
    return raw


def text(ctx: Context, path: str, raw: Any) -> str:
    """Free text (descriptions)."""
    if not isinstance(raw, str):
        raise ctx.error(path, "wrong type", raw, "a string")
    return raw


def choice(ctx: Context, path: str, raw: Any, options: tuple[str, ...]) -> str:
    """One of a fixed set of words."""
    expected = " or ".join(repr(o) for o in options)
    if not isinstance(raw, str):
        raise ctx.error(path, "wrong type", raw, expected)
    if raw not in options:
        close = difflib.get_close_matches(raw, options, n=1, cutoff=0.6) if len(raw) <= 100 else []
        hint = f", did you mean {close[0]!r}?" if close else ""
        raise ctx.error(path, f"not a valid choice{hint}", raw, expected)
    return raw


def point(ctx: Context, path: str, raw: Any, unit: str = "m") -> np.ndarray:
    """``[x, y]`` -> ``(2,)`` float array."""
    return vector(ctx, path, raw, 2, f"[x, y] in {unit}", unit)


def vector(ctx: Context, path: str, raw: Any, size: int, what: str, unit: str = "") -> np.ndarray:
    """A list of exactly ``size`` finite numbers (each in ``unit`` if given)."""
    if not isinstance(raw, list) or len(raw) != size:
        raise ctx.error(path, "wrong shape", raw, what)
    return np.array([number(ctx, join(path, i), v, unit) for i, v in enumerate(raw)], dtype=float)


def points(ctx: Context, path: str, raw: Any, min_len: int, what: str) -> np.ndarray:
    """A list of ``[x, y]`` -> ``(N, 2)`` float array, N >= ``min_len``."""
    items = sequence(ctx, path, raw, what, min_len)
    if all(type(p) is list and len(p) == 2 and type(p[0]) in _REAL and type(p[1]) in _REAL for p in items):
        try:
            pts = np.array(items, dtype=float)  # the usual case, checked at once
        except OverflowError:  # a huge integer: reported below
            pts = None
        if pts is not None and np.all(np.abs(pts) <= WORLD_LIMIT):
            return pts
    return np.array([point(ctx, join(path, i), p) for i, p in enumerate(items)], dtype=float)


_REAL = (int, float)


def readonly(array: np.ndarray) -> np.ndarray:
    """``array`` made read-only (returned for chaining)."""
    array.setflags(write=False)
    return array


# ---------------------------------------------------------------- YAML

def parse_yaml(ctx: Context, source_text: str | bytes) -> Any:
    """Parse a map's YAML text (str, or UTF-8 bytes) within the limits of
    :mod:`agvsim.world.yamlread` (size, depth, aliases); every problem is a
    one-line MapError naming the file and the line.

    Duplicate keys are refused; ``1e-3`` reads as a float (PyYAML alone reads
    exponents without a dot as strings); merge keys ``<<:`` are supported.
    """
    import yaml

    from agvsim.world import yamlread

    size = len(source_text)
    if size > yamlread.MAX_MAP_BYTES:
        raise ctx.error("", f"file too large ({size} bytes)",
                        expected=f"a map file of at most {yamlread.MAX_MAP_BYTES} bytes (MAX_MAP_BYTES)")
    if isinstance(source_text, bytes):
        source_text = decode_text(ctx, source_text)
    try:
        return yamlread.read_yaml(source_text)
    except yamlread.YamlLimit as exc:
        where = f"line {exc.line}" if exc.line is not None else ""
        value = MISSING if exc.value is None else exc.value
        raise ctx.error(where, exc.problem, value, exc.expected) from None
    except yaml.YAMLError as exc:
        raise ctx.error(*_yaml_problem(exc)) from None


def read_map_file(ctx: Context, path: os.PathLike) -> bytes:
    """A map file's bytes, refused past ``MAX_MAP_BYTES`` before reading them all."""
    from agvsim.world.yamlread import MAX_MAP_BYTES

    with open(path, "rb") as stream:
        data = stream.read(MAX_MAP_BYTES + 1)
    if len(data) > MAX_MAP_BYTES:
        size = os.path.getsize(path)
        raise ctx.error("", f"file too large ({size if size > MAX_MAP_BYTES else 'over ' + str(MAX_MAP_BYTES)} bytes)",
                        expected=f"a map file of at most {MAX_MAP_BYTES} bytes (MAX_MAP_BYTES)")
    return data


def decode_text(ctx: Context, data: bytes) -> str:
    """A map file's bytes as text: UTF-8 (a UTF-8 byte-order mark is allowed)."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise ctx.error("", "not UTF-8: the file starts with a UTF-16 byte-order mark",
                        expected="a YAML text file saved as UTF-8")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        bad = data[exc.start:exc.start + 1]
        raise ctx.error("", f"not a UTF-8 text file: byte 0x{bad.hex()} at offset {exc.start}",
                        expected="a YAML text file saved as UTF-8") from None


def _yaml_problem(exc: Exception) -> tuple[str, str]:
    """(where, problem) of a PyYAML error, on one line."""
    mark = getattr(exc, "problem_mark", None)
    where = f"line {mark.line + 1}" if mark is not None else ""
    if getattr(exc, "character", None) is not None and getattr(exc, "reason", None):  # a ReaderError
        char = exc.character
        code = ord(char) if isinstance(char, str) else char
        return "", f"not a text file: character 0x{code:02x} at offset {exc.position} ({exc.reason})"
    problem = getattr(exc, "problem", None) or str(exc)
    return where, "invalid YAML: " + " ".join(str(problem).split())
