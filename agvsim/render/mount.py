"""Where the camera sits on the vehicle, and the camera's pose in the map.

Frames:

* map: x east, y north, z up (m); vehicle pose ``(x, y, θ)``, θ CCW from +x.
* vehicle: x forward, y left, z up, origin at the vehicle's centre on the floor.
* camera (OpenCV, as in :mod:`localizer.camera`): x right, y down, z forward.
  With no jitter the optical axis is horizontal and image rows are level
  (thesis §3.5 assumption 1).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def _finite(name: str, value: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(float(value)):
        raise ValueError(f"CameraMount.{name} must be a finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class CameraMount:
    """The camera's place on the vehicle.

    Attributes:
        forward: offset of the lens centre ahead of the vehicle centre (m).
        lateral: offset to the vehicle's left (m).
        height: lens centre above the floor (m).
        yaw: optical axis direction relative to the vehicle's heading (rad, CCW):
            0 forward-looking, +pi/2 looking left, -pi/2 looking right.
        pitch_sigma: standard deviation of the per-frame pitch jitter (rad), 0 for none.
        roll_sigma: standard deviation of the per-frame roll jitter (rad), 0 for none.
    """

    forward: float = 0.4  # m
    lateral: float = 0.0  # m, left positive
    height: float = 1.2  # m above the floor
    yaw: float = 0.0  # rad, CCW from the vehicle's heading
    pitch_sigma: float = 0.0  # rad
    roll_sigma: float = 0.0  # rad

    def __post_init__(self) -> None:
        for name in ("forward", "lateral", "height", "yaw", "pitch_sigma", "roll_sigma"):
            object.__setattr__(self, name, _finite(name, getattr(self, name)))
        if self.height <= 0:
            raise ValueError(f"CameraMount.height must be above the floor (m > 0), got {self.height!r}")
        if self.pitch_sigma < 0 or self.roll_sigma < 0:
            raise ValueError("CameraMount.pitch_sigma and roll_sigma must be >= 0 (rad)")

    @classmethod
    def forward_looking(cls, height: float = 1.2, **kw) -> "CameraMount":
        """Camera at the front, looking ahead."""
        return cls(forward=0.4, lateral=0.0, height=height, yaw=0.0, **kw)

    @classmethod
    def side_looking(cls, side: str = "left", height: float = 1.2, **kw) -> "CameraMount":
        """Camera on the ``"left"`` or ``"right"`` flank, looking sideways."""
        if side not in ("left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {side!r}")
        s = 1.0 if side == "left" else -1.0
        return cls(forward=0.0, lateral=0.3 * s, height=height, yaw=s * math.pi / 2, **kw)

    # ----------------------------------------------------------------- poses
    def camera_pose(self, vehicle_pose) -> tuple[np.ndarray, float]:
        """Lens centre ``(3,)`` (m, map frame) and heading φ (rad) of the level camera.

        Raises:
            ValueError: ``vehicle_pose`` is not three finite numbers.
        """
        x, y, th = check_pose(vehicle_pose)
        c, s = math.cos(th), math.sin(th)
        pos = np.array([x + c * self.forward - s * self.lateral, y + s * self.forward + c * self.lateral,
                        self.height])
        return pos, th + self.yaw

    def vehicle_pose_for_camera(self, camera_xy, heading: float) -> tuple[float, float, float]:
        """The vehicle pose that puts the lens at ``camera_xy`` (m) looking along ``heading`` (rad)."""
        th = float(heading) - self.yaw
        c, s = math.cos(th), math.sin(th)
        x = float(camera_xy[0]) - (c * self.forward - s * self.lateral)
        y = float(camera_xy[1]) - (s * self.forward + c * self.lateral)
        return x, y, math.atan2(math.sin(th), math.cos(th))

    def draw_jitter(self, rng: np.random.Generator | None) -> tuple[float, float]:
        """``(pitch, roll)`` (rad) for one frame; zeros when the sigmas are 0 or ``rng`` is None."""
        if rng is None or (self.pitch_sigma == 0 and self.roll_sigma == 0):
            return 0.0, 0.0
        return float(rng.normal(0.0, self.pitch_sigma)), float(rng.normal(0.0, self.roll_sigma))


def check_pose(pose) -> tuple[float, float, float]:
    """``(x m, y m, θ rad)`` as floats; ValueError unless three finite numbers."""
    try:
        vals = np.asarray(pose, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"vehicle pose must be (x m, y m, theta rad), got {pose!r}") from None
    if vals.shape != (3,):
        raise ValueError(f"vehicle pose must be three numbers (x m, y m, theta rad), got {pose!r}")
    if not np.all(np.isfinite(vals)):
        raise ValueError(f"vehicle pose must be finite (x m, y m, theta rad), got {pose!r}")
    return float(vals[0]), float(vals[1]), float(vals[2])


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
        rot = level_rotation(heading) @ jitter_rotation(pitch, roll)
        return cls(pos, heading, rot, pitch, roll)

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
