"""The vehicle layer: pymunk world and chassis, wheel encoders, dead reckoning, the stepped simulation.

Data flows one way: a map (:mod:`agvsim.world`) becomes a pymunk space
(:mod:`~agvsim.vehicle.physics`); the chassis (:mod:`~agvsim.vehicle.dynamics`)
moves in it; the encoders (:mod:`~agvsim.vehicle.encoders`) read the true wheel
motion with errors; dead reckoning (:mod:`~agvsim.vehicle.odometry`) integrates
the counts; :class:`~agvsim.vehicle.simulation.Simulation` steps all of it at the
control rate. Names load on first use (no pymunk at ``import agvsim.vehicle``).
"""
from __future__ import annotations

from localizer.lazy import lazy_exports

_LAZY = {
    "DiffDriveVehicle": "agvsim.vehicle.dynamics",
    "VehicleParams": "agvsim.vehicle.dynamics",
    "EncoderModel": "agvsim.vehicle.encoders",
    "OdometryErrorModel": "agvsim.vehicle.encoders",
    "PRESETS": "agvsim.vehicle.encoders",
    "WheelTicks": "agvsim.vehicle.encoders",
    "DeadReckoning": "agvsim.vehicle.odometry",
    "SimConfig": "agvsim.vehicle.simulation",
    "Simulation": "agvsim.vehicle.simulation",
    "StepResult": "agvsim.vehicle.simulation",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
