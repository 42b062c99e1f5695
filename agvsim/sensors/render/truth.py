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

:func:`frame_truth` works on all targets at once: :class:`TruthGeometry` holds a
map's target centres, normals and the target-frame ``(u, v)`` of every point
it projects (built once per map and cached), so a frame costs a handful of
NumPy operations on ``(n_targets, 51)`` arrays whatever the number of targets.
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, fields

import numpy as np

from localizer.camera import Camera
from localizer.geometry import TargetPose
from agvsim.sensors.render.mount import CameraPose, level_rotation

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
    """One target's pose in the level camera frame (localizer conventions) and whether it faces the lens.

    Returns ``(None, facing)`` when the target centre is at the lens (degenerate).
    (:func:`frame_truth` computes the same for all targets at once.)
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


# columns of TruthGeometry.u / .v: the points projected for each target
ACTIVE, OUTER, EDGES_TOP, EDGES_BOTTOM = slice(0, 4), slice(4, 8), slice(8, 12), slice(12, 16)
GRID = slice(16, 16 + OCCLUSION_GRID[0] * OCCLUSION_GRID[1])  # the occlusion test's face points
N_POINTS = GRID.stop  # 51


class TruthGeometry:
    """A map's targets as arrays, for :func:`frame_truth` (build once per map; :meth:`of` caches it).

    Attributes:
        targets: the map's targets, in map order (n of them).
        centres: ``(n, 3)`` face centres in the map (m).
        normals: ``(n, 3)`` unit face normals, ``z = 0``.
        u, v: ``(n, 51)`` target coordinates (m, ``u`` right, ``v`` down, origin at the centre) of
            the points projected per frame: active-area corners TL, TR, BR, BL (columns 0-3),
            printed-face corners (4-7), the four bar edges' tops (8-11) and bottoms (12-15), and
            the 7 x 5 occlusion grid over 90 % of the printed face (16-50, row-major).
    """

    def __init__(self, targets) -> None:
        self.targets = tuple(targets)
        n = len(self.targets)
        self.centres = np.array([t.center_3d for t in self.targets], dtype=float).reshape(n, 3)
        self.normals = np.array([[t.normal[0], t.normal[1], 0.0] for t in self.targets], dtype=float).reshape(n, 3)
        self.u = np.empty((n, N_POINTS))
        self.v = np.empty((n, N_POINTS))
        nx, ny = OCCLUSION_GRID
        for i, t in enumerate(self.targets):
            spec = t.spec
            b, hh = spec.bar_width, spec.bar_height / 2
            uo, vo = spec.outer_width / 2, spec.outer_height / 2
            edges = np.array([-1.5, -0.5, 0.5, 1.5]) * b
            gu, gv = spec.outer_width / 2 * 0.9, spec.outer_height / 2 * 0.9
            uu, vv = np.meshgrid(np.linspace(-gu, gu, nx), np.linspace(-gv, gv, ny))
            self.u[i] = np.concatenate([[-1.5 * b, 1.5 * b, 1.5 * b, -1.5 * b], [-uo, uo, uo, -uo], edges, edges,
                                        uu.ravel()])
            self.v[i] = np.concatenate([[-hh, -hh, hh, hh], [-vo, -vo, vo, vo], np.full(4, -hh), np.full(4, hh),
                                        vv.ravel()])
        # per-target constants of the TargetTruth records
        self._static = [{"id": t.id, "polarity": t.polarity} for t in self.targets]

    @classmethod
    def of(cls, world_map) -> "TruthGeometry":
        """The (cached) geometry of ``world_map``'s targets."""
        g = _CACHE.get(world_map)
        if g is None:
            g = _CACHE[world_map] = cls(world_map.targets)
        return g


_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
# TargetTruth's fields after id, polarity, in declaration order (the order frame_truth's columns come in)
_FIELDS = ("visible", "in_view", "facing", "occluded_fraction", "in_envelope", "distance", "alpha", "beta", "z",
           "height", "corners", "bbox", "bar_width_px", "bar_rows")
assert ("id", "polarity") + _FIELDS == tuple(f.name for f in fields(TargetTruth))


