"""Ground truth of every target in a frame, in the localizer's conventions.

For each map target: the true ``d``, ``α``, ``β`` (thesis conventions, see
:mod:`localizer.geometry`), measured in the *level* camera frame -- the
horizontal quantities the localizer estimates, unaffected by pitch/roll
jitter -- and its image geometry (active-area corners TL, TR, BR, BL, the
bounding box of the printed face) through the *actual* camera (jitter and, if
applied to the image, lens distortion included).

A target is ``visible`` when the camera is in front of its face, the whole
printed face (margin included) projects inside the image, and the depth
buffer shows nothing in front of it at any of a grid of points on the face.
``in_envelope`` adds the localizer's working envelope (bars >= 5 px wide and
>= 16 rows tall, |α| <= 70°).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.camera import Camera
from localizer.geometry import TargetPose
from agvsim.sensors.render.mount import CameraPose

OCCLUSION_GRID = (7, 5)  # sample points across x down the printed face
MIN_BAR_PX = 5.0
MIN_ROWS = 16.0
MAX_ALPHA = math.radians(70.0)
NEAR = 0.05  # m, the renderer's near plane


@dataclass(frozen=True)
class TargetTruth:
    """Ground truth of one target in one frame.

    Attributes:
        id, polarity: from the map.
        visible: facing the camera, wholly in view and not occluded.
        in_view: the whole printed face projects inside the image, in front of the lens.
        facing: the lens is in front of the target's face.
        occluded_fraction: share of the face's sample points hidden behind something (0..1).
        in_envelope: visible and inside the localizer's working envelope.
        distance: d (m), horizontal lens centre -> target centre.
        alpha, beta: α, β (rad), thesis conventions (level camera).
        z: range along the level optical axis (m). height: level-camera y of the centre (m, down).
        corners: ``(4, 2)`` image x, y (px) of the active area's TL, TR, BR, BL.
        bbox: ``(x0, y0, x1, y1)`` (px) of the printed face (margin included), not clipped.
        bar_width_px: narrowest of the three strips (px); bar_rows: shortest bar (rows).
    """

    id: str
    polarity: str
    visible: bool
    in_view: bool
    facing: bool
    occluded_fraction: float
    in_envelope: bool
    distance: float  # m
    alpha: float  # rad
    beta: float  # rad
    z: float  # m
    height: float  # m
    corners: np.ndarray  # (4, 2) px
    bbox: tuple[float, float, float, float]  # px
    bar_width_px: float  # px
    bar_rows: float  # px

    def to_dict(self) -> dict:
        """JSON-ready dict (SI units, pixels)."""
        return {"id": self.id, "visible": self.visible, "distance": self.distance, "alpha": self.alpha,
                "beta": self.beta, "polarity": self.polarity, "bbox": [float(v) for v in self.bbox],
                "corners": np.asarray(self.corners, float).tolist(), "in_view": self.in_view,
                "facing": self.facing, "occluded_fraction": self.occluded_fraction,
                "in_envelope": self.in_envelope, "z": self.z, "height": self.height,
                "bar_width_px": self.bar_width_px, "bar_rows": self.bar_rows}


@dataclass(frozen=True)
class FrameTruth:
    """Ground truth of one frame.

    Attributes:
        camera: the intrinsics the frame was rendered with.
        vehicle_pose: ``(x m, y m, θ rad)``.
        camera_pose: the camera's pose (jitter included).
        lighting: the lighting override level, or None when the map's zones were used.
        targets: one :class:`TargetTruth` per map target, in map order.
    """

    camera: Camera
    vehicle_pose: tuple[float, float, float]
    camera_pose: CameraPose
    lighting: float | None
    targets: tuple[TargetTruth, ...]

    @property
    def visible(self) -> tuple[TargetTruth, ...]:
        return tuple(t for t in self.targets if t.visible)

    def target(self, target_id: str) -> TargetTruth:
        for t in self.targets:
            if t.id == target_id:
                return t
        raise KeyError(f"no target {target_id!r} in this frame's truth")

    def to_dict(self) -> dict:
        """JSON-ready: camera intrinsics, poses and the ``targets`` list."""
        c = self.camera
        cp = self.camera_pose
        return {
            "camera": {"fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy, "width": c.width, "height": c.height,
                       "dist": list(c.dist), "K": c.K.tolist(),
                       "pixel_convention": "pixel (row i, col j) has its centre at (x, y) = (j, i)"},
            "vehicle_pose": list(self.vehicle_pose),
            "camera_pose": {"position": cp.position.tolist(), "heading": cp.heading, "pitch": cp.pitch,
                            "roll": cp.roll},
            "lighting_override": self.lighting,
            "units": {"distance": "m", "alpha": "rad", "beta": "rad", "bbox": "px", "corners": "px"},
            "targets": [t.to_dict() for t in self.targets],
        }


def level_target_pose(target, cam_pose: CameraPose) -> tuple[TargetPose | None, bool]:
    """The target's pose in the level camera frame (localizer conventions) and whether it faces the lens.

    Returns ``(None, facing)`` when the target centre is at the lens (degenerate).
    """
    centre = target.center_3d
    p = cam_pose.to_level_camera(centre)  # (X right, Y down, Z forward)
    n = np.array([target.normal[0], target.normal[1], 0.0])
    n_cam = cam_pose.to_level_camera(cam_pose.position + n)  # direction (rotation only)
    facing = float(np.dot(n[:2], cam_pose.position[:2] - centre[:2])) > 0.0
    d = math.hypot(p[0], p[2])
    if d <= 1e-9:
        return None, facing
    beta = math.atan2(p[0], p[2])
    # the localizer's normal (sin α, 0, cos α) points away from the camera: -n
    alpha = math.atan2(-n_cam[0], -n_cam[2])
    return TargetPose(distance=d, beta=beta, alpha=alpha, height=float(p[1])), facing


def frame_truth(world_map, camera: Camera, cam_pose: CameraPose, vehicle_pose, depth: np.ndarray | None,
                supersample: int = 1, distorted: bool = False, lighting: float | None = None) -> FrameTruth:
    """Ground truth of every target of ``world_map`` seen from ``cam_pose``.

    Args:
        camera: intrinsics (pixel-centre convention of :mod:`localizer.camera`).
        cam_pose: the camera's pose (jitter included).
        vehicle_pose: for the record.
        depth: ``(H * s, W * s)`` float depth buffer (m along the optical axis, 0 = nothing),
            rendered with ``supersample`` s; None skips the occlusion test.
        distorted: report corners/bbox through ``camera.dist`` (the image was distorted).
    """
    jit = cam_pose.rotation.T @ _level(cam_pose)  # level -> actual camera frame
    out = []
    for t in world_map.targets:
        spec = t.spec
        pose, facing = level_target_pose(t, cam_pose)
        if pose is None:
            continue
        b, hh = spec.bar_width, spec.bar_height / 2
        uo, vo = spec.outer_width / 2, spec.outer_height / 2
        u = np.array([-1.5 * b, 1.5 * b, 1.5 * b, -1.5 * b])
        v = np.array([-hh, -hh, hh, hh])
        active = pose.points(u, v) @ jit.T
        outer = pose.points(np.array([-uo, uo, uo, -uo]), np.array([-vo, -vo, vo, vo])) @ jit.T
        edges_top = pose.points(np.array([-1.5, -0.5, 0.5, 1.5]) * b, -hh) @ jit.T
        edges_bot = pose.points(np.array([-1.5, -0.5, 0.5, 1.5]) * b, hh) @ jit.T
        in_front = bool(np.all(outer[:, 2] > NEAR))
        corners = np.full((4, 2), np.nan)
        bbox = (math.nan,) * 4
        in_view = False
        occluded = 0.0
        bar_w = bar_rows = 0.0
        if in_front:
            proj = camera if distorted else _ideal(camera)
            corners = proj.project(active)
            outer_px = proj.project(outer)
            bbox = (float(outer_px[:, 0].min()), float(outer_px[:, 1].min()),
                    float(outer_px[:, 0].max()), float(outer_px[:, 1].max()))
            in_view = bool(bbox[0] >= -0.5 and bbox[1] >= -0.5 and bbox[2] <= camera.width - 0.5
                           and bbox[3] <= camera.height - 0.5)
            et, eb = proj.project(edges_top), proj.project(edges_bot)
            bar_w = float(np.min(np.abs(np.diff(et[:, 0]))))
            bar_rows = float(min(eb[0, 1] - et[0, 1], eb[1, 1] - et[1, 1], eb[2, 1] - et[2, 1], eb[3, 1] - et[3, 1]))
            if in_view and depth is not None:
                occluded = _occluded_fraction(camera, pose, spec, jit, depth, supersample)
        visible = bool(facing and in_view and occluded == 0.0)
        in_env = bool(visible and bar_w >= MIN_BAR_PX and bar_rows >= MIN_ROWS and abs(pose.alpha) <= MAX_ALPHA)
        out.append(TargetTruth(
            id=t.id, polarity=t.polarity, visible=visible, in_view=in_view, facing=facing,
            occluded_fraction=float(occluded), in_envelope=in_env, distance=pose.distance, alpha=pose.alpha,
            beta=pose.beta, z=pose.z, height=pose.height, corners=corners, bbox=bbox,
            bar_width_px=bar_w, bar_rows=bar_rows))
    return FrameTruth(camera=camera, vehicle_pose=tuple(float(v) for v in vehicle_pose), camera_pose=cam_pose,
                      lighting=lighting, targets=tuple(out))


def _level(cam_pose: CameraPose) -> np.ndarray:
    from agvsim.sensors.render.mount import level_rotation

    return level_rotation(cam_pose.heading)


def _ideal(camera: Camera) -> Camera:
    return camera if not camera.dist else Camera(camera.fx, camera.fy, camera.cx, camera.cy, camera.width,
                                                  camera.height)


def _occluded_fraction(camera: Camera, pose: TargetPose, spec, jit: np.ndarray, depth: np.ndarray,
                       supersample: int) -> float:
    """Share of a grid of points on the printed face behind something nearer in ``depth``."""
    nx, ny = OCCLUSION_GRID
    uo, vo = spec.outer_width / 2 * 0.9, spec.outer_height / 2 * 0.9
    uu, vv = np.meshgrid(np.linspace(-uo, uo, nx), np.linspace(-vo, vo, ny))
    pts = pose.points(uu.ravel(), vv.ravel()) @ jit.T
    px = _ideal(camera).project(pts)
    s = supersample
    cols = np.floor((px[:, 0] + 0.5) * s).astype(int)
    rows = np.floor((px[:, 1] + 0.5) * s).astype(int)
    ok = (cols >= 0) & (cols < depth.shape[1]) & (rows >= 0) & (rows < depth.shape[0])
    if not np.any(ok):
        return 1.0
    zbuf = depth[rows[ok], cols[ok]]
    z = pts[ok, 2]
    tol = 0.004 + 0.0005 * z
    hidden = (zbuf > 0) & (zbuf < z - tol) | (zbuf == 0)
    return float(np.mean(hidden))
