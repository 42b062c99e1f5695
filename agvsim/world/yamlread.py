"""Reading a map file's YAML safely: bounded size, depth and alias expansion.

A map is a hand-written file from anyone, so reading it must not be a way to
exhaust memory or time. :func:`read_yaml` builds plain Python values (dicts,
lists, str, int, float, bool, None) straight from the parser's event stream,
in one pass with no recursion, and refuses, before anything large is built:

- a file over :data:`MAX_MAP_BYTES` (checked by the caller on the bytes);
- nesting deeper than :data:`MAX_DEPTH`;
- aliases (``*name``) that together would add more than
  :data:`MAX_ALIAS_NODES` values to the document (an "alias bomb" of a few
  hundred bytes otherwise expands to gigabytes), and aliases to an anchor
  that is still open (recursive data);
- integers written with more than :data:`MAX_NUMBER_CHARS` characters;
- explicit tags other than YAML's plain ones (``!!set``, ``!python/...``, ...);
- more than one document, duplicate keys, keys that are lists or mappings.

Merge keys (``<<: *base`` or ``<<: [*a, *b]``) are supported: the merged
mapping's keys are copied under the explicit ones (explicit keys win; in a
list, earlier mappings win); what they copy counts towards the alias budget.

The parser is libyaml's (``yaml.CParser``, :data:`USING_LIBYAML`) when PyYAML
was built with it, else PyYAML's pure-Python one (about 20x slower, same
results). Scalars are resolved as by ``yaml.SafeLoader``, except that ``1e-3``
(an exponent without a dot) is a float, as users expect.
"""
from __future__ import annotations

import re
from typing import Any, Callable

import yaml
from yaml.events import (AliasEvent, DocumentEndEvent, DocumentStartEvent, MappingEndEvent, MappingStartEvent,
                         ScalarEvent, SequenceEndEvent, SequenceStartEvent, StreamEndEvent, StreamStartEvent)
from yaml.nodes import ScalarNode

__all__ = ["MAX_ALIAS_NODES", "MAX_DEPTH", "MAX_MAP_BYTES", "MAX_NUMBER_CHARS", "USING_LIBYAML", "YamlLimit",
           "read_yaml"]

#: Largest map file read (bytes): 10 MiB, twice a 5 MB floor of 60 000 walls.
MAX_MAP_BYTES = 10 * 1024 * 1024
#: Deepest nesting of lists and mappings (a map needs 6: walls[i].points[j][k]).
MAX_DEPTH = 64
#: Most values (scalars, lists, mappings) that aliases and merge keys may add.
MAX_ALIAS_NODES = 100_000
#: Longest integer scalar, in characters (a float beyond ±1.8e308 reads as inf).
MAX_NUMBER_CHARS = 1000

#: Whether PyYAML's libyaml parser is used (else the pure-Python fallback).
USING_LIBYAML: bool = bool(getattr(yaml, "__with_libyaml__", False))
_PARSER = yaml.CSafeLoader if USING_LIBYAML else yaml.SafeLoader

_TAG = "tag:yaml.org,2002:"
_STR, _INT, _FLOAT, _BOOL, _NULL = (_TAG + t for t in ("str", "int", "float", "bool", "null"))
_MERGE = _TAG + "merge"
_SEQ, _MAP = _TAG + "seq", _TAG + "map"


class YamlLimit(Exception):
    """The document breaks a limit or a rule of this reader (``line`` is 1-based, or None)."""

    def __init__(self, line: int | None, problem: str, value: Any = None, expected: str = "") -> None:
        super().__init__(problem)
        self.line = line
        self.problem = problem
        self.value = value
        self.expected = expected


# ---------------------------------------------------------------- scalars

