"""A sweep's specification: a base drive, the axes to vary, the seeds; read from YAML.

A spec file::

    base:                      # a drive's settings (agvsim.loop.drive.DriveSettings), all optional
      map: plant_floor
      distance: 100            # m per seed
      observations: geometric
    grid:                      # every combination of the axes' values (a grid) ...
      odometry: [typical, worn]
      targets_removed: [0.0, 0.33, 0.5]
    seeds: 2                   # seeds per point: first_seed .. first_seed + seeds - 1
    first_seed: 0              # (optional, default 0)

or, instead of ``grid``, a seeded random sample of the axes::

    sample:
      points: 20
      seed: 7
      axes:
        camera_rate: {low: 1.0, high: 8.0}   # uniform between (a number axis)
        odometry: [typical, worn]            # one of these, equally likely

The axes (:data:`AXES`, defined once: the CLI's help, the validation and the docs read it) are
fields of :class:`~agvsim.loop.drive.DriveSettings`; ``map`` takes map names or YAML paths
(relative paths from the spec's folder), ``camera_mount`` the ``--camera-mount`` forms. Every
point is checked as a whole drive when the spec is read (each map loaded and its route looked
up), so a bad value is reported before anything runs: one line naming the file, the field,
the value and what was expected.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

__all__ = ["AXES", "BASE_FIELDS", "Axis", "SpecError", "SweepSpec", "load_spec"]


class SpecError(ValueError):
    """A spec that cannot be run: the message is one line naming file, field, value and what was expected."""


@dataclass(frozen=True)
class Axis:
    """A setting a sweep can vary.

    Attributes:
        name: the :class:`~agvsim.loop.drive.DriveSettings` field.
        kind: ``number`` (a sample draws it uniformly between ``low`` and ``high``) or
            ``choice`` (a sample draws one of a list).
        help: what it is, with its unit.
    """

    name: str
    kind: str
    help: str


#: the axes a sweep can vary, in the order the results' columns list them
AXES: dict[str, Axis] = {a.name: a for a in (
    Axis("map", "choice", "map name or YAML path (a list of map files)"),
    Axis("odometry", "choice", "odometry error preset"),
    Axis("targets_removed", "number", "share of the map's targets removed, evenly spread (0 <= s < 1)"),
    Axis("camera_rate", "number", "camera frames per second (Hz)"),
    Axis("latency", "number", "capture-to-fusion delay (s)"),
    Axis("lens", "choice", "the thesis camera's focal length (mm)"),
    Axis("camera_mount", "choice", "where the camera sits: map, forward, left, right or forward=F,lateral=L,height=H,yaw=Y"),
    Axis("lighting", "number", "scale of the map's illumination levels (1: the map's own)"),
    Axis("observations", "choice", "observation source"),
)}

#: the fields ``base`` may set: every DriveSettings field
BASE_FIELDS: tuple[str, ...] = ("map", "route", "distance", "odometry", "camera_rate", "latency", "vision",
                                "observations", "backend", "drop_targets", "targets_removed", "false_rate",
                                "camera_mount", "lens", "lighting")

_TOP = ("base", "grid", "sample", "seeds", "first_seed")
#: most points a spec may expand to (a typo such as 1e6 seeds is refused, not started)
MAX_RUNS = 100_000


@dataclass(frozen=True)
class SweepSpec:
    """A read and checked spec.

    Attributes:
        path: the spec file.
        base: the base drive's settings as given (plain values).
        axes: the varied axes' names, in :data:`AXES` order.
        points: one dict per point: axis name -> value (plain: str or float), in run order.
        seeds: the seeds every point runs.
        data: the spec as read (YAML data), stored beside the results.
    """

    path: Path
    base: Mapping[str, Any]
    axes: tuple[str, ...]
    points: tuple[Mapping[str, Any], ...]
    seeds: tuple[int, ...]
    data: Mapping[str, Any]

    def settings(self, index: int):
        """Point ``index``'s :class:`~agvsim.loop.drive.DriveSettings`."""
        return _settings({**self.base, **self.points[index]}, self.path.parent)

    def identity(self) -> dict:
        """What makes two sweeps the same sweep (the folder's resume check): base, points, seeds."""
        return {"base": dict(self.base), "axes": list(self.axes), "points": [dict(p) for p in self.points],
                "seeds": list(self.seeds)}


