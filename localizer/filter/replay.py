"""The frames a tracking filter keeps for its re-localization (:mod:`localizer.filter.ekf`).

While tracking, the filter keeps the frames since the last one with an accepted observation:
the odometry between them and their measurements. On becoming lost it replays them into the
re-localization first, so the detections that were refused are the first evidence (a kidnapped
vehicle has often seen two targets by the time it knows it is lost).
"""
from __future__ import annotations

from collections import deque

import numpy as np

__all__ = ["RecentFrames"]


class RecentFrames:
    """At most ``frames`` entries ``[u (3,) m, m, rad; Q (3, 3); measurements]``, oldest first."""

    def __init__(self, frames: int) -> None:
        self._entries: deque = deque(maxlen=frames)
        self._last_motion = None  # the entry the last motion() made, for the frame that follows

    def motion(self, u: np.ndarray, Q: np.ndarray) -> None:
        """Keep an odometry increment ``u`` with covariance ``Q`` (a flush of the filter)."""
        self._last_motion = [u, Q, ()]
        self._entries.append(self._last_motion)

    def no_motion(self) -> None:
        """A flush that moved nothing: the next frame's measurements get their own entry."""
        self._last_motion = None

    def measured(self, ms) -> None:
        """Keep a frame's measurements ``ms``, with the motion just before them if any."""
        if self._last_motion is not None and self._entries and self._entries[-1] is self._last_motion:
            self._last_motion[2] = ms
        else:
            self._entries.append([np.zeros(3), np.zeros((3, 3)), ms])

    def clear(self) -> None:
        """Forget them (a frame fitted: the replay starts after it)."""
        self._entries.clear()

    def replay(self, relocalizer) -> None:
        """Feed them to ``relocalizer`` (its ``predict(u, Q)`` and ``process(ms)``), then forget them."""
        for u, Q, ms in self._entries:
            relocalizer.predict(u, Q)
            if ms:
                relocalizer.process(ms)
        self._entries.clear()
