"""What every observation source is: the :class:`ObservationSource` protocol and its observation type.

A source reports what the camera sees at one frame. It sees the *true* pose
(the camera is where the vehicle really is); the filter never does.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

__all__ = ["ObservationSource", "SimObservation"]


@dataclass(frozen=True)
class SimObservation:
    """An observation from a simulated source (same fields the filter reads from a
    :class:`localizer.TargetObservation`).

    ``truth_id``: the map target really seen (None for a false detection); for evaluation only.
    """

    distance: float  # m
    beta: float  # rad, > 0 when the target centre is right of the optical axis
    alpha: float  # rad, > 0 when the target's right edge is nearer the camera
    covariance: np.ndarray  # (3, 3) over (d, β, α): m², rad²
    polarity: str
    truth_id: str | None = None


@runtime_checkable
class ObservationSource(Protocol):
    """The camera of the closed loop, one frame at a time.

    Attributes:
        name: the registry name (:data:`agvsim.sensors.registry.SOURCES`).
        draws_frames: the source makes camera images (:attr:`last_frame` is set after a frame).
        has_exposure: the source's frames follow :meth:`set_exposure`.
        last_frame: the latest image ((H, W) uint8), or None.
    """

    name: ClassVar[str]
    draws_frames: ClassVar[bool]
    has_exposure: ClassVar[bool]
    last_frame: np.ndarray | None

    def observe(self, true_pose, rng: np.random.Generator,
                command: tuple[float, float] = (0.0, 0.0)) -> list[SimObservation]:
        """The targets seen from the vehicle at ``true_pose`` (x m, y m, θ rad) while it
        drives with ``command`` (v m/s, ω rad/s, for motion blur); noise from ``rng``."""
        ...

    def set_exposure(self, factor: float) -> None:
        """Scale the exposure of the following frames (1 = nominal); a no-op where
        :attr:`has_exposure` is False."""
        ...
