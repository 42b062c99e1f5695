"""Dead reckoning from wheel encoder counts with the *nominal* parameters.

Integration is exact for a constant-curvature arc over each update
(Δs along the arc, Δθ heading change)::

    x += Δs * sinc(Δθ/2) * cos(θ + Δθ/2)
    y += Δs * sinc(Δθ/2) * sin(θ + Δθ/2)
    θ += Δθ

with ``sinc(u) = sin(u)/u``, Δs = (s_R + s_L)/2 and Δθ = (s_R - s_L)/b.
"""
from __future__ import annotations

import math
from agvsim.vehicle.encoders import WheelTicks


def arc_chord_factor(half_angle: float) -> float:
    """sin(u)/u, the chord-to-arc ratio of an arc turning 2u (rad)."""
    if abs(half_angle) < 1e-4:
        return 1.0 - half_angle * half_angle / 6.0
    return math.sin(half_angle) / half_angle


class DeadReckoning:
    """Integrates encoder counts into a pose with the nominal wheel radius
    and wheelbase.

    Args:
        pose: initial pose (x m, y m, θ rad), usually the known start station.
        wheel_radius: nominal wheel radius (m).
        track_width: nominal wheelbase (m).
        counts_per_rad: encoder counts per radian of wheel rotation.
        ticks: the encoder reading at start.
    """

    def __init__(self, pose: tuple[float, float, float], wheel_radius: float,
                 track_width: float, counts_per_rad: float, ticks: WheelTicks) -> None:
        self.x, self.y, self.theta = (float(p) for p in pose)
        self._metres_per_count = wheel_radius / counts_per_rad
        self._track = track_width
        self._last_left = ticks.left
        self._last_right = ticks.right
        self._acc_ds = 0.0
        self._acc_dtheta = 0.0
        self.distance = 0.0  # m, total |Δs| integrated

    @property
    def pose(self) -> tuple[float, float, float]:
        """Dead-reckoned (x m, y m, θ rad), θ unwrapped."""
        return (self.x, self.y, self.theta)

    def update(self, ticks: WheelTicks) -> None:
        """Integrate the counts since the previous reading."""
        self.update_counts(ticks.left, ticks.right)

    def update_counts(self, left: float, right: float) -> None:
        """Integrate cumulative counts (left, right) since the previous reading."""
        self.update_steps((left,), (right,))

    def update_steps(self, lefts: list, rights: list) -> None:
        """:meth:`update_counts` for each reading (cumulative counts) of a control step, in one loop."""
        per_count, track = self._metres_per_count, self._track
        last_left, last_right = self._last_left, self._last_right
        x, y, theta = self.x, self.y, self.theta
        acc_ds, acc_dtheta, distance = self._acc_ds, self._acc_dtheta, self.distance
        cos, sin = math.cos, math.sin
        for left, right in zip(lefts, rights):
            s_left = (left - last_left) * per_count
            s_right = (right - last_right) * per_count
            last_left, last_right = left, right
            ds = 0.5 * (s_left + s_right)
            dtheta = (s_right - s_left) / track
            half = 0.5 * dtheta
            chord = ds * (1.0 - half * half / 6.0 if abs(half) < 1e-4 else sin(half) / half)  # arc_chord_factor
            heading = theta + half
            x += chord * cos(heading)
            y += chord * sin(heading)
            theta += dtheta
            acc_ds += ds
            acc_dtheta += dtheta
            distance += abs(ds)
        self._last_left, self._last_right = last_left, last_right
        self.x, self.y, self.theta = x, y, theta
        self._acc_ds, self._acc_dtheta, self.distance = acc_ds, acc_dtheta, distance

    def take_increment(self) -> tuple[float, float]:
        """(Δs m, Δθ rad) integrated since the last call: what a real AGV controller sees
        each control step (Δs negative when reversing)."""
        inc = (self._acc_ds, self._acc_dtheta)
        self._acc_ds = 0.0
        self._acc_dtheta = 0.0
        return inc


__all__ = ["DeadReckoning", "arc_chord_factor"]
