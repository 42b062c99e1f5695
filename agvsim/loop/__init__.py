"""The loop layer: the closed loop (simulation + camera + filter), the route follower and the
one route driver with its one log type.

* :mod:`agvsim.loop.closed_loop`: :class:`ClosedLoop` (the one place a run is put together),
  :class:`LoopConfig`.
* :mod:`agvsim.loop.mission`: :func:`run_mission` with :class:`MissionConfig`
  (``steer_on="estimate" | "truth"``).
* :mod:`agvsim.loop.log`: :class:`MissionLog` and its records.
* :mod:`agvsim.loop.record`: :class:`MissionRecorder`, which keeps a run's log within
  :class:`RecordLimits` whatever the distance (a long run thinned, with totals over every step).
* :mod:`agvsim.loop.pure_pursuit`: the path follower.
* :mod:`agvsim.loop.modes`: the choice lists (localization modes, steer-on).

Names load on first use.
"""
from __future__ import annotations

from localizer.lazy import lazy_exports

_LAZY = {
    "ClosedLoop": "agvsim.loop.closed_loop",
    "LoopConfig": "agvsim.loop.closed_loop",
    "LoopStep": "agvsim.loop.closed_loop",
    "FusedFrame": "agvsim.loop.closed_loop",
    "filter_config_for": "agvsim.loop.closed_loop",
    "odometry_noise_for": "agvsim.loop.closed_loop",
    "MissionConfig": "agvsim.loop.mission",
    "run_mission": "agvsim.loop.mission",
    "Arrival": "agvsim.loop.log",
    "FrameRecord": "agvsim.loop.log",
    "MissionLog": "agvsim.loop.log",
    "ObservationRecord": "agvsim.loop.log",
    "StepTotals": "agvsim.loop.log",
    "EventTotals": "agvsim.loop.log",
    "MissionRecorder": "agvsim.loop.record",
    "RecordLimits": "agvsim.loop.record",
    "FollowerParams": "agvsim.loop.pure_pursuit",
    "PurePursuit": "agvsim.loop.pure_pursuit",
    "RoutePath": "agvsim.loop.pure_pursuit",
    "LOCALIZATION_MODES": "agvsim.loop.modes",
    "STEER_ON": "agvsim.loop.modes",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
