"""The vectorised :func:`agvsim.sensors.render.truth.frame_truth` against the per-target loop it
replaced (copied below as the reference): along the routes of ``plant_floor`` and ``corridor``,
with pitch/roll jitter, with lens distortion, with synthetic depth buffers that occlude parts of
some targets (nearer surfaces, empty pixels), at supersample 1 and 2: floats equal to 1e-9
(relative), booleans identical, the same targets in the same order."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from localizer.model.camera import Camera
from localizer.model.geometry import TargetPose
from agvsim.sensors.render.mount import CameraPose, level_rotation
from agvsim.sensors.render.strip import route_poses
from agvsim.sensors.render.truth import (MAX_ALPHA, MIN_BAR_PX, MIN_ROWS, NEAR, OCCLUSION_GRID, TRUTH_COLUMNS,
                                         FrameTruth, TargetTruth, TruthGeometry, frame_truth)
from agvsim.world import load_map

N_POSES = 40
RTOL = 1e-9
DIST = (-0.25, 0.08, 0.001, -0.0015, -0.01)


# ---------------------------------------------------------------- reference: the per-target loop
def _ref_level_target_pose(target, cam_pose):
    centre = target.center_3d
    p = cam_pose.to_level_camera(centre)
    n = np.array([target.normal[0], target.normal[1], 0.0])
    n_cam = cam_pose.to_level_camera(cam_pose.position + n)
    facing = float(np.dot(n[:2], cam_pose.position[:2] - centre[:2])) > 0.0
    d = math.hypot(p[0], p[2])
    if d <= 1e-9:
        return None, facing
    beta = math.atan2(p[0], p[2])
    alpha = math.atan2(-n_cam[0], -n_cam[2])
    return TargetPose(distance=d, beta=beta, alpha=alpha, height=float(p[1])), facing


def _ref_ideal(camera):
    return camera if not camera.dist else Camera(camera.fx, camera.fy, camera.cx, camera.cy, camera.width,
                                                  camera.height)


def _ref_occluded_fraction(camera, pose, spec, jit, depth, supersample):
    nx, ny = OCCLUSION_GRID
    uo, vo = spec.outer_width / 2 * 0.9, spec.outer_height / 2 * 0.9
    uu, vv = np.meshgrid(np.linspace(-uo, uo, nx), np.linspace(-vo, vo, ny))
    pts = pose.points(uu.ravel(), vv.ravel()) @ jit.T
    px = _ref_ideal(camera).project(pts)
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


def _reference_frame_truth(world_map, camera, cam_pose, vehicle_pose, depth, supersample=1, distorted=False,
                           lighting=None):
    jit = cam_pose.rotation.T @ level_rotation(cam_pose.heading)
    out = []
    for t in world_map.targets:
        spec = t.spec
        pose, facing = _ref_level_target_pose(t, cam_pose)
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
            proj = camera if distorted else _ref_ideal(camera)
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
                occluded = _ref_occluded_fraction(camera, pose, spec, jit, depth, supersample)
        visible = bool(facing and in_view and occluded == 0.0)
        in_env = bool(visible and bar_w >= MIN_BAR_PX and bar_rows >= MIN_ROWS and abs(pose.alpha) <= MAX_ALPHA)
        out.append(TargetTruth(
            id=t.id, polarity=t.polarity, visible=visible, in_view=in_view, facing=facing,
            occluded_fraction=float(occluded), in_envelope=in_env, distance=pose.distance, alpha=pose.alpha,
            beta=pose.beta, z=pose.z, height=pose.height, corners=corners, bbox=bbox,
            bar_width_px=bar_w, bar_rows=bar_rows))
    return SimpleNamespace(camera=camera, vehicle_pose=tuple(float(v) for v in vehicle_pose),
                           camera_pose=cam_pose, lighting=lighting, targets=tuple(out))


# ---------------------------------------------------------------- helpers
def _close(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or abs(a - b) <= RTOL * max(abs(a), abs(b), 1e-3)


def _assert_same(new: FrameTruth, ref: FrameTruth, where: str) -> None:
    assert new.camera is ref.camera and new.camera_pose is ref.camera_pose, where
    assert new.vehicle_pose == ref.vehicle_pose and new.lighting == ref.lighting, where
    assert [t.id for t in new.targets] == [t.id for t in ref.targets], where
    for a, b in zip(new.targets, ref.targets):
        at = f"{where}, target {b.id}"
        assert type(a) is TargetTruth and list(vars(a)) == list(vars(b)), at
        for name, va in vars(a).items():
            vb = getattr(b, name)
            if isinstance(vb, bool) or isinstance(vb, str):
                assert type(va) is type(vb) and va == vb, f"{at}: {name} {va!r} != {vb!r}"
            elif isinstance(vb, float):
                assert type(va) is float and _close(va, vb), f"{at}: {name} {va!r} != {vb!r}"
            elif name == "bbox":
                assert type(va) is tuple and len(va) == 4 and all(type(x) is float for x in va), at
                assert all(_close(x, y) for x, y in zip(va, vb)), f"{at}: bbox {va} != {vb}"
            else:  # corners
                assert isinstance(va, np.ndarray) and va.shape == (4, 2) and va.dtype == vb.dtype, at
                assert all(_close(x, y) for x, y in zip(va.ravel().tolist(), vb.ravel().tolist())), \
                    f"{at}: corners {va} != {vb}"


def _synthetic_depth(truth: FrameTruth, camera: Camera, s: int, variant: int) -> np.ndarray:
    """A depth buffer over which the targets in view are: far behind (clear), at their own range
    (part of a turned face hides behind it), half-covered by a nearer surface; a band of empty
    pixels (0) along the top; ``variant`` rotates which target gets what."""
    depth = np.full((camera.height * s, camera.width * s), 50.0)
    depth[: camera.height * s // 10] = 0.0
    for j, t in enumerate(truth.targets):
        if not t.in_view:
            continue
        x0, y0, x1, y1 = (int(math.floor((v + 0.5) * s)) for v in t.bbox)
        kind = (j + variant) % 4
        if kind == 1:
            depth[y0:y1 + 1, x0:x1 + 1] = t.z
        elif kind == 2:
            depth[y0:y1 + 1, x0:(x0 + x1) // 2] = t.z - 0.3
        elif kind == 3:
            depth[(y0 + y1) // 2:y1 + 1, x0:x1 + 1] = 0.0
    return depth


@pytest.fixture(scope="module", params=["plant_floor", "corridor"])
def route(request):
    m = load_map(request.param)
    mount = m.camera_mount
    poses = route_poses(m, N_POSES, mount=mount)
    rng = np.random.default_rng(7)
    cams = []
    for k, vp in enumerate(poses):
        pitch, roll = (0.0, 0.0) if k % 3 == 0 else tuple(rng.normal(0.0, 0.03, 2))
        cams.append((vp, CameraPose.from_vehicle(mount, vp, pitch, roll)))
    return m, cams


def test_frame_truth_matches_the_per_target_reference(route):
    m, cams = route
    cameras = {False: Camera.thesis(16.0), True: Camera.from_intrinsics(*_k(Camera.thesis(16.0)), dist=DIST)}
    fractions = []
    for k, (vp, cp) in enumerate(cams):
        for distorted in (False, True):
            cam = cameras[distorted]
            ref0 = _reference_frame_truth(m, cam, cp, vp, None, 1, distorted, None)
            _assert_same(frame_truth(m, cam, cp, vp, None, 1, distorted, None), ref0, f"pose {k} no depth")
            for s in (1, 2):
                depth = _synthetic_depth(ref0, cam, s, k + s)
                ref = _reference_frame_truth(m, cam, cp, vp, depth, s, distorted, 0.7)
                new = frame_truth(m, cam, cp, vp, depth, s, distorted, 0.7, geometry=TruthGeometry.of(m))
                _assert_same(new, ref, f"pose {k} distorted={distorted} s={s}")
                fractions += [t.occluded_fraction for t in ref.targets if t.in_view]
    # the buffers exercised clear, partly and wholly occluded targets
    f = np.array(fractions)
    assert np.any(f == 0.0) and np.any((f > 0.0) & (f < 1.0)) and np.any(f == 1.0)
    # and the route saw targets in view, in the envelope and out of view
    truths = [_reference_frame_truth(m, cameras[False], cp, vp, None) for vp, cp in cams]
    flags = [(t.in_view, t.in_envelope) for tr in truths for t in tr.targets]
    assert any(iv for iv, _ in flags) and any(env for _, env in flags) and not all(iv for iv, _ in flags)


def test_a_target_at_the_lens_is_left_out(route):
    m, cams = route
    t = m.targets[0]
    vp, cp = cams[0]
    at = CameraPose(t.center_3d.copy(), cp.heading, cp.rotation, cp.pitch, cp.roll)
    cam = Camera.thesis(16.0)
    new = frame_truth(m, cam, at, vp, None)
    assert t.id not in [x.id for x in new.targets] and len(new.targets) == len(m.targets) - 1
    _assert_same(new, _reference_frame_truth(m, cam, at, vp, None), "camera at a target")


def test_the_geometry_is_built_once_per_map(route):
    m, _ = route
    g = TruthGeometry.of(m)
    assert TruthGeometry.of(m) is g and g.uv1.shape == (len(m.targets), 51, 3) and np.all(g.uv1[..., 2] == 1.0)
    assert g.frame.shape == (len(m.targets), 3, 3)
    assert np.array_equal(g.frame[:, 2], [t.center_3d for t in m.targets])
    # across is the normal turned clockwise (seen from above): the right as seen facing the target
    assert np.allclose(g.frame[:, 0, :2], [(-t.normal[1], t.normal[0]) for t in m.targets], rtol=0, atol=1e-15)


def test_a_map_without_targets(route):
    m, cams = route
    vp, cp = cams[0]
    truth = frame_truth(m, Camera.thesis(16.0), cp, vp, np.zeros((480, 512)), geometry=TruthGeometry(()))
    assert truth.targets == () and truth.visible == ()


def _k(c: Camera):
    return c.fx, c.fy, c.cx, c.cy, c.width, c.height


def test_columns_are_the_targets_fields(route):
    """:meth:`FrameTruth.column` reads the same numbers as :attr:`FrameTruth.targets`, flags as bool."""
    m, cams = route
    cam = Camera.thesis(16.0)
    fields = {"d": "distance", "beta": "beta", "alpha": "alpha", "z": "z", "height": "height",
              "occluded": "occluded_fraction", "bar_width_px": "bar_width_px", "bar_rows": "bar_rows",
              "facing": "facing", "in_view": "in_view", "visible": "visible", "in_envelope": "in_envelope"}
    seen = 0
    for vp, cp in cams[:12]:
        truth = frame_truth(m, cam, cp, vp, np.full((480, 512), 50.0))
        seen += int(truth.column("visible").sum())
        assert isinstance(truth, FrameTruth) and truth.table.values.shape == (len(m.targets), len(TRUTH_COLUMNS))
        for col, attr in fields.items():
            got = truth.column(col)
            want = np.array([getattr(t, attr) for t in truth.targets])
            assert got.dtype == want.dtype and np.array_equal(got, want, equal_nan=got.dtype.kind == "f"), col
        assert np.array_equal(truth.column("bbox_x0"), [t.bbox[0] for t in truth.targets], equal_nan=True)
    assert seen > 0 and not truth.table.values.flags.writeable
    with pytest.raises(ValueError, match="unknown column 'range'"):
        truth.column("range")
