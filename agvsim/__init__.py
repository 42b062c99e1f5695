"""agvsim: a plant-floor simulator for vision-guided AGV navigation.

Import-light on purpose: ``import agvsim`` loads neither numpy, pymunk nor
OpenGL. The names below are imported on first use.

    >>> import numpy as np, agvsim
    >>> floor = agvsim.load_map("plant_floor")
    >>> config = agvsim.MissionConfig(sim=agvsim.SimConfig(odometry=agvsim.OdometryErrorModel.preset("worn")),
    ...                               vision=False, steer_on="truth", laps=2)
    >>> log = agvsim.run_mission(floor, None, np.random.default_rng(0), config)

Layers (data flows one way; ``ARCHITECTURE.md``): :mod:`agvsim.world` (maps) →
:mod:`agvsim.vehicle` (physics, encoders, odometry) → :mod:`agvsim.sensors`
(observation sources, renderer) → :mod:`agvsim.loop` (closed loop, mission) →
:mod:`agvsim.analysis` (metrics, plots) and the ``agvsim`` command.
"""
from __future__ import annotations

from localizer.lazy import lazy_exports

#: public name -> module that defines it (imported lazily, PEP 562).
_LAZY = {
    # maps
    "load_map": "agvsim.world.loader",
    "shipped_maps": "agvsim.world.loader",
    "Map": "agvsim.world.map",
    "MapError": "agvsim.world.loader",
    # vehicle
    "SimConfig": "agvsim.vehicle.simulation",
    "Simulation": "agvsim.vehicle.simulation",
    "OdometryErrorModel": "agvsim.vehicle.encoders",
    "ODOMETRY_PRESETS": "agvsim.vehicle.encoders:PRESETS",
    # sensors
    "CameraMount": "localizer.model.mount",
    "VisionConfig": "agvsim.sensors.vision",
    "SOURCES": "agvsim.sensors.registry",
    "make_source": "agvsim.sensors.registry",
    "GeometricNoise": "agvsim.sensors.geometric",
    "GeometricSource": "agvsim.sensors.geometric",
    "SyntheticFrameSource": "agvsim.sensors.synthetic",
    "RenderedSource": "agvsim.sensors.rendered",
    # loop
    "ClosedLoop": "agvsim.loop.closed_loop",
    "LoopConfig": "agvsim.loop.closed_loop",
    "LOCALIZATION_MODES": "agvsim.loop.modes",
    "STEER_ON": "agvsim.loop.modes",
    "MissionConfig": "agvsim.loop.mission",
    "MissionLog": "agvsim.loop.log",
    "run_mission": "agvsim.loop.mission",
    # analysis
    "run_metrics": "agvsim.analysis.evaluate",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
