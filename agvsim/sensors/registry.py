"""The observation sources by name: the one list that CLI choices, env validation and docs use.

Light on purpose (no NumPy): ``agvsim --help`` reads :data:`SOURCES` without
importing a source. A name maps to ``"module:Class"``; :func:`make_source`
imports the class on first use.

Adding a sensor: write a class that satisfies
:class:`agvsim.sensors.base.ObservationSource` in its own module under
``agvsim/sensors/`` and add one line here.
"""
from __future__ import annotations

import importlib

__all__ = ["SOURCES", "SOURCE_HELP", "make_source", "source_class"]

#: name -> "module:Class" of the source.
_ENTRY_POINTS: dict[str, str] = {
    "rendered": "agvsim.sensors.rendered:RenderedSource",
    "synthetic": "agvsim.sensors.synthetic:SyntheticFrameSource",
    "geometric": "agvsim.sensors.geometric:GeometricSource",
}

#: name -> one line for --help and docs.
SOURCE_HELP: dict[str, str] = {
    "rendered": "camera frames of the scene at the true pose (raycaster or pyrender), targets found by the localizer (the real thing)",
    "synthetic": "each visible target warped onto a plain background, found by the localizer (no scene)",
    "geometric": "true (d, beta, alpha) of the visible targets plus noise from a fitted covariance model (fast)",
}

#: The source names, in the order --help lists them.
SOURCES: tuple[str, ...] = tuple(_ENTRY_POINTS)


def source_class(name: str) -> type:
    """The class registered as ``name`` (one of :data:`SOURCES`)."""
    from localizer.numeric import check_choice

    check_choice("observation source", name, SOURCES)
    module, cls = _ENTRY_POINTS[name].split(":")
    return getattr(importlib.import_module(module), cls)


def make_source(name: str, world_map, vision=None, **kw):
    """A new source called ``name`` on ``world_map`` with ``vision``
    (:class:`~agvsim.sensors.vision.VisionConfig`; None: the map's recommended mount,
    16 mm lens); ``kw`` are the source's own options."""
    return source_class(name)(world_map, vision, **kw)
