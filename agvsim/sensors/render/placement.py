"""Poses that put a map target at a chosen (d, α, β) in front of the camera (tests, benchmarks)."""
from __future__ import annotations

import math

import numpy as np

from localizer.numeric import check_number

from agvsim.sensors.render.mount import CameraMount


def camera_pose_facing(target, distance: float, alpha: float, beta: float = 0.0) -> tuple[np.ndarray, float]:
    """Lens position ``(2,)`` (m) and heading (rad) of a level camera that sees ``target``
    at horizontal distance ``distance`` (m), bearing ``beta`` and angle ``alpha`` (rad,
    thesis conventions: see :mod:`localizer.model.geometry`).

    In the camera frame the target normal pointing away from the camera is
    ``(sin α, 0, cos α)``; the map normal faces the camera, so the heading is the
    direction of ``-normal`` turned by ``alpha`` (CCW is to the camera's left).
    """
    check_number("alpha", alpha, unit="rad")
    check_number("beta", beta, unit="rad")
    check_number("distance", distance, low=0.0, low_open=True, unit="m")
    psi = math.atan2(-float(target.normal[1]), -float(target.normal[0]))
    heading = psi + alpha
    bearing = heading - beta  # map direction from the lens to the target centre
    pos = np.asarray(target.position, float) - distance * np.array([math.cos(bearing), math.sin(bearing)])
    return pos, heading


def vehicle_pose_for_target(mount: CameraMount, target, distance: float, alpha: float,
                            beta: float = 0.0) -> tuple[float, float, float]:
    """The vehicle pose ``(x, y, θ)`` whose camera (``mount``) sees ``target`` at ``(d, α, β)``."""
    pos, heading = camera_pose_facing(target, distance, alpha, beta)
    return mount.vehicle_pose_for_camera(pos, heading)