def _where(path: Path, field: str) -> str:
    return f"{path}: {field}"


def _settings(values: Mapping[str, Any], folder: Path):
    """DriveSettings from plain values (map paths resolved from ``folder``, mounts parsed)."""
    from agvsim.commands._args import parse_mount
    from agvsim.loop.drive import DriveSettings

    kw = dict(values)
    if "map" in kw:
        kw["map"] = _map_ref(kw["map"], folder)
    if "camera_mount" in kw:
        kw["camera_mount"] = parse_mount(str(kw["camera_mount"]))
    return DriveSettings(**kw)


def _map_ref(name: str, folder: Path) -> str:
    """A map name, or a YAML path made absolute from the spec's folder."""
    if name.endswith((".yaml", ".yml")) and not Path(name).is_absolute():
        return str((folder / name).resolve())
    return name


def _check_value(path: Path, where: str, name: str, value: Any) -> Any:
    """One axis or base value, checked on its own (types); the drive checks the rest."""
    import argparse

    from agvsim.commands._args import parse_mount

    if name in ("map", "route", "odometry", "observations", "backend"):
        if not isinstance(value, str) or not value:
            raise SpecError(f"{_where(path, where)}: {value!r} is not a name; expected a string")
        return value
    if name == "camera_mount":
        try:
            parse_mount(str(value))
        except argparse.ArgumentTypeError as exc:
            raise SpecError(f"{_where(path, where)}: {exc}") from None
        return str(value)
    if name == "vision":
        if not isinstance(value, bool):
            raise SpecError(f"{_where(path, where)}: {value!r}; expected true or false")
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SpecError(f"{_where(path, where)}: {value!r} is not a number; expected a finite number")
    return int(value) if name == "drop_targets" else float(value)


def _mapping(path: Path, where: str, raw: Any, known: tuple[str, ...], what: str) -> dict:
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise SpecError(f"{_where(path, where)}: {raw!r}; expected {what}")
    for key in raw:
        if key not in known:
            raise SpecError(f"{_where(path, f'{where}.{key}' if where else str(key))}: unknown field; "
                            f"expected one of {', '.join(known)}")
    return raw


def _int(path: Path, where: str, raw: Any, low: int) -> int:
    if isinstance(raw, bool) or not isinstance(raw, int) or raw < low:
        raise SpecError(f"{_where(path, where)}: {raw!r}; expected a whole number >= {low}")
    return raw


def _grid(path: Path, raw: dict) -> list[dict]:
    axes = _mapping(path, "grid", raw, tuple(AXES), "a mapping of axis: [values]")
    lists = {}
    for name in AXES:  # (AXES order: the columns' order)
        if name not in axes:
            continue
        values = axes[name]
        if not isinstance(values, list) or not values:
            raise SpecError(f"{_where(path, f'grid.{name}')}: {values!r}; expected a non-empty list of values")
        lists[name] = [_check_value(path, f"grid.{name}[{i}]", name, v) for i, v in enumerate(values)]
        if len(set(map(repr, lists[name]))) != len(lists[name]):
            raise SpecError(f"{_where(path, f'grid.{name}')}: {values!r} repeats a value; expected distinct values")
    names = list(lists)
    return [dict(zip(names, combo)) for combo in itertools.product(*(lists[n] for n in names))]


def _sample(path: Path, raw: dict) -> list[dict]:
    spec = _mapping(path, "sample", raw, ("points", "seed", "axes"), "a mapping {points, seed, axes}")
    for key in ("points", "seed", "axes"):
        if key not in spec:
            raise SpecError(f"{_where(path, f'sample.{key}')}: missing; expected "
                            + {"points": "the number of points", "seed": "the sample's seed (a whole number)",
                               "axes": "a mapping of axis: [values] or {low, high}"}[key])
    n = _int(path, "sample.points", spec["points"], 1)
    rng = np.random.default_rng(_int(path, "sample.seed", spec["seed"], 0))
    axes = _mapping(path, "sample.axes", spec["axes"], tuple(AXES), "a mapping of axis: [values] or {low, high}")
    draws: dict[str, Callable[[], Any]] = {}
    for name in AXES:
        if name not in axes:
            continue
        where, value = f"sample.axes.{name}", axes[name]
        if isinstance(value, list) and value:
            options = [_check_value(path, f"{where}[{i}]", name, v) for i, v in enumerate(value)]
            draws[name] = lambda options=options: options[int(rng.integers(len(options)))]
        elif isinstance(value, dict) and AXES[name].kind == "number":
            r = _mapping(path, where, value, ("low", "high"), "{low: number, high: number}")
            low = _check_value(path, f"{where}.low", name, r.get("low"))
            high = _check_value(path, f"{where}.high", name, r.get("high"))
            if not low < high:
                raise SpecError(f"{_where(path, where)}: low {low!r} >= high {high!r}; expected low < high")
            draws[name] = lambda low=low, high=high: float(rng.uniform(low, high))
        else:
            expected = "a list of values or {low, high}" if AXES[name].kind == "number" else "a non-empty list of values"
            raise SpecError(f"{_where(path, where)}: {value!r}; expected {expected}")
    if not draws:
        raise SpecError(f"{_where(path, 'sample.axes')}: empty; expected at least one axis")
    return [{name: draw() for name, draw in draws.items()} for _ in range(n)]


