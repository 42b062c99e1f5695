"""The raycaster's kernels compiled ahead of their first frame (a part of ``agvsim warmup``).

:func:`raycaster` renders a few frames of the default map that between them take every path
of the frame kernels: the scene, the floor pass, the truth table, sensor noise, motion blur,
a depth-dependent defocus and the RGB output. In a fresh install that compiles them (about half
a minute of one core: 74 functions, most of it LLVM optimising the column pass, into which the
per-column and per-span helpers are inlined); once they are cached it takes about a second.
"""
from __future__ import annotations

__all__ = ["raycaster"]


def raycaster() -> None:
    """Render the frames that compile every raycaster kernel (module docstring)."""
    import numpy as np

    from agvsim.sensors.render.mount import CameraMount
    from agvsim.sensors.render.renderer import CameraRenderer, RenderConditions
    from agvsim.world import load_map

    renderer = CameraRenderer(load_map("plant_floor"), mount=CameraMount(height=1.2))
    rng = np.random.default_rng(0)
    pose = (30.0, 4.0, -1.5708)
    for conditions in (RenderConditions(),
                       RenderConditions(velocity=(1.0, 0.3), rgb=True),
                       RenderConditions(defocus_px=1.0, focus_distance=2.0)):
        _, truth = renderer.render(pose, conditions, rng)
        truth.to_dict()
    renderer.close()
