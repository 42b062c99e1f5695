"""Camera frames of wall targets, rendered with pyrender (issue 4).

Importing this package imports neither pyrender nor OpenGL; the GL context is
opened when the first frame is rendered (:mod:`agvsim.render.gl`).

    >>> import numpy as np
    >>> from agvsim.world.map import load_map
    >>> from agvsim.render import CameraRenderer, CameraMount, RenderConditions
    >>> r = CameraRenderer(load_map("plant_floor"), mount=CameraMount(height=1.2))
    >>> image, truth = r.render((30.0, 4.0, -1.5708), RenderConditions(lighting="bright"),
    ...                         np.random.default_rng(0))
    >>> truth.to_dict()["targets"][0]["distance"]

Modules: ``gl`` (headless platform), ``textures``, ``scene``, ``lighting``,
``mount``, ``sensor``, ``truth``, ``renderer``, ``strip`` (demo strip of frames).
"""
from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "CameraRenderer": "agvsim.render.renderer",
    "RenderConditions": "agvsim.render.renderer",
    "CameraMount": "agvsim.render.mount",
    "CameraPose": "agvsim.render.mount",
    "SensorModel": "agvsim.render.sensor",
    "GLContext": "agvsim.render.gl",
    "RenderUnavailable": "agvsim.render.gl",
    "FrameTruth": "agvsim.render.truth",
    "TargetTruth": "agvsim.render.truth",
    "LIGHTING_LEVELS": "agvsim.render.lighting",
    "build_scene": "agvsim.render.scene",
    "save_camera_strip": "agvsim.render.strip",
    "camera_pose_facing": "agvsim.render.placement",
    "vehicle_pose_for_target": "agvsim.render.placement",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'agvsim.render' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
