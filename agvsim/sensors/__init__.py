"""Sensors: what the vehicle's camera reports (observation sources) and how frames are made.

* :mod:`agvsim.sensors.registry`: the sources by name (:data:`SOURCES`, :func:`make_source`).
* :mod:`agvsim.sensors.base`: the :class:`ObservationSource` protocol, :class:`SimObservation`.
* :mod:`agvsim.sensors.vision`: the camera on the vehicle (:class:`VisionConfig`), visibility.
* :mod:`agvsim.sensors.geometric`, :mod:`~agvsim.sensors.synthetic`,
  :mod:`~agvsim.sensors.rendered`: the sources.
* :mod:`agvsim.sensors.render`: the renderer backend of the ``rendered`` source (pyrender).

Importing this package opens no OpenGL context and imports no source module.
"""
from __future__ import annotations

from localizer.lazy import lazy_exports

from agvsim.sensors.registry import SOURCES, make_source, source_class

_LAZY = {
    "BACKENDS": "agvsim.sensors.backends",
    "ObservationSource": "agvsim.sensors.base",
    "SimObservation": "agvsim.sensors.base",
    "VisionConfig": "agvsim.sensors.vision",
    "LENSES_MM": "agvsim.sensors.vision",
    "targets_from_map": "agvsim.sensors.vision",
    "visible_targets": "agvsim.sensors.vision",
    "GeometricNoise": "agvsim.sensors.geometric",
    "GeometricSource": "agvsim.sensors.geometric",
    "SyntheticFrameSource": "agvsim.sensors.synthetic",
    "RenderedSource": "agvsim.sensors.rendered",
}

__all__ = sorted([*_LAZY, "SOURCES", "make_source", "source_class"])

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
