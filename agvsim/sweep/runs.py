"""One run of a sweep: a point's drive for one seed, as one row of the results.

:func:`run_unit` is what a worker does for each (point, seed), on either engine: the drive of
``agvsim drift`` (:func:`agvsim.loop.drive.drive_seed`), its figures
(:func:`agvsim.analysis.evaluate.run_metrics`, the scalar ones) and the point's axis values,
as one flat row. A drive that raises becomes a row with ``status`` ``failed`` and its error, so
the sweep goes on; a Ctrl-C is not caught.
"""
from __future__ import annotations

import math
import time
from typing import Any

from agvsim.commands.workers import MetreReporter

__all__ = ["TIMING_COLUMNS", "run_unit", "unit_key", "units_of"]

#: columns that measure the machine, not the drive: left out when two engines' rows are compared
TIMING_COLUMNS: tuple[str, ...] = ("observe_ms_median", "filter_ms_median", "wall_time_s", "run_wall_s")


def unit_key(point: int, seed: int) -> str:
    """The run's name in the results folder: ``p0003_s0001``."""
    return f"p{point:04d}_s{seed:04d}"


def units_of(spec, todo: set[str] | None = None) -> list[dict]:
    """The runs of ``spec`` (every point, every seed, point by point), those in ``todo`` only
    when given: ``{"key", "point", "seed", "values", "settings"}`` each (picklable)."""
    units = []
    for i, values in enumerate(spec.points):
        settings = spec.settings(i)
        for seed in spec.seeds:
            key = unit_key(i, seed)
            if todo is None or key in todo:
                units.append({"key": key, "point": i, "seed": seed, "values": dict(values), "settings": settings})
    return units


def _scalar(value: Any) -> bool:
    return isinstance(value, (bool, int, float, str)) or value is None


def run_unit(unit: dict) -> tuple[str, dict]:
    """Drive ``unit`` (from :func:`units_of`; ``queue``: where metres driven are reported, or
    None) and return ``(key, row)``: ``point``, ``seed``, the axis values, ``status`` (``ok`` or
    ``failed``), ``error`` (empty, or ``Type: message``), the run's figures (NaN where a
    failed run has none) and ``run_wall_s``."""
    from agvsim.analysis.evaluate import run_metrics
    from agvsim.loop.drive import drive_seed

    progress = MetreReporter(unit.get("queue"))
    started = time.perf_counter()
    row: dict[str, Any] = {"point": unit["point"], "seed": unit["seed"], **unit["values"]}
    try:
        figures = run_metrics(drive_seed(unit["settings"], unit["seed"], progress.to))
        row.update(status="ok", error="", **{k: v for k, v in figures.items() if _scalar(v)})
    except Exception as exc:  # noqa: BLE001 - a failed run is recorded and the sweep goes on
        row.update(status="failed", error=f"{type(exc).__name__}: {exc}")
    row["run_wall_s"] = time.perf_counter() - started
    progress.finish(unit["settings"].distance)
    return unit["key"], {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items()}