def load_spec(path: str | Path) -> SweepSpec:
    """Read and check the spec at ``path``.

    Raises:
        SpecError: one line naming the file, field, value and what was expected (a point that is
            not a valid drive names the point and its values).
    """
    import yaml

    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise SpecError(f"{path}: cannot read the spec ({exc.strerror or exc})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" (line {mark.line + 1})" if mark is not None else ""
        raise SpecError(f"{path}: not valid YAML{at}: {getattr(exc, 'problem', exc)}") from None
    data = _mapping(path, "", data, _TOP, "a mapping with base, grid or sample, seeds")
    base = {k: _check_value(path, f"base.{k}", k, v)
            for k, v in _mapping(path, "base", data.get("base"), BASE_FIELDS, "a mapping of drive settings").items()}
    if ("grid" in data) == ("sample" in data):
        raise SpecError(f"{_where(path, 'grid')}: expected exactly one of grid (every combination) "
                        "or sample (a seeded random sample)")
    points = _grid(path, data["grid"]) if "grid" in data else _sample(path, data["sample"])
    axes = tuple(n for n in AXES if n in points[0])
    clash = [n for n in axes if n in base]
    if clash:
        raise SpecError(f"{_where(path, f'base.{clash[0]}')}: also an axis; expected it in base or among the axes, not both")
    if "seeds" not in data:
        raise SpecError(f"{_where(path, 'seeds')}: missing; expected the number of seeds per point (a whole number >= 1)")
    first = _int(path, "first_seed", data.get("first_seed", 0), 0)
    seeds = tuple(range(first, first + _int(path, "seeds", data["seeds"], 1)))
    if len(points) * len(seeds) > MAX_RUNS:
        raise SpecError(f"{_where(path, 'seeds')}: {len(points)} points x {len(seeds)} seeds = "
                        f"{len(points) * len(seeds)} drives; expected at most {MAX_RUNS}")
    spec = SweepSpec(path, base, axes, tuple(points), seeds, data)
    _check_drives(spec)
    return spec


def _check_drives(spec: SweepSpec) -> None:
    """Every point as a drive: its settings valid, each map loaded once and its route there."""
    from agvsim.commands._args import check_route
    from agvsim.world import load_map

    maps: dict[str, Any] = {}
    for i, point in enumerate(spec.points):
        values = ", ".join(f"{k}={v}" for k, v in point.items())
        try:
            settings = spec.settings(i)
        except ValueError as exc:
            field = str(exc).split(" ", 1)[0]
            where = f"base.{field}" if field in spec.base and field not in point else f"point {i} ({values})"
            raise SpecError(f"{spec.path}: {where}: {exc}") from None
        if settings.map not in maps:
            try:
                maps[settings.map] = load_map(settings.map)
            except (ValueError, OSError, KeyError) as exc:
                field = "grid.map" if "map" in point else "base.map"
                raise SpecError(f"{_where(spec.path, field)}: {exc}") from None
        try:
            check_route(maps[settings.map], settings.route, flag=_where(spec.path, "base.route"))
        except ValueError as exc:
            raise SpecError(str(exc)) from None


def drive_fields() -> tuple[str, ...]:
    """The DriveSettings fields (kept equal to :data:`BASE_FIELDS` by a test)."""
    from agvsim.loop.drive import DriveSettings

    return tuple(f.name for f in fields(DriveSettings))
