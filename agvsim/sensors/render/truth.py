"""Ground truth of every target in a frame, in the localizer's conventions.

For each map target: the true ``d``, ``α``, ``β`` (thesis conventions, see
:mod:`localizer.model.geometry`), measured in the *level* camera frame -- the
horizontal quantities the localizer estimates, unaffected by pitch/roll
jitter -- and its image geometry (active-area corners TL, TR, BR, BL, the
bounding box of the printed face) through the *actual* camera (jitter and, if
applied to the image, lens distortion included).

A target is ``visible`` when the camera is in front of its face, the whole
printed face (margin included) projects inside the image, and the depth
buffer shows nothing in front of it at any of a grid of points on the face.
``in_envelope`` adds the localizer's working envelope (bars >= 5 px wide and
>= 16 rows tall, |α| <= 70°).

:func:`frame_truth` works on all targets at once: :class:`TruthGeometry` holds,
per target, its frame (the face's across and down directions and its centre in the map)
and the target coordinates of every point projected (built once per map and cached); a
compiled kernel (:mod:`agvsim.sensors.render._truth_kernels`) fills one table per frame
with every target's level-frame pose and whether it is in front of the lens, the image
geometry of those in front, and the depth-buffer test of those in view. Only a distorted
frame's projection is NumPy's (:meth:`localizer.model.camera.Camera.project`).
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from localizer.model.camera import Camera
from localizer.model.geometry import TargetPose
from agvsim.sensors.render._truth_kernels import COLUMNS as TRUTH_COLUMNS
from agvsim.sensors.render._truth_kernels import (CameraRotation, TargetPoints, TruthParams, blank_table, frame_table, image_geometry,
                                                  occlusion_verdicts, target_poses)
from agvsim.sensors.render.mount import CameraPose, level_rotation

OCCLUSION_GRID = (7, 5)  # sample points across x down the printed face
_COL = {name: k for k, name in enumerate(TRUTH_COLUMNS)}
_FLAGS = frozenset(("facing", "in_front", "in_view", "visible", "in_envelope"))
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
class TruthTable:
    """A frame's truth as one table: what :attr:`FrameTruth.targets` is built from.

    Attributes:
        ids, polarities: of the targets reported, in map order (a target whose centre is at
            the lens is left out).
        values: ``(n, len(TRUTH_COLUMNS))`` float64, read-only, row per target, columns
            :data:`TRUTH_COLUMNS` (SI units, pixels; flags 0.0 / 1.0; corners and bbox NaN for a
            target not in front of the lens).
    """

    ids: tuple[str, ...]
    polarities: tuple[str, ...]
    values: np.ndarray


@dataclass(frozen=True)
class FrameTruth:
    """Ground truth of one frame.

    Attributes:
        camera: the intrinsics the frame was rendered with.
        vehicle_pose: ``(x m, y m, θ rad)``.
        camera_pose: the camera's pose (jitter included).
        lighting: the lighting override level, or None when the map's zones were used.
        table: the numbers, one row per target (:class:`TruthTable`); :attr:`targets` and
            :meth:`column` read it.
    """

    camera: Camera
    vehicle_pose: tuple[float, float, float]
    camera_pose: CameraPose
    lighting: float | None
    table: TruthTable = field(repr=False)

    @cached_property
    def targets(self) -> tuple[TargetTruth, ...]:
        """One :class:`TargetTruth` per map target, in map order (built at the first access)."""
        tab = self.table
        n = len(tab.ids)
        if n == 0:
            return ()
        out = []
        new, set_dict = object.__new__, object.__setattr__
        corners = tab.values[:, _COL["x_tl"]:_COL["bbox_x0"]].reshape(n, 4, 2)  # (views)
        for row, cor, i, pol in zip(tab.values.tolist(), corners, tab.ids, tab.polarities):
            d, bt, a, zz, h, *_, b0, b1, b2, b3, bw, br, occ, fac, _, inv, vis, env = row
            # the frozen dataclass is filled without its __init__ (sixteen object.__setattr__ calls)
            t = new(TargetTruth)
            set_dict(t, "__dict__", {
                "id": i, "polarity": pol, "visible": vis != 0.0, "in_view": inv != 0.0, "facing": fac != 0.0,
                "occluded_fraction": occ, "in_envelope": env != 0.0, "distance": d, "alpha": a, "beta": bt,
                "z": zz, "height": h, "corners": cor, "bbox": (b0, b1, b2, b3), "bar_width_px": bw,
                "bar_rows": br})
            out.append(t)
        return tuple(out)

    def column(self, name: str) -> np.ndarray:
        """``(n,)`` one of :data:`TRUTH_COLUMNS` over the targets reported (map order, as
        :attr:`targets`): float64, or bool for the flags (``facing``, ``in_front``, ``in_view``,
        ``visible``, ``in_envelope``). Cheaper than :attr:`targets` for a loop over a frame's
        targets that reads a few fields."""
        if name not in _COL:
            raise ValueError(f"FrameTruth.column: unknown column {name!r}; expected one of {', '.join(TRUTH_COLUMNS)}")
        col = self.table.values[:, _COL[name]]
        return col != 0.0 if name in _FLAGS else col

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


# rows of TruthGeometry.uv1: the points projected for each target
ACTIVE, OUTER, EDGES_TOP, EDGES_BOTTOM = slice(0, 4), slice(4, 8), slice(8, 12), slice(12, 16)
IMAGE = slice(0, 16)  # the points whose image the truth reports (corners, bbox, bar sizes)
GRID = slice(16, 16 + OCCLUSION_GRID[0] * OCCLUSION_GRID[1])  # the occlusion test's face points
N_POINTS = GRID.stop  # 51


class TruthGeometry:
    """A map's targets as arrays, for :func:`frame_truth` (build once per map; :meth:`of` caches it).

    A face point at target coordinates ``(u, v)`` (m, ``u`` to the right as seen facing the
    target, ``v`` down, origin at the centre) is, in the map, ``[u, v, 1] @ frame``, ``frame``
    the target's rows ``across, down, centre``; in a camera frame, the same with the rows
    rotated into it (and the lens position taken from the centre).

    Attributes:
        targets: the map's targets, in map order (n of them).
        frame: ``(n, 3, 3)`` per target, rows: ``across = (-normal_y, normal_x, 0)`` (unit, the
            direction of ``u``), ``down = (0, 0, -1)``, the face centre (m), in the map.
        uv1: ``(n, 51, 3)`` rows ``[u, v, 1]`` (m) of the points projected per frame: active-area
            corners TL, TR, BR, BL (rows 0-3), printed-face corners (4-7), the four bar edges'
            tops (8-11) and bottoms (12-15), and the 7 x 5 occlusion grid over 90 % of the
            printed face (16-50, row-major).
    """

    def __init__(self, targets) -> None:
        self.targets = tuple(targets)
        n = len(self.targets)
        self.frame = np.zeros((n, 3, 3))
        self.uv1 = np.ones((n, N_POINTS, 3))
        nx, ny = OCCLUSION_GRID
        for i, t in enumerate(self.targets):
            normal = np.asarray(t.normal, dtype=float) / math.hypot(*t.normal)
            self.frame[i] = [[-normal[1], normal[0], 0.0], [0.0, 0.0, -1.0], t.center_3d]
            spec = t.spec
            b, hh = spec.bar_width, spec.bar_height / 2
            uo, vo = spec.outer_width / 2, spec.outer_height / 2
            edges = np.array([-1.5, -0.5, 0.5, 1.5]) * b
            gu, gv = spec.outer_width / 2 * 0.9, spec.outer_height / 2 * 0.9
            uu, vv = np.meshgrid(np.linspace(-gu, gu, nx), np.linspace(-gv, gv, ny))
            self.uv1[i, :, 0] = np.concatenate([[-1.5 * b, 1.5 * b, 1.5 * b, -1.5 * b], [-uo, uo, uo, -uo], edges,
                                                edges, uu.ravel()])
            self.uv1[i, :, 1] = np.concatenate([[-hh, -hh, hh, hh], [-vo, -vo, vo, vo], np.full(4, -hh),
                                                np.full(4, hh), vv.ravel()])
        self._outer, self._image, self._grid = (self.uv1[:, s].copy() for s in (OUTER, IMAGE, GRID))
        self._blank = np.concatenate([np.full((n, 12), np.nan), np.zeros((n, 3))], axis=1)
        self._ids = [t.id for t in self.targets]
        self._polarities = [t.polarity for t in self.targets]

    @classmethod
    def of(cls, world_map) -> "TruthGeometry":
        """The (cached) geometry of ``world_map``'s targets."""
        try:
            g = _CACHE.get(world_map)
        except TypeError:  # a map that cannot be weakly referenced: not cached
            return cls(world_map.targets)
        if g is None:
            g = _CACHE[world_map] = cls(world_map.targets)
        return g


