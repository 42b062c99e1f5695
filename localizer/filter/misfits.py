"""Misfitting detections placed in the map: do they line up frame after frame?

One real target seen from a wrong estimate stays put in the map, as odometry moves the estimate
with the vehicle; false detections do not line up (:mod:`localizer.filter.ekf`, lost by misfits).
"""
from __future__ import annotations

import math

from localizer.numeric import wrap_angle

__all__ = ["line_up"]


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
    lens, phi = camera_pose
    r2 = radius ** 2
    now = []
    for m in ms:
        d, beta, alpha = float(m.z[0]), float(m.z[1]), float(m.z[2])
        px, py = lens[0] + d * math.cos(phi - beta), lens[1] + d * math.sin(phi - beta)
        yaw = phi - alpha - math.pi  # the way the target faces (h(x), localizer.filter.measurement)
        support = 1 + max((n for (qx, qy, qyaw, pol, n, _) in past
                           if pol == m.polarity and (qx - px) ** 2 + (qy - py) ** 2 <= r2
                           and abs(wrap_angle(yaw - qyaw)) <= max_yaw), default=0)
        now.append((px, py, yaw, m.polarity, support, k))
    return now
