"""A sweep's results for a scientist: the table, the summary over seeds, a plot per axis.

From the rows in a results folder (:func:`agvsim.sweep.folder.read_rows`):

* ``results.parquet`` (or ``results.csv``): one row per point and seed, columns ``point``,
  ``seed``, the axes, ``status``, ``error``, then the run's figures (SI units, as
  :func:`agvsim.analysis.evaluate.run_metrics` names them);
* ``summary.parquet`` (or ``.csv``): one row per point: the axes, ``seeds`` (finished),
  ``failed``, and for each of :data:`SUMMARY_FIGURES` its mean, standard deviation, minimum,
  5th, 50th and 95th percentile and maximum over the point's seeds (``<figure>_mean``, ...);
* ``plots/<axis>.png``: for each axis with more than one value, each of :data:`PLOT_FIGURES`
  against it: every seed a dot, the mean over seeds a line, one line per combination of the
  other axes.

Parquet is written through pyarrow with the spec and software version in its metadata.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from agvsim.files import atomic_write

__all__ = ["FORMATS", "PLOT_FIGURES", "SUMMARY_FIGURES", "write_report"]

#: table formats (``--format``)
FORMATS: tuple[str, ...] = ("parquet", "csv")
#: figures summarised over seeds per point
SUMMARY_FIGURES: tuple[str, ...] = ("position_rmse_m", "position_p95_m", "position_max_m", "heading_rmse_rad",
                                    "nees_in_bounds", "dead_reckoning_final_error_m",
                                    "frames_with_accepted_observation", "lost", "time_lost_s")
#: figures plotted against each axis: (column, label, scale to the plotted unit)
PLOT_FIGURES: tuple[tuple[str, str, float], ...] = (
    ("position_rmse_m", "position RMSE (cm)", 100.0),
    ("position_max_m", "max position error (cm)", 100.0),
    ("nees_in_bounds", "NEES within 95 % bounds (%)", 100.0),
)
_STATS = (("mean", np.mean), ("std", np.std), ("min", np.min), ("p5", lambda v: np.percentile(v, 5)),
          ("p50", np.median), ("p95", lambda v: np.percentile(v, 95)), ("max", np.max))


def _columns(rows: list[dict], axes: tuple[str, ...]) -> list[str]:
    """``point, seed``, the axes, ``status, error``, then every other column in first-seen order."""
    first = ["point", "seed", *axes, "status", "error"]
    rest: dict[str, None] = {}
    for row in rows:
        for k in row:
            if k not in first:
                rest.setdefault(k)
    return first + list(rest)


def _write_table(path: Path, rows: list[dict], columns: list[str], fmt: str, meta: dict) -> Path:
    """``rows`` as a table at ``path`` (suffix from ``fmt``), atomically."""
    import pyarrow as pa

    data = {}
    for c in columns:
        values = [r.get(c) for r in rows]
        kinds = {type(v) for v in values if v is not None}
        if kinds <= {int, float} and float in kinds:
            values = [math.nan if v is None else float(v) for v in values]
        data[c] = values
    table = pa.table(data)
    target = path.with_suffix("." + fmt)
    with atomic_write(target) as tmp:
        if fmt == "parquet":
            import pyarrow.parquet as pq

            table = table.replace_schema_metadata({"agvsim.sweep": json.dumps(meta)})
            pq.write_table(table, tmp)
        else:
            import pyarrow.csv as pcsv

            pcsv.write_csv(table, tmp)
    return target


def summarize_points(rows: list[dict], axes: tuple[str, ...], points: list[dict]) -> list[dict]:
    """One dict per point (module docstring): the axes, ``seeds``, ``failed``, the statistics."""
    out = []
    for i, values in enumerate(points):
        mine = [r for r in rows if r["point"] == i]
        ok = [r for r in mine if r.get("status") == "ok"]
        entry: dict[str, Any] = {"point": i, **{a: values[a] for a in axes}, "seeds": len(ok),
                                 "failed": len(mine) - len(ok)}
        for fig in SUMMARY_FIGURES:
            v = np.array([r[fig] for r in ok if isinstance(r.get(fig), (int, float))], dtype=float)
            for name, stat in _STATS:
                entry[f"{fig}_{name}"] = float(stat(v)) if v.size else math.nan
        out.append(entry)
    return out


def _axis_positions(values: list) -> tuple[np.ndarray, list[str] | None]:
    """x positions of an axis's values: the numbers themselves, or 0, 1, ... for names (with labels)."""
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return np.array(values, dtype=float), None
    names = list(dict.fromkeys(str(v) for v in values))
    return np.array([names.index(str(v)) for v in values], dtype=float), names


