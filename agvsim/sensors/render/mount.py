"""The camera's pose in the map for one frame (the mount itself is :class:`localizer.model.mount.CameraMount`).

Frames:

* map: x east, y north, z up (m); vehicle pose ``(x, y, θ)``, θ CCW from +x.
* vehicle: x forward, y left, z up, origin at the vehicle's centre on the floor.
* camera (OpenCV, as in :mod:`localizer.model.camera`): x right, y down, z forward.
  With no jitter the optical axis is horizontal and image rows are level
  (thesis §3.5 assumption 1).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.model.mount import CameraMount, check_pose

__all__ = ["CameraMount", "CameraPose", "check_pose", "jitter_rotation", "level_rotation", "rotation_from_vector"]


def level_rotation(heading: float) -> np.ndarray:
    """``(3, 3)`` camera-to-map rotation of a level camera looking along ``heading`` (rad).

    Columns: camera x (right), y (down), z (forward) in map coordinates.
    """
    c, s = math.cos(heading), math.sin(heading)
    return np.array([[s, 0.0, c], [-c, 0.0, s], [0.0, -1.0, 0.0]])


def jitter_rotation(pitch: float, roll: float) -> np.ndarray:
    """``(3, 3)`` rotation of the actual camera in the level camera's frame.

    ``pitch`` > 0 tilts the optical axis up (rotation about camera x);
    ``roll`` > 0 rotates the image clockwise as seen by the camera (about camera z).
    """
    cp, sp = math.cos(pitch), math.sin(pitch)
    cr, sr = math.cos(roll), math.sin(roll)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    rz = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
    return rx @ rz


def rotation_from_vector(rvec) -> np.ndarray:
    """``(3, 3)`` rotation of the rotation vector ``rvec`` (axis x angle, rad): Rodrigues' formula
    ``cos θ I + (1 - cos θ) r rᵀ + sin θ [r]ₓ`` with ``r`` the unit axis, identity below
    ``DBL_EPSILON``. OpenCV's ``cv2.Rodrigues`` to the last bit (the same operations in the same
    order; tested), without importing OpenCV into a process that needs nothing else of it."""
    x, y, z = (float(v) for v in np.ravel(rvec))
    theta = math.sqrt(x * x + y * y + z * z)
    if theta < 2.220446049250313e-16:
        return np.eye(3)
    c, s = math.cos(theta), math.sin(theta)
    c1 = 1.0 - c
    inv = 1.0 / theta
    x, y, z = x * inv, y * inv, z * inv
    rrt = np.array([[x * x, x * y, x * z], [x * y, y * y, y * z], [x * z, y * z, z * z]])
    r_x = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return c * np.eye(3) + c1 * rrt + s * r_x


@dataclass(frozen=True)
class CameraPose:
    """The camera's pose for one frame.

    Attributes:
        position: ``(3,)`` lens centre in the map (m).
        heading: level optical axis direction (rad, CCW from +x).
        rotation: ``(3, 3)`` camera-to-map rotation (columns x right, y down, z forward),
            jitter included.
        pitch, roll: the jitter drawn for this frame (rad).
    """

    position: np.ndarray  # (3,) m
    heading: float  # rad
    rotation: np.ndarray  # (3, 3)
    pitch: float = 0.0  # rad
    roll: float = 0.0  # rad

    @classmethod
    def from_vehicle(cls, mount: CameraMount, vehicle_pose, pitch: float = 0.0, roll: float = 0.0) -> "CameraPose":
        pos, heading = mount.camera_pose(vehicle_pose)
        no_jitter = pitch == 0.0 and roll == 0.0 and math.copysign(1.0, pitch) > 0.0 and math.copysign(1.0, roll) > 0.0
        if no_jitter:
            # level_rotation(heading) @ jitter_rotation(0.0, 0.0) (the identity, its -sin 0 entries
            # +0.0) without the product: each entry of that product is one entry of the level
            # rotation plus zeros, exact, and a zero sum is +0.0 (every row holds a +0.0), so it
            # is the level rotation with -0.0 made +0.0 (x + 0.0), bit for bit
            rot = level_rotation(heading) + 0.0
        else:
            rot = level_rotation(heading) @ jitter_rotation(pitch, roll)
        pose = object.__new__(cls)  # frozen: filled without __init__'s five object.__setattr__ calls
        object.__setattr__(pose, "__dict__", {"position": pos, "heading": heading, "rotation": rot,
                                              "pitch": pitch, "roll": roll})
        return pose

    def to_camera(self, points_map) -> np.ndarray:
        """``(..., 3)`` map points (m) -> camera frame (m)."""
        p = np.asarray(points_map, dtype=float)
        return (p - self.position) @ self.rotation

    def to_level_camera(self, points_map) -> np.ndarray:
        """``(..., 3)`` map points (m) -> the level (jitter-free) camera frame (m)."""
        p = np.asarray(points_map, dtype=float)
        return (p - self.position) @ level_rotation(self.heading)

    def gl_pose(self) -> np.ndarray:
        """``(4, 4)`` camera-to-map transform in OpenGL's camera convention (x right, y up, z back)."""
        m = np.eye(4)
        m[:3, :3] = self.rotation @ np.diag([1.0, -1.0, -1.0])
        m[:3, 3] = self.position
        return m
