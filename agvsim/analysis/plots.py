"""Plots of run logs (matplotlib, Agg backend; imported only when plotting)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def error_vs_distance(path: str | Path, distance: np.ndarray, series: dict[str, np.ndarray],
                      title: str, bound: np.ndarray | None = None) -> Path:
    """Save a plot of position error (m) against distance travelled (m), on a log error axis
    (centimetre filter errors and metre dead-reckoning drift both readable), the legend below it.

    Args:
        path: PNG file to write.
        distance: (N,) distance travelled (m).
        series: label -> (N,) position error (m).
        title: plot title.
        bound: optional (N,) 2σ bound (m), drawn dashed.
    """
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(7.0, 4.4), dpi=110, layout="constrained")
    try:
        curves = [np.asarray(err, float) for err in series.values()]
        for label, err in zip(series, curves):
            ax.plot(distance, err, label=label, linewidth=1.4)
        if bound is not None:
            curves.append(np.asarray(bound, float))
            ax.plot(distance, bound, "k--", linewidth=0.9, label="2σ bound of the estimate")
        ax.set_yscale("log")
        positive = np.concatenate([c[np.isfinite(c) & (c > 0)] for c in curves] + [np.ones(1)])
        low = max(float(np.percentile(positive, 1)) / 2, 1e-5)  # zeros (the start) cannot be drawn
        ax.set_ylim(bottom=low, top=max(2 * float(positive.max()), 10 * low))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.set_xlabel("distance travelled (m)")
        ax.set_ylabel("position error (m, log scale)")
        ax.set_title(title)
        ax.grid(True, which="major", alpha=0.35)
        ax.grid(True, which="minor", alpha=0.12)
        fig.legend(loc="outside lower center", ncols=min(3, len(curves)), frameon=False)
        fig.savefig(path)
    finally:
        plt.close(fig)
    return path
