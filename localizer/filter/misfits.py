"""Misfitting detections placed in the map: do they line up frame after frame?

One real target seen from a wrong estimate stays put in the map, as odometry moves the estimate
with the vehicle; false detections do not line up (:mod:`localizer.filter.ekf`, lost by misfits).
A detection that, placed from the estimate, lands on a map target of its polarity facing its way
is explained by the map, whatever the gate said (a target seen beyond the view limits the filter
predicts with, steeper or nearer the image border): it is no misfit (:func:`explained_by_map`).
"""
from __future__ import annotations

import math

from localizer.numeric import wrap_angle

__all__ = ["MisfitWatch", "explained_by_map", "line_up", "place"]


def place(m, camera_pose) -> tuple[float, float, float]:
    """Where the measurement ``m`` (``z = (d m, β rad, α rad)``) puts its target in the map from
    the camera pose ``(lens (x, y) m, heading φ rad)``: ``(x m, y m, facing rad)``."""
    lens, phi = camera_pose
    d, beta, alpha = float(m.z[0]), float(m.z[1]), float(m.z[2])
    yaw = phi - alpha - math.pi  # the way the target faces (h(x), localizer.filter.measurement)
    return lens[0] + d * math.cos(phi - beta), lens[1] + d * math.sin(phi - beta), yaw


def explained_by_map(m, camera_pose, targets, radius: float, max_yaw: float) -> bool:
    """Whether ``m``, placed in the map from ``camera_pose`` (:func:`place`), lands on a target of
    ``targets`` (a :class:`~localizer.filter.measurement.TargetMap`) of its polarity (or of unknown
    polarity) facing its way: within ``radius`` (m) of it, or within 3 sigma of the place when the
    measurement is looser (``m.R``: sd of d, and d times sd of beta), and facing within
    ``max_yaw`` (rad), or 3 sigma of alpha (a far, steep target's alpha may be known to tens of
    degrees: its facing then tells nothing)."""
    px, py, yaw = place(m, camera_pose)
    d = float(m.z[0])
    sd_d, sd_beta, sd_alpha = (math.sqrt(max(float(m.R[i][i]), 0.0)) for i in range(3))
    r2 = max(radius, 3.0 * math.hypot(sd_d, d * sd_beta)) ** 2
    max_yaw = max(max_yaw, 3.0 * sd_alpha)
    for j in range(len(targets)):
        pol = targets.polarities[j]
        if pol is not None and m.polarity is not None and pol != m.polarity:
            continue
        tx, ty = targets.positions[j]
        if (tx - px) ** 2 + (ty - py) ** 2 <= r2 and abs(wrap_angle(yaw - float(targets.yaws[j]))) <= max_yaw:
            return True
    return False


def line_up(ms, camera_pose, past, k: int, radius: float, max_yaw: float) -> list[tuple]:
    """The entries of frame ``k``'s misfitting measurements ``ms``.

    Args:
        ms: measurements (``z = (d m, β rad, α rad)``, ``polarity``).
        camera_pose: ``(lens (x, y) m, heading φ rad)`` of the camera from the estimate.
        past: the entries of the frames before (``(x m, y m, yaw rad, polarity, support, frame)``).
        k: this frame's number. radius: m, max_yaw: rad: how near an entry of ``past`` must be
            (same polarity, within ``radius``, facing within ``max_yaw``) to support one of these.
    Returns:
        one entry per measurement: its place and facing in the map, polarity, ``support`` (1 +
        the best support among the past entries near it: the frames in a row it lines up over)
        and ``k``.
    """
    r2 = radius ** 2
    now = []
    for m in ms:
        px, py, yaw = place(m, camera_pose)
        support = 1 + max((n for (qx, qy, qyaw, pol, n, _) in past
                           if pol == m.polarity and (qx - px) ** 2 + (qy - py) ** 2 <= r2
                           and abs(wrap_angle(yaw - qyaw)) <= max_yaw), default=0)
        now.append((px, py, yaw, m.polarity, support, k))
    return now


class MisfitWatch:
    """The main filter's watch on grossly misfitting detections (:mod:`localizer.filter.ekf`):
    over how many frames in a row (one skipped allowed) those the map does not explain line up.

    Args:
        targets: the map's targets (:class:`~localizer.filter.measurement.TargetMap`).
        d2: D² above which a refused detection misfits grossly.
        radius: m, max_yaw: rad: how near two frames' misfits must lie, and face, to line up.
    """

    def __init__(self, targets, d2: float, radius: float, max_yaw: float) -> None:
        self.targets = targets
        self.d2, self.radius, self.max_yaw = d2, radius, max_yaw
        self.frames = 0  # the longest line-up (frames)
        # since the last clear: (x m, y m, facing rad, polarity, support frames, misfit frame number)
        self._entries: list[tuple[float, float, float, str | None, int, int]] = []
        self._count = 0  # frames with misfitting detections so far

    def clear(self) -> None:
        """Forget the misfits so far (a frame fitted, or the filter recovered)."""
        self.frames = 0
        self._entries.clear()

    def observe(self, ms, assoc, camera_pose) -> None:
        """Add a frame with no accepted observation: its measurements ``ms``, their associations
        ``assoc``, the camera pose ``(lens (x, y) m, heading φ rad)`` from the estimate."""
        gross = [ms[a.observation] for a in assoc if a.d2 > self.d2]
        gross = [m for m in gross if not explained_by_map(m, camera_pose, self.targets, self.radius, self.max_yaw)]
        if not gross:
            return
        self._count += 1
        past = [e for e in self._entries if e[5] >= self._count - 2]  # the two frames before this one
        now = line_up(gross, camera_pose, past, self._count, self.radius, self.max_yaw)
        self.frames = max([self.frames] + [e[4] for e in now])
        self._entries = now + past
