"""Camera frames of wall targets: a compiled raycaster (default) or pyrender (the reference).

Importing this package imports neither pyrender, OpenGL nor numba; the pyrender backend
opens its GL context when its first frame is rendered (:mod:`agvsim.sensors.render.gl`).

    >>> import numpy as np
    >>> from agvsim.world import load_map
    >>> from agvsim.sensors.render import CameraRenderer, CameraMount, RenderConditions
    >>> r = CameraRenderer(load_map("plant_floor"), mount=CameraMount(height=1.2))
    >>> image, truth = r.render((30.0, 4.0, -1.5708), RenderConditions(lighting="bright"),
    ...                         np.random.default_rng(0))
    >>> truth.to_dict()["targets"][0]["distance"]

Modules: ``renderer`` (``CameraRenderer``; the backends' list is :mod:`agvsim.sensors.backends`), ``raycast`` (+ its
kernels and ``ray_records``), ``pyrender_backend`` and ``gl`` (headless platform),
``scene``, ``textures``, ``lighting``, ``mount``, ``sensor``, ``truth``, ``strip`` (demo strip).
"""
from __future__ import annotations

from localizer.lazy import lazy_exports

_LAZY = {
    "CameraRenderer": "agvsim.sensors.render.renderer",
    "RenderConditions": "agvsim.sensors.render.renderer",
    "CameraMount": "agvsim.sensors.render.mount",
    "CameraPose": "agvsim.sensors.render.mount",
    "SensorModel": "agvsim.sensors.render.sensor",
    "GLContext": "agvsim.sensors.render.gl",
    "RenderUnavailable": "agvsim.sensors.render.gl",
    "FrameTruth": "agvsim.sensors.render.truth",
    "TargetTruth": "agvsim.sensors.render.truth",
    "LIGHTING_LEVELS": "agvsim.sensors.render.lighting",
    "build_scene": "agvsim.sensors.render.scene",
    "save_camera_strip": "agvsim.sensors.render.strip",
    "camera_pose_facing": "agvsim.sensors.render.placement",
    "vehicle_pose_for_target": "agvsim.sensors.render.placement",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
