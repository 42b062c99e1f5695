"""Analysis on the side of the loop: metrics of runs, plots and top-down pictures.

* :mod:`agvsim.analysis.evaluate`: metrics of :class:`~agvsim.loop.log.MissionLog` runs and floors.
* :mod:`agvsim.analysis.plots`: error-against-distance plots (matplotlib).
* :mod:`agvsim.analysis.topdown`: the top-down view of the floor (OpenCV drawing, no OpenGL).
"""
from __future__ import annotations

from localizer.lazy import lazy_exports

_LAZY = {
    "TopDownView": "agvsim.analysis.topdown",
    "Trajectory": "agvsim.analysis.topdown",
    "error_vs_distance": "agvsim.analysis.plots",
    "run_metrics": "agvsim.analysis.evaluate",
    "summarize": "agvsim.analysis.evaluate",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
