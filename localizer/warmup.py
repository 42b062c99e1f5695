"""Compile the localizer's kernels ahead of their first use: ``python -m localizer.warmup``.

The kernels are compiled by numba for the machine they run on, the first time they are
called, and cached on disk (beside the modules, or in the user's cache directory when the
package's directory cannot be written): in a fresh install the first :func:`detect_targets`
takes about a minute on a 2-core machine, every later process loads them in about a second.
An installer, a container build or a new worker runs this once, so that no user's first
frame waits.

:data:`PARTS` names the pieces (each a detection on a synthetic frame that takes every path
its method has, or the kernels several methods share); :func:`warm` compiles one in this
process, the command line all of them. ``agvsim warmup`` compiles these and the simulator's
kernels, in parallel processes; a part of :data:`AFTER` starts once the parts whose kernels it
calls have cached them, so that no kernel is compiled in two processes.
"""
from __future__ import annotations

import math
import sys
import time

__all__ = ["AFTER", "PARTS", "compile_part", "warm"]


def _frame():
    from localizer.model.camera import Camera
    from localizer.tools.synthetic import pose_at_column, render_frame

    camera = Camera.thesis(16.0)
    return camera, render_frame(camera, pose_at_column(camera, 3.0, math.radians(20.0)))


def edges() -> None:
    """The search (:func:`localizer._kernels.search.recognize`) and the measurement of a verified
    stack (:func:`localizer._kernels.measure.measure`, on the frame's pixels and on a window
    linearized through the sRGB inverse): the kernels the ``"exact"`` and the thesis method share."""
    from localizer.detect import SRGB_TO_LINEAR
    from localizer.measure.exact_pose import ExactSettings, exact_measure, exact_measure_lut
    from localizer.model.params import DetectionStats, DetectorParams
    from localizer.search.recognize import find_stacks
    from localizer.model.target import TargetSpec

    camera, image = _frame()
    p = DetectorParams().resolved(*image.shape)
    v = find_stacks(image, camera, TargetSpec(), p, DetectionStats())[1][0]
    settings = ExactSettings(0.05, 8, p.width_tolerance, p.width_slack, p.min_rows)
    exact_measure(image, camera, TargetSpec(), v, settings)
    box = (max(int(v.rows[0]) - 20, 0), int(v.rows[-1]) + 21, max(int(v.bounds[0]) - 15, 0), int(v.bounds[3]) + 16)
    exact_measure_lut(image, SRGB_TO_LINEAR, box, camera, TargetSpec(), v, settings)


def photometric() -> None:
    """The photometric refinement (:func:`localizer.measure.photometric.refine_pose`), on its own kernels."""
    from localizer.measure.photometric import refine_pose
    from localizer.model.target import TargetSpec

    camera, image = _frame()
    refine_pose(image, camera, TargetSpec(), (1.0, 3.0, 0.3, 0.0), True, 30.0)


def detector() -> None:
    """The edge-based (``"exact"``) detector and its photometric refinement, on the frame's
    pixels and on a target's neighbourhood linearized through the sRGB inverse (after
    :func:`edges` and :func:`photometric`: their kernels loaded from the cache)."""
    from localizer.detect import detect_targets

    camera, image = _frame()
    detect_targets(image, camera)
    detect_targets(image, camera, photometric="all")
    detect_targets(image, camera, response="srgb", photometric="all")


def thesis() -> None:
    """The thesis's row-scanning method (``method="thesis"``; after :func:`edges`)."""
    from localizer.detect import detect_targets

    camera, image = _frame()
    detect_targets(image, camera, method="thesis")
    detect_targets(image, camera, method="thesis", response="srgb")  # its exact check on a linearized window


def pyramid() -> None:
    """The area-averaged levels of large frames (:mod:`localizer._kernels.area`: both
    halvings, read from a window of the frame)."""
    import numpy as np

    from localizer.image.pyramid import level_image

    image = np.zeros((16, 16), np.uint8)
    level_image(image, 2)
    level_image(image, 4, (1, 1, 13, 13))


#: the parts, by name: ``"module:function"`` (importable in a fresh process), in the order they
#: are started
PARTS: dict[str, str] = {
    "edges": "localizer.warmup:edges",
    "photometric": "localizer.warmup:photometric",
    "pyramid": "localizer.warmup:pyramid",
    "detector": "localizer.warmup:detector",
    "thesis": "localizer.warmup:thesis",
}

#: the parts that call another's kernels, and those parts: started once those have finished (their
#: kernels then load from the cache rather than being compiled a second time in another process)
AFTER: dict[str, tuple[str, ...]] = {
    "detector": ("edges", "photometric"),
    "thesis": ("edges",),
}


def compile_part(spec: str) -> tuple[float, int]:
    """Run one part, ``"module:function"``, in this process (without the compile notice: the
    caller reports). Returns ``(seconds, compiled)``: the wall time and how many of the
    project's functions numba compiled (0 when every kernel came from the cache)."""
    import importlib

    from localizer._jit import CompileCounter, quiet_compile_notice

    quiet_compile_notice()
    module, function = spec.split(":")
    with CompileCounter() as counter:
        start = time.perf_counter()
        getattr(importlib.import_module(module), function)()
        return time.perf_counter() - start, counter.count


def warm(part: str) -> tuple[float, int]:
    """Compile (or load from the cache) one of :data:`PARTS` in this process:
    ``(seconds, compiled)`` as :func:`compile_part`."""
    from localizer.numeric import check_choice

    return compile_part(PARTS[check_choice("part", part, tuple(PARTS))])


def main() -> int:
    for part in PARTS:
        print(f"localizer warmup: {part}...", end=" ", file=sys.stderr, flush=True)
        seconds, compiled = warm(part)
        print(f"{seconds:.1f} s ({compiled} functions compiled)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
