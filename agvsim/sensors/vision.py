"""The camera on the vehicle (:class:`VisionConfig`) and what it can see.

Visibility (geometric and synthetic sources): the whole printed target inside
the image with bars at least 5 px wide and 16 rows tall
(:func:`localizer.tools.synthetic.in_envelope`), range and incidence limits, and no
wall or obstacle crossing the 2-D line of sight (:meth:`Solids.blocker`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from localizer.model.camera import Camera
from localizer.filter import TargetMap, ViewLimits, predict_all
from localizer.model.geometry import TargetPose
from localizer.model.mount import CameraMount
from localizer.numeric import check_choice, check_number
from localizer.model.params import METHODS

__all__ = ["LENSES_MM", "VisionConfig", "match_truth", "targets_from_map", "visible_targets"]

#: Focal lengths (mm) of the thesis camera's lenses (thesis ch. 5).
LENSES_MM: tuple[float, ...] = (16.0, 50.0)


@dataclass(frozen=True)
class VisionConfig:
    """The camera on the vehicle: where it sits, its lens, what the localizer is trusted with.

    Attributes:
        mount: the :class:`~localizer.model.mount.CameraMount`; None: the map's recommended mount
            (``camera_mount`` in its YAML), filled in by :meth:`for_map`.
        focal_mm: lens focal length (mm) of the thesis camera, one of :data:`LENSES_MM`.
        max_range: farthest target the localizer is trusted with (m).
        max_incidence: largest |γ| = |α - β| at which targets are reported (rad).
        detector: ``localizer.detect_targets`` method (one of ``localizer.METHODS``).
    """

    mount: CameraMount | None = None
    focal_mm: float = 16.0  # mm
    max_range: float = 10.0  # m
    max_incidence: float = math.radians(70.0)  # rad
    detector: str = "exact"

    def __post_init__(self) -> None:
        if self.mount is not None and not isinstance(self.mount, CameraMount):
            raise ValueError(f"VisionConfig.mount must be a localizer.model.mount.CameraMount or None, got {self.mount!r}")
        focal = check_number("VisionConfig.focal_mm", self.focal_mm, unit="mm")
        if focal not in LENSES_MM:
            raise ValueError(f"VisionConfig.focal_mm must be one of {', '.join(f'{v:g}' for v in LENSES_MM)} (mm), "
                             f"got {self.focal_mm!r}")
        check_number("VisionConfig.max_range", self.max_range, low=0.0, low_open=True, unit="m")
        check_number("VisionConfig.max_incidence", self.max_incidence, low=0.0, high=math.pi / 2,
                     low_open=True, unit="rad")
        check_choice("VisionConfig.detector", self.detector, METHODS)

    def for_map(self, world_map) -> "VisionConfig":
        """This configuration with the map's recommended mount where none was given."""
        if self.mount is not None:
            return self
        return replace(self, mount=world_map.camera_mount)

    @cached_property
    def camera(self) -> Camera:
        """The thesis camera with this lens (built once per configuration)."""
        return Camera.thesis(self.focal_mm)

    @cached_property
    def half_fov(self) -> float:
        """Half the horizontal field of view (rad)."""
        cam = self.camera
        return math.atan(0.5 * cam.width / cam.fx)

    def view_limits(self) -> ViewLimits:
        """The filter's prediction of which targets are in view (horizontal FOV of the lens);
        one (frozen) instance per configuration."""
        return self._filter_limits

    @cached_property
    def _filter_limits(self) -> ViewLimits:
        return ViewLimits(half_fov=self.half_fov, min_range=0.3, max_range=self.max_range + 1.0,
                          max_incidence=min(self.max_incidence + math.radians(5.0), math.pi / 2))

    @cached_property
    def visibility_limits(self) -> ViewLimits:
        """Where the camera really sees a target (no margin): the first test of
        :func:`visible_targets`; one (frozen) instance per configuration."""
        return ViewLimits(half_fov=self.half_fov, min_range=0.3, max_range=self.max_range,
                          max_incidence=self.max_incidence, margin=0.0)


def targets_from_map(world_map) -> TargetMap:
    """The map's targets as the filter's plain data (ids, face centres, facing yaws, polarities)."""
    ts = world_map.targets
    return TargetMap(tuple(t.id for t in ts), np.array([t.position for t in ts]).reshape(-1, 2),
                     np.array([t.yaw for t in ts]), tuple(t.polarity for t in ts))


def visible_targets(world_map, vision: VisionConfig, true_pose,
                    targets: TargetMap | None = None) -> list[tuple[int, TargetPose]]:
    """(index into ``world_map.targets``, true camera-frame pose) of every target the camera can see.

    ``vision`` must carry a mount (:meth:`VisionConfig.for_map`); ``targets``: the map's
    :func:`targets_from_map`, if already made (sources make it once, not per frame).
    """
    tm = targets if targets is not None else targets_from_map(world_map)
    if len(tm) == 0:
        return []
    mount = vision.mount
    cam = vision.camera
    Z, ok = predict_all(np.asarray(true_pose, dtype=float), tm, mount, vision.visibility_limits)
    if not ok.any():
        return []
    from localizer.tools.synthetic import in_envelope

    lens, _ = mount.camera_pose(true_pose)
    out = []
    for i in np.nonzero(ok)[0]:
        t = world_map.targets[i]
        pose = TargetPose(float(Z[i, 0]), float(Z[i, 1]), float(Z[i, 2]), float(mount.height - t.height))
        if not in_envelope(cam, pose, t.spec):
            continue
        if world_map.solids.blocker(lens[:2], t.position) is not None:
            continue
        out.append((int(i), pose))
    return out


def match_truth(obs, visible, world_map) -> str | None:
    """Id of the visible target nearest in bearing to ``obs`` (within 0.02 rad and 10 % in d), else None.

    ``visible``: (index into ``world_map.targets``, true :class:`TargetPose`) pairs.
    """
    best, best_id = 0.02, None
    for i, pose in visible:
        db = abs(obs.beta - pose.beta)
        if db < best and abs(obs.distance - pose.distance) < 0.1 * pose.distance:
            best, best_id = db, world_map.targets[i].id
    return best_id
