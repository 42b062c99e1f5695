"""The planner's outputs: the new map file, the picture of the layout and its predicted error.

:func:`write_map` writes the map's own YAML with its ``targets:`` section replaced (everything
else, comments included, as the user wrote it), each placed target marked ``# planned``, and
checks the result loads. :func:`draw_plan` draws the floor (:class:`agvsim.analysis.topdown.TopDownView`)
with the route coloured by the predicted ``3σ`` and the placed targets ringed and named.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from agvsim.files import atomic_write

__all__ = ["draw_plan", "target_line", "write_map"]

_TOP_KEY = re.compile(r"^[A-Za-z_][\w-]*\s*:")


def target_line(t, planned: bool) -> str:
    """One target as a YAML flow mapping line of the ``targets:`` list."""
    from localizer.model.target import TargetSpec

    size = ""
    if t.spec != TargetSpec():
        size = (f", size: {{bar_width: {t.spec.bar_width:.4f}, bar_height: {t.spec.bar_height:.4f}, "
                f"margin: {t.spec.margin:.4f}}}")
    line = (f"  - {{id: {t.id}, wall: {t.wall}, at: {t.at:.3f}, side: {t.side}, height: {t.height:.3f}, "
            f"polarity: {t.polarity}{size}}}")
    return line + ("  # planned" if planned else "")


def write_map(world_map, targets, placed: set[str], path: str | Path, header: str) -> Path:
    """Write ``world_map``'s file with ``targets`` as its targets (module docstring) to ``path``.

    Args:
        world_map: a map read from a file (``source``). targets: the new layout (``MapTarget``s).
        placed: ids of the planner's targets (marked). header: comment lines put first.
    Raises:
        ValueError: the map has no file to start from, or the written map does not load.
    """
    from agvsim.world import load_map

    if world_map.source is None:
        raise ValueError(f"map {world_map.name!r} has no YAML file to write a new layout from")
    lines = Path(world_map.source).read_text(encoding="utf-8").splitlines()
    start = next((i for i, ln in enumerate(lines) if re.match(r"^targets\s*:", ln)), None)
    block = ["targets:"] + [target_line(t, t.id in placed) for t in targets]
    if start is None:
        lines += [""] + block
    else:
        end = next((j for j in range(start + 1, len(lines)) if _TOP_KEY.match(lines[j])), len(lines))
        lines[start:end] = block + ([""] if end < len(lines) else [])
    path = Path(path)
    lines = [f"name: {path.stem}" if re.match(r"^name\s*:", ln) else ln for ln in lines]
    lines = [f"# {h}" for h in header.splitlines()] + lines
    with atomic_write(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
        load_map(str(tmp))  # (a map that does not load is not left under its final name)
    return path


def draw_plan(path: str | Path, world_map, plan, model, title: str) -> Path:
    """The floor with the route coloured by the predicted 3σ (cm) and the placed targets named."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    from agvsim.analysis.topdown import TopDownView

    view = TopDownView(world_map, pixels_per_metre=16.0, max_size=1300)
    image = view.render(legend=False)
    fig, ax = plt.subplots(figsize=(image.shape[1] / 100 + 1.6, image.shape[0] / 100 + 0.8), dpi=100)
    ax.imshow(image)
    pts = view.to_pixels(model.poses[:, :2])
    if model.path.loop:
        pts = np.vstack([pts, pts[:1]])
    segs = np.stack([pts[:-1], pts[1:]], axis=1)
    bound = 300.0 * plan.sigma[: len(segs)]
    lines = LineCollection(segs, cmap="viridis", linewidths=4.0)
    lines.set_array(bound)
    lines.set_clim(0.0, max(100.0 * plan.budget, float(bound.max())))
    ax.add_collection(lines)
    bar = fig.colorbar(lines, ax=ax, fraction=0.035, pad=0.01)
    bar.set_label("predicted 3σ position error (cm)")
    bar.ax.axhline(100.0 * plan.budget, color="red", lw=2)
    placed = [t for t in plan.targets if t.id in set(plan.placed)]
    if placed:
        xy = view.to_pixels(np.array([t.position for t in placed]))
        ax.scatter(xy[:, 0], xy[:, 1], s=90, facecolors="none", edgecolors="red", linewidths=1.6,
                   label="placed by the planner")
        for (u, v), t in zip(xy, placed):
            ax.annotate(t.id, (u, v), xytext=(4, 4), textcoords="offset points", fontsize=7, color="darkred")
        ax.legend(loc="lower right", fontsize=8)
    ax.set_axis_off()
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    with atomic_write(path) as tmp:
        fig.savefig(tmp, dpi=100)
    plt.close(fig)
    return path
