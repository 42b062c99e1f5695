"""Plots of run logs (matplotlib, Agg backend; imported only when plotting)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def error_vs_distance(path: str | Path, distance: np.ndarray, series: dict[str, np.ndarray],
                      title: str, bound: np.ndarray | None = None) -> Path:
    """Save a plot of position error (m) against distance travelled (m).

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

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(7.0, 4.0), dpi=110)
    try:
        for label, err in series.items():
            ax.plot(distance, err, label=label, linewidth=1.4)
        if bound is not None:
            ax.plot(distance, bound, "k--", linewidth=0.9, label="2σ bound")
        ax.set_xlabel("distance travelled (m)")
        ax.set_ylabel("position error (m)")
        ax.set_title(title)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left")
        fig.tight_layout()
        fig.savefig(path)
    finally:
        plt.close(fig)
    return path
