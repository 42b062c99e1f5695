"""Where the camera sits on the vehicle: the project's one camera-mount type.

Frames:

* map: x east, y north, z up (m); vehicle pose ``(x, y, θ)``, θ CCW from +x.
* vehicle: x forward, y left, z up, origin at the vehicle's centre on the floor.
* camera (OpenCV, as in :mod:`localizer.model.camera`): x right, y down, z forward.
  With no jitter the optical axis is horizontal and image rows are level
  (thesis §3.5 assumption 1).

The pose filter (:mod:`localizer.filter`) reads ``forward``, ``lateral`` and
``yaw`` (the top view); the renderer also reads ``height`` and the jitter.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.numeric import check_number, wrap_angle

__all__ = ["CameraMount", "check_pose"]


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
            object.__setattr__(self, name, check_number(f"CameraMount.{name}", getattr(self, name)))
        check_number("CameraMount.height", self.height, low=0.0, low_open=True, unit="m above the floor")
        check_number("CameraMount.pitch_sigma", self.pitch_sigma, low=0.0, unit="rad")
        check_number("CameraMount.roll_sigma", self.roll_sigma, low=0.0, unit="rad")

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
        return x, y, wrap_angle(th)

    def draw_jitter(self, rng: np.random.Generator | None) -> tuple[float, float]:
        """``(pitch, roll)`` (rad) for one frame; zeros when the sigmas are 0 or ``rng`` is None."""
        if rng is None or (self.pitch_sigma == 0 and self.roll_sigma == 0):
            return 0.0, 0.0
        return float(rng.normal(0.0, self.pitch_sigma)), float(rng.normal(0.0, self.roll_sigma))


def check_pose(pose) -> tuple[float, float, float]:
    """``(x m, y m, θ rad)`` as floats; ValueError unless three finite numbers."""
    if type(pose) is tuple and len(pose) == 3:  # the common case, per frame: three finite floats
        x, y, th = pose
        if isinstance(x, float) and isinstance(y, float) and isinstance(th, float) and \
                math.isfinite(x) and math.isfinite(y) and math.isfinite(th):
            return float(x), float(y), float(th)
    try:
        vals = np.asarray(pose, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"vehicle pose must be (x m, y m, theta rad), got {pose!r}") from None
    if vals.shape != (3,):
        raise ValueError(f"vehicle pose must be three numbers (x m, y m, theta rad), got {pose!r}")
    if not np.all(np.isfinite(vals)):
        raise ValueError(f"vehicle pose must be finite (x m, y m, theta rad), got {pose!r}")
    return float(vals[0]), float(vals[1]), float(vals[2])