_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def frame_truth(world_map, camera: Camera, cam_pose: CameraPose, vehicle_pose, depth: np.ndarray | None,
                supersample: int = 1, distorted: bool = False, lighting: float | None = None,
                geometry: TruthGeometry | None = None) -> FrameTruth:
    """Ground truth of every target of ``world_map`` seen from ``cam_pose``.

    Args:
        camera: intrinsics (pixel-centre convention of :mod:`localizer.model.camera`).
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
    rot = cam_pose.rotation  # no jitter: the level rotation's very bits
    jittered = rot.tobytes() != level.tobytes()
    params = TruthParams(float(camera.fx), float(camera.fy), float(camera.cx), float(camera.cy),
                            int(camera.width), int(camera.height), int(supersample), NEAR, MIN_BAR_PX, MIN_ROWS,
                            MAX_ALPHA)
    position = np.asarray(cam_pose.position, dtype=np.float64)
    has_depth = depth is not None
    depth_t = _NO_DEPTH if not has_depth else depth.T if depth.T.flags.c_contiguous and depth.dtype == np.float32 \
        else np.ascontiguousarray(depth.T, np.float32)  # (one layout: one compiled kernel)
    table = blank_table(n)
    act = np.empty((n, 3, 3))
    if n and not (distorted and camera.dist):
        frame_table(TargetPoints(g.frame, g._outer, g._image, g._grid), CameraRotation(position, rot, level, jittered),
                    params, depth_t, has_depth, act, table, np.empty((1, IMAGE.stop, 2)))
    elif n:  # the image geometry through the lens distortion (NumPy), the rest compiled
        target_poses(g.frame, position, rot, level, jittered, g._outer, NEAR, act, table)
        f = (table[:, _COL["in_front"]] != 0.0).nonzero()[0]
        if len(f):
            px = camera.project(g._image[f] @ act[f])  # (m, 16, 2) px
            image_geometry(np.ascontiguousarray(px, dtype=np.float64), f, camera.width, camera.height, table)
        occlusion_verdicts(g._grid, act, params, depth_t, has_depth, table)
    kept = table[:, 0] > 1e-9  # a centre at the lens has no pose
    if kept.all():
        ids, polarities = tuple(g._ids), tuple(g._polarities)
    else:
        table = table[kept]
        ids = tuple(i for i, k in zip(g._ids, kept) if k)
        polarities = tuple(p for p, k in zip(g._polarities, kept) if k)
    table.flags.writeable = False
    return FrameTruth(camera=camera, vehicle_pose=tuple(float(v) for v in vehicle_pose), camera_pose=cam_pose,
                      lighting=lighting, table=TruthTable(ids, polarities, table))


_NO_DEPTH = np.zeros((0, 0), np.float32)  # (the depth argument of a frame without a buffer: not read)
