"""Reading hand-written YAML values with precise error messages.

Every error is a :class:`MapError` naming the file, the path to the field
(``targets[3].height``), the problem, the bad value and what was expected.
Nothing here knows about walls or targets: :mod:`agvsim.world.map` says
which keys each section has and which reader checks each value.
"""
from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from localizer.numeric import check_number

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
        where = f"{self.file}: {self.path}" if self.path else self.file
        details = []
        if self.value is not MISSING:
            details.append(f"got {_plain(self.value)!r}")
        if self.expected:
            details.append(f"expected {self.expected}")
        suffix = f" ({'; '.join(details)})" if details else ""
        return f"{where}: {self.problem}{suffix}"


def _plain(value: Any) -> Any:
    """numpy values as plain Python, so messages show ``[1.0, 2.0]``, not ``array(...)``."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


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
    close = difflib.get_close_matches(key, list(valid), n=1, cutoff=0.6)
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
    try:
        return check_number(path, raw, low=0.0 if (positive or non_negative) else None, low_open=positive)
    except ValueError:
        if isinstance(raw, bool) or not isinstance(raw, (int, float)):
            reason = "wrong type"
        elif not math.isfinite(float(raw)):
            reason = "not a finite number"
        else:
            reason = "must be positive" if positive else "must not be negative"
        raise ctx.error(path, reason, raw, expected) from None


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
        close = difflib.get_close_matches(raw, options, n=1, cutoff=0.6)
        hint = f", did you mean {close[0]!r}?" if close else ""
        raise ctx.error(path, f"not a valid choice{hint}", raw, expected)
    return raw


def point(ctx: Context, path: str, raw: Any, unit: str = "m") -> np.ndarray:
    """``[x, y]`` -> ``(2,)`` float array."""
    return vector(ctx, path, raw, 2, f"[x, y] in {unit}")


def vector(ctx: Context, path: str, raw: Any, size: int, what: str) -> np.ndarray:
    """A list of exactly ``size`` finite numbers."""
    if not isinstance(raw, list) or len(raw) != size:
        raise ctx.error(path, "wrong shape", raw, what)
    return np.array([number(ctx, join(path, i), v) for i, v in enumerate(raw)], dtype=float)


def points(ctx: Context, path: str, raw: Any, min_len: int, what: str) -> np.ndarray:
    """A list of ``[x, y]`` -> ``(N, 2)`` float array, N >= ``min_len``."""
    items = sequence(ctx, path, raw, what, min_len)
    return np.array([point(ctx, join(path, i), p) for i, p in enumerate(items)], dtype=float)


def readonly(array: np.ndarray) -> np.ndarray:
    """``array`` made read-only (returned for chaining)."""
    array.setflags(write=False)
    return array


# ---------------------------------------------------------------- YAML

def parse_yaml(ctx: Context, source_text: str) -> Any:
    """Parse YAML text; duplicate keys and syntax errors become MapErrors.

    Uses a safe loader that also reads ``1e-3`` as a float (PyYAML alone
    reads exponents without a dot as strings).
    """
    import yaml

    loader_cls = _strict_loader(yaml)
    try:
        return yaml.load(source_text, Loader=loader_cls)  # noqa: S506 - a SafeLoader subclass
    except _DuplicateKey as exc:
        raise ctx.error(f"line {exc.line}", "duplicate key", exc.key,
                        "each key once per mapping") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ctx.error(where, f"invalid YAML: {problem}") from None


class _DuplicateKey(Exception):
    def __init__(self, key: Any, line: int) -> None:
        super().__init__(key)
        self.key = key
        self.line = line


_FLOAT = re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
    |\.[0-9_]+(?:[eE][-+][0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""", re.X)


def _strict_loader(yaml):
    """A SafeLoader subclass rejecting duplicate keys and reading 1e-3 as a float."""

    class StrictLoader(yaml.SafeLoader):
        def construct_mapping(self, node, deep=False):
            seen = set()
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=deep)
                try:
                    duplicate = key in seen
                except TypeError:  # unhashable key; the base class reports it
                    break
                if duplicate:
                    raise _DuplicateKey(key, key_node.start_mark.line + 1)
                seen.add(key)
            return super().construct_mapping(node, deep=deep)

    StrictLoader.yaml_implicit_resolvers = {
        k: [r for r in v if r[0] != "tag:yaml.org,2002:float"]
        for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()
    }
    StrictLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT,
                                       list("-+0123456789."))
    return StrictLoader
