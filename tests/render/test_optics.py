"""Motion blur and lens distortion through the renderer: the blur grows with the yaw rate as
fx * omega * T, and a distorted camera's frames still give the localizer the right pose."""
from __future__ import annotations

import math

import numpy as np
import pytest

from agvsim.sensors.render.placement import vehicle_pose_for_target
from agvsim.sensors.render.renderer import CameraRenderer, RenderConditions
from localizer import Camera, detect_targets

pytestmark = pytest.mark.render


def _box_blur(row: np.ndarray, length: float, n: int = 64) -> np.ndarray:
    """``row`` averaged over shifts spread evenly across ``length`` pixels (a moving box)."""
    x = np.arange(len(row), dtype=float)
    shifts = ((np.arange(n) + 0.5) / n - 0.5) * length
    return np.mean([np.interp(x + s, x, row.astype(float)) for s in shifts], axis=0)


def test_yaw_rate_blurs_vertical_edges(hall_renderers, hall, mount):
    """A yaw rate w over the exposure T smears the image sideways by fx * w * T * (1 + forward / Z)
    (rotation plus the sideways motion of a lens mounted ``forward`` of the turning centre)."""
    r = hall_renderers[16]
    d = 2.0
    vpose = vehicle_pose_for_target(mount, hall.target("P"), d, 0.0, 0.0)
    still, truth = r.render(vpose, RenderConditions.ideal())
    w, t = 1.0, 0.02  # rad/s, s
    moving, _ = r.render(vpose, RenderConditions.ideal(velocity=(0.0, w), exposure_time=t))
    p = truth.target("P")
    row = int(round(p.corners[:, 1].mean()))
    x0, x1 = int(p.bbox[0]) - 30, int(p.bbox[2]) + 30
    length = r.camera.fx * w * t * (1 + mount.forward / d)
    expect = _box_blur(still[row], length)[x0:x1]
    got = moving[row, x0:x1].astype(float)
    assert np.max(np.abs(got - expect)) < 6.0
    # a wrong blur length would not fit
    assert np.max(np.abs(got - _box_blur(still[row], 0.6 * length)[x0:x1])) > 15.0
    # horizontal edges (the bars' tops) stay sharp under a pure yaw
    col = int(round(p.corners[0, 0] + 0.5 * (p.corners[1, 0] - p.corners[0, 0]) / 3))
    top = int(round(p.corners[0, 1]))
    prof = moving[top - 8:top + 8, col].astype(float)
    ramp = np.count_nonzero((prof > prof.min() + 0.1 * np.ptp(prof)) & (prof < prof.max() - 0.1 * np.ptp(prof)))
    assert ramp <= 4


def test_lens_distortion_is_applied_and_undone_by_the_localizer(hall, mount, gl_context, rng):
    base = Camera.thesis(16)
    cam = Camera.from_intrinsics(base.fx, base.fy, base.cx, base.cy, base.width, base.height,
                                 dist=(-0.3, 0.1, 0.0, 0.0, 0.0))
    r = CameraRenderer(hall, cam, mount, context=gl_context, backend="pyrender")
    # target near the image's left edge, where barrel distortion moves it most
    vpose = vehicle_pose_for_target(mount, hall.target("P"), 2.5, math.radians(-20.0), math.radians(-10.0))
    img, truth = r.render(vpose, RenderConditions(), rng)
    undist, truth0 = r.render(vpose, RenderConditions(distortion=False), rng)
    t, t0 = truth.target("P"), truth0.target("P")
    shift = np.abs(t.corners - t0.corners).max()
    assert shift > 2.0  # the distortion is visible
    obs = detect_targets(img, cam)
    assert len(obs) == 1
    assert obs[0].distance == pytest.approx(t.distance, rel=0.01)
    assert math.degrees(abs(obs[0].alpha - t.alpha)) < 1.5
    # the distorted frame's truth corners are where the camera model puts them
    from localizer.model.geometry import TargetPose

    pose = TargetPose(t.distance, t.beta, t.alpha, t.height)
    b, hh = 0.075, 0.075
    expect = cam.project(pose.points(np.array([-1.5, 1.5, 1.5, -1.5]) * b, np.array([-hh, -hh, hh, hh])))
    np.testing.assert_allclose(t.corners, expect, atol=1e-9)