_FLOAT_RE = re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
    |\.[0-9_]+(?:[eE][-+][0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""", re.X)


def _implicit_resolvers() -> dict[str, list[tuple[str, re.Pattern]]]:
    """First character -> [(tag, regexp)], SafeLoader's plus floats such as ``1e-3``."""
    table: dict[str, list[tuple[str, re.Pattern]]] = {}
    for first, pairs in yaml.SafeLoader.yaml_implicit_resolvers.items():
        table[first] = [(tag, rx) for tag, rx in pairs if tag != _FLOAT]
    for first in "-+0123456789.":
        table.setdefault(first, []).append((_FLOAT, _FLOAT_RE))
    return table


_RESOLVERS = _implicit_resolvers()
_SIMPLE_INT = re.compile(r"^[-+]?(?:0|[1-9][0-9]*)$")
_SIMPLE_FLOAT = re.compile(r"^[-+]?[0-9]+(?:\.[0-9]*)?(?:[eE][-+]?[0-9]+)?$")
_NUMBER_FIRST = frozenset("-+123456789")  # (not 0: 010 is octal in YAML 1.1, 0.5 goes the long way)
_CONSTRUCTOR = yaml.SafeLoader("")  # only its construct_yaml_* methods are used, on single scalars
_SCALAR_CONSTRUCTORS = {_FLOAT: _CONSTRUCTOR.construct_yaml_float, _INT: _CONSTRUCTOR.construct_yaml_int,
                        _BOOL: _CONSTRUCTOR.construct_yaml_bool,
                        _TAG + "timestamp": _CONSTRUCTOR.construct_yaml_timestamp}


def _scalar(ev: ScalarEvent) -> tuple[Any, str]:
    """A scalar event -> (value, tag)."""
    value = ev.value
    tag = ev.tag
    if tag is None and ev.implicit[0] and value[:1] in _NUMBER_FIRST and len(value) <= MAX_NUMBER_CHARS:
        # the common case, a plain decimal number: what the resolvers below give it, at once
        # (a leading 0 is left to them: YAML 1.1 reads 010 as octal)
        if _SIMPLE_INT.match(value):
            return int(value), _INT
        if _SIMPLE_FLOAT.match(value) and not value.lstrip("+-").isdigit():  # (-010: octal, the long way)
            return float(value), _FLOAT
    if tag is None or tag == "!":
        if tag is None and ev.implicit[0]:
            tag = _STR
            for candidate, rx in _RESOLVERS.get(value[:1], ()):
                if rx.match(value):
                    tag = candidate
                    break
        else:
            return value, _STR
    if tag == _STR:
        return value, tag
    if tag == _FLOAT and _SIMPLE_FLOAT.match(value):
        return float(value), tag
    if tag == _INT and _SIMPLE_INT.match(value) and len(value) <= MAX_NUMBER_CHARS:
        return int(value), tag
    if tag == _NULL:
        return None, tag
    if tag == _MERGE:
        return _MergeKey, tag
    construct = _SCALAR_CONSTRUCTORS.get(tag)
    if construct is not None:
        if tag == _INT and len(value) > MAX_NUMBER_CHARS:
            raise YamlLimit(_line(ev), f"integer of {len(value)} characters", value,
                            f"a number of at most {MAX_NUMBER_CHARS} characters")
        try:
            return construct(ScalarNode(tag, value)), tag
        except (ValueError, TypeError, ArithmeticError, yaml.YAMLError):
            what = tag[len(_TAG):] if tag.startswith(_TAG) else tag
            raise YamlLimit(_line(ev), f"not a valid {what}", value, f"a YAML {what}") from None
    raise YamlLimit(_line(ev), f"unsupported tag {tag!r}", value,
                    "plain YAML values (strings, numbers, true/false, null, lists, mappings)")


class _MergeKey:
    """The ``<<`` merge key (a marker, never a value)."""


def _line(ev) -> int | None:
    mark = getattr(ev, "start_mark", None)
    return mark.line + 1 if mark is not None else None


# ---------------------------------------------------------------- collections

class _Frame:
    """A list or mapping being built: its value, expanded size, anchor and (mappings) state."""

    __slots__ = ("value", "size", "anchor", "key", "has_key", "keys", "merges", "line", "is_map")

    def __init__(self, value: Any, anchor: str | None, line: int | None) -> None:
        self.value = value
        self.size = 1
        self.anchor = anchor
        self.key: Any = None
        self.has_key = False
        self.keys: dict | None = None
        self.merges: list | None = None
        self.line = line
        self.is_map = isinstance(value, dict)


def read_yaml(text: str | bytes) -> Any:
    """Parse one YAML document within the limits of this module.

    Returns:
        The document's value (None for an empty document).

    Raises:
        YamlLimit: a limit or rule of this module is broken.
        yaml.YAMLError: the text is not valid YAML.
    """
    parser = _PARSER(text)
    try:
        return _build(parser.get_event, parser.check_event)
    finally:
        parser.dispose()


def _build(get_event: Callable[[], Any], check_event: Callable[[], bool]) -> Any:
    stack: list[_Frame] = []
    anchors: dict[str, tuple[Any, int]] = {}
    open_anchors: set[str] = set()
    alias_nodes = 0
    documents = 0
    result: Any = None
    while check_event():
        ev = get_event()
        kind = type(ev)
        if kind is ScalarEvent:
            value, tag = _scalar(ev)
            size = 1
            if ev.anchor is not None:
                anchors[ev.anchor] = (value, 1)
        elif kind is SequenceStartEvent or kind is MappingStartEvent:
            is_map = kind is MappingStartEvent
            if ev.tag not in (None, "!", _MAP if is_map else _SEQ):
                raise YamlLimit(_line(ev), f"unsupported tag {ev.tag!r}", expected="plain YAML lists and mappings")
            if len(stack) >= MAX_DEPTH:
                raise YamlLimit(_line(ev), f"nested more than {MAX_DEPTH} levels deep",
                                expected=f"lists and mappings at most {MAX_DEPTH} levels deep")
            frame = _Frame({} if is_map else [], ev.anchor, _line(ev))
            if ev.anchor is not None:
                open_anchors.add(ev.anchor)
            stack.append(frame)
            continue
        elif kind is SequenceEndEvent or kind is MappingEndEvent:
            frame = stack.pop()
            if frame.is_map and frame.merges:
                _apply_merges(frame)
            value, size, tag = frame.value, frame.size, None
            if frame.anchor is not None:
                open_anchors.discard(frame.anchor)
                anchors[frame.anchor] = (value, size)
        elif kind is AliasEvent:
            if ev.anchor in open_anchors:
                raise YamlLimit(_line(ev), f"alias *{ev.anchor} refers to a list or mapping that contains it",
                                expected="aliases to finished values only (no recursive data)")
            if ev.anchor not in anchors:
                raise YamlLimit(_line(ev), f"unknown alias *{ev.anchor}", expected="an anchor &name defined before")
            value, size = anchors[ev.anchor]
            tag = None
            alias_nodes += size
            if alias_nodes > MAX_ALIAS_NODES:
                raise YamlLimit(_line(ev), f"aliases expand to more than {MAX_ALIAS_NODES} values "
                                f"(at *{ev.anchor})", expected=f"aliases and merge keys adding at most "
                                f"{MAX_ALIAS_NODES} values")
        elif kind is DocumentStartEvent:
            documents += 1
            if documents > 1:
                raise YamlLimit(_line(ev), "a second YAML document ('---')", expected="one document per map file")
            continue
        elif kind is DocumentEndEvent or kind is StreamStartEvent or kind is StreamEndEvent:
            continue
        else:  # pragma: no cover - PyYAML has no other events
            raise YamlLimit(_line(ev), f"unexpected YAML event {kind.__name__}")
        # a finished value: put it in its parent
        if not stack:
            result = value
            continue
        parent = stack[-1]
        parent.size += size
        if not parent.is_map:
            parent.value.append(value)
        elif not parent.has_key:
            if isinstance(value, (list, dict)):
                raise YamlLimit(_line(ev), "a list or mapping used as a key",
                                expected="keys that are plain values (strings)")
            parent.key, parent.has_key = value, True
        else:
            parent.has_key = False
            key = parent.key
            if key is _MergeKey:
                _add_merge(parent, value, ev)
            elif key in parent.value:
                raise YamlLimit(_line(ev), "duplicate key", key, "each key once per mapping")
            else:
                parent.value[key] = value
    return result


def _add_merge(frame: _Frame, value: Any, ev) -> None:
    """Record a ``<<:`` value (a mapping or a list of mappings) to merge when ``frame`` ends."""
    items = value if isinstance(value, list) else [value]
    if not items or not all(isinstance(item, dict) for item in items):
        raise YamlLimit(_line(ev), "merge key '<<' needs a mapping or a list of mappings",
                        expected="'<<: *name' or '<<: [*a, *b]' naming mappings")
    if frame.merges is None:
        frame.merges = []
    frame.merges.extend(items)


def _apply_merges(frame: _Frame) -> None:
    """Keys from merged mappings under the explicit ones; earlier merged mappings win."""
    merged: dict = {}
    for item in reversed(frame.merges or []):
        merged.update(item)
    merged.update(frame.value)
    frame.value.clear()
    frame.value.update(merged)