def frame_truth(world_map, camera: Camera, cam_pose: CameraPose, vehicle_pose, depth: np.ndarray | None,
                supersample: int = 1, distorted: bool = False, lighting: float | None = None,
                geometry: TruthGeometry | None = None) -> FrameTruth:
    """Ground truth of every target of ``world_map`` seen from ``cam_pose``.

    Args:
        camera: intrinsics (pixel-centre convention of :mod:`localizer.camera`).
        cam_pose: the camera's pose (jitter included).
        vehicle_pose: for the record.
        depth: ``(H * s, W * s)`` float depth buffer (m along the optical axis, 0 = nothing),
            rendered with ``supersample`` s; None skips the occlusion test.
        distorted: report corners/bbox through ``camera.dist`` (the image was distorted).
        geometry: ``world_map``'s :class:`TruthGeometry` (default: :meth:`TruthGeometry.of`).
    Returns:
        one :class:`TargetTruth` per map target, in map order (a target whose centre is at
        the lens is left out).
    """
    g = geometry if geometry is not None else TruthGeometry.of(world_map)
    n = len(g.targets)
    level = level_rotation(cam_pose.heading)
    jit = cam_pose.rotation.T @ level  # level -> actual camera frame
    pos = np.asarray(cam_pose.position, dtype=float)
    # level-frame pose of every target (as level_target_pose)
    p = (g.centres - pos) @ level  # (n, 3) m
    n_cam = ((pos + g.normals) - pos) @ level
    rel = pos[:2] - g.centres[:, :2]
    facing = g.normals[:, 0] * rel[:, 0] + g.normals[:, 1] * rel[:, 1] > 0.0
    d = np.hypot(p[:, 0], p[:, 2])
    beta = np.arctan2(p[:, 0], p[:, 2])
    alpha = np.arctan2(-n_cam[:, 0], -n_cam[:, 2])
    height = p[:, 1]
    cx, cz = d * np.sin(beta), d * np.cos(beta)  # TargetPose.centre (x, z), cz == TargetPose.z
    # every point of every target, level -> actual camera frame: (n, 51, 3) m
    ca, sa = np.cos(alpha)[:, None], np.sin(alpha)[:, None]
    pts = np.stack([cx[:, None] + g.u * ca, height[:, None] + g.v,
                    cz[:, None] - g.u * sa], axis=-1) @ jit.T
    in_front = np.all(pts[:, OUTER, 2] > NEAR, axis=1)
    corners = np.full((n, 4, 2), np.nan)
    bbox = np.full((n, 4), np.nan)
    in_view = np.zeros(n, dtype=bool)
    occluded = np.zeros(n)
    bar_w = np.zeros(n)
    bar_rows = np.zeros(n)
    f = np.flatnonzero(in_front)
    if len(f):
        q = pts[f]  # (m, 51, 3), all in front of the lens (the points lie inside the printed face)
        ideal = np.stack([camera.cx + camera.fx * (q[..., 0] / q[..., 2]),
                          camera.cy + camera.fy * (q[..., 1] / q[..., 2])], axis=-1)  # (m, 51, 2) px
        px = camera.project(q[:, :GRID.start]) if distorted and camera.dist else ideal[:, :GRID.start]
        corners[f] = px[:, ACTIVE]
        outer = px[:, OUTER]
        box = np.concatenate([outer.min(axis=1), outer.max(axis=1)], axis=1)  # (m, 4): x0, y0, x1, y1
        bbox[f] = box
        iv = ((box[:, 0] >= -0.5) & (box[:, 1] >= -0.5) & (box[:, 2] <= camera.width - 0.5)
              & (box[:, 3] <= camera.height - 0.5))
        in_view[f] = iv
        et, eb = px[:, EDGES_TOP], px[:, EDGES_BOTTOM]
        bar_w[f] = np.min(np.abs(np.diff(et[..., 0], axis=1)), axis=1)
        bar_rows[f] = np.min(eb[..., 1] - et[..., 1], axis=1)
        if depth is not None and iv.any():
            k = np.flatnonzero(iv)
            occluded[f[k]] = _occluded_fraction(ideal[k, GRID], q[k, GRID, 2], depth, supersample)
    visible = facing & in_view & (occluded == 0.0)
    in_env = visible & (bar_w >= MIN_BAR_PX) & (bar_rows >= MIN_ROWS) & (np.abs(alpha) <= MAX_ALPHA)
    columns = zip(visible.tolist(), in_view.tolist(), facing.tolist(), occluded.tolist(), in_env.tolist(),
                  d.tolist(), alpha.tolist(), beta.tolist(), cz.tolist(), height.tolist(), corners,
                  map(tuple, bbox.tolist()), bar_w.tolist(), bar_rows.tolist())
    keep = (d > 1e-9).tolist()
    new = object.__new__
    out = []
    for static, ok, values in zip(g._static, keep, columns):
        if ok:  # a frozen dataclass filled without its __init__'s per-field object.__setattr__
            t = new(TargetTruth)
            t.__dict__.update(static)
            t.__dict__.update(zip(_FIELDS, values))
            out.append(t)
    return FrameTruth(camera=camera, vehicle_pose=tuple(float(v) for v in vehicle_pose), camera_pose=cam_pose,
                      lighting=lighting, targets=tuple(out))


def _occluded_fraction(px: np.ndarray, z: np.ndarray, depth: np.ndarray, supersample: int) -> np.ndarray:
    """Per target, the share of its face points behind something nearer in ``depth``.

    Args:
        px: ``(m, k, 2)`` undistorted pixel x, y of the face points; z: ``(m, k)`` their range (m).
        depth: ``(H * s, W * s)`` depth buffer (m, 0 = nothing) rendered with ``supersample`` s.
    Returns:
        ``(m,)`` fractions in [0, 1]; 1 for a target none of whose points falls in the buffer.
    """
    s = supersample
    cols = np.floor((px[..., 0] + 0.5) * s).astype(int)
    rows = np.floor((px[..., 1] + 0.5) * s).astype(int)
    h, w = depth.shape
    ok = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    zbuf = depth[np.where(ok, rows, 0), np.where(ok, cols, 0)]
    tol = 0.004 + 0.0005 * z
    hidden = ((zbuf > 0) & (zbuf < z - tol) | (zbuf == 0)) & ok
    n_ok = ok.sum(axis=1)
    return np.where(n_ok > 0, hidden.sum(axis=1) / np.maximum(n_ok, 1), 1.0)