def plot_axis(path: Path, rows: list[dict], axis: str, others: tuple[str, ...], title: str) -> None:
    """``plots/<axis>.png`` (module docstring), atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r.get("status") == "ok"]
    xs, names = _axis_positions([r[axis] for r in ok])
    groups: dict[tuple, list[int]] = {}
    for k, r in enumerate(ok):
        groups.setdefault(tuple(r[o] for o in others), []).append(k)
    fig, panels = plt.subplots(1, len(PLOT_FIGURES), figsize=(4.6 * len(PLOT_FIGURES), 4.2), squeeze=False)
    colours = plt.get_cmap("tab10")
    span = (xs.max() - xs.min()) if xs.size else 1.0
    jitter = 0.012 * (span if span > 0 else 1.0)
    for ax, (column, label, scale) in zip(panels[0], PLOT_FIGURES):
        for g, (key, idx) in enumerate(sorted(groups.items(), key=lambda kv: str(kv[0]))):
            colour = colours(g % 10)
            x = xs[idx]
            y = np.array([ok[k][column] if ok[k].get(column) is not None else math.nan for k in idx], float) * scale
            offset = (g - (len(groups) - 1) / 2) * jitter
            ax.plot(x + offset, y, "o", ms=4, alpha=0.55, color=colour)
            ux = np.unique(x)
            means = [np.nanmean(y[x == u]) if np.any(np.isfinite(y[x == u])) else math.nan for u in ux]
            name = ", ".join(f"{o}={v}" for o, v in zip(others, key)) or "mean over seeds"
            ax.plot(ux + offset, means, "-", lw=1.8, color=colour, label=name)
        ax.set_xlabel(axis)
        ax.set_ylabel(label)
        if names is not None:
            ax.set_xticks(range(len(names)), names)
        ax.grid(alpha=0.3)
    panels[0][0].legend(fontsize=8, loc="best", title="dots: seeds; lines: mean", title_fontsize=8)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    with atomic_write(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def write_report(out: str | Path, rows: dict[str, dict], record: dict, fmt: str = "parquet",
                 plots: bool = True) -> dict:
    """Write the table, the summary and the plots of the rows in ``out`` (module docstring).

    Args:
        out: the results folder. rows: ``{key: row}`` (:func:`agvsim.sweep.folder.read_rows`).
        record: the folder's ``sweep.json`` (its identity gives the axes and points).
        fmt: one of :data:`FORMATS`. plots: draw the plots.
    Returns:
        ``{"results": path, "summary": path, "plots": [paths]}``.
    """
    out = Path(out)
    axes = tuple(record["identity"]["axes"])
    points = record["identity"]["points"]
    ordered = [rows[k] for k in sorted(rows)]
    meta = {"spec": record.get("spec"), "software": record.get("software")}
    results = _write_table(out / "results", ordered, _columns(ordered, axes), fmt, meta)
    summary_rows = summarize_points(ordered, axes, points)
    summary = _write_table(out / "summary", summary_rows, list(summary_rows[0]) if summary_rows else ["point"],
                           fmt, meta)
    drawn = []
    if plots and ordered:
        base = record["identity"]["base"]
        where = f"{base.get('map', 'plant_floor')}, {base.get('distance', 1000.0):g} m per seed"
        for axis in axes:
            if len({json.dumps(p[axis]) for p in points}) < 2:
                continue
            path = out / "plots" / f"{axis}.png"
            path.parent.mkdir(parents=True, exist_ok=True)
            plot_axis(path, ordered, axis, tuple(a for a in axes if a != axis),
                      f"{where}: figures against {axis}")
            drawn.append(str(path))
    return {"results": str(results), "summary": str(summary), "plots": drawn}
