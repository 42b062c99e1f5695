"""Sensor and optics on synthetic radiance (no OpenGL): saturation, seeded noise, motion blur
length, defocus, lens distortion maps; and RenderConditions / CameraMount validation."""
from __future__ import annotations

import math

import numpy as np
import pytest

from agvsim.sensors.render import sensor as sn
from agvsim.sensors.render.lighting import LIGHTING_LEVELS, lighting_level
from agvsim.sensors.render.mount import CameraMount, CameraPose, check_pose
from agvsim.sensors.render.renderer import RenderConditions
from localizer import Camera


def test_exposure_saturates_and_quantises():
    s = sn.SensorModel()
    rad = np.array([[0.06, 0.9]], np.float32)
    normal = sn.expose(rad, s, 1.0, False, None)
    bright = sn.expose(rad * LIGHTING_LEVELS["bright"], s, 1.0, False, None)
    assert normal.dtype == np.uint8
    assert 200 <= normal[0, 1] < 255 and normal[0, 0] < 30
    assert bright[0, 1] == 255 and bright[0, 0] < 100


def test_noise_is_seeded_and_grows_with_signal():
    s = sn.SensorModel()
    rad = np.full((200, 200), 0.1, np.float32)
    a = sn.expose(rad, s, 1.0, True, np.random.default_rng(1))
    b = sn.expose(rad, s, 1.0, True, np.random.default_rng(1))
    c = sn.expose(rad * 8, s, 1.0, True, np.random.default_rng(1))
    assert np.array_equal(a, b)
    assert 0.5 < a.std() < c.std()  # shot noise grows with the signal
    with pytest.raises(ValueError, match="Generator"):
        sn.expose(rad, s, 1.0, True, None)


def test_motion_blur_length_matches_yaw_rate():
    """A vertical step edge blurred by a pure yaw w over T spreads over fx * w * T pixels."""
    cam = Camera.thesis(16.0)
    rad = np.zeros(cam.shape, np.float32)
    rad[:, 256:] = 1.0
    depth = np.full(cam.shape, 5.0, np.float32)
    w, t = 1.0, 0.01  # rad/s, s
    out = sn.motion_blur(rad, depth, cam, (np.zeros(3), np.array([0.0, -w, 0.0])), t)
    row = out[240]
    ramp = np.count_nonzero((row > 0.02) & (row < 0.98))
    assert ramp == pytest.approx(cam.fx * w * t, abs=2.0)
    assert row[200] == 0.0 and row[320] == 1.0
    still = sn.motion_blur(rad, depth, cam, (np.zeros(3), np.zeros(3)), t)
    assert np.array_equal(still, rad)


def test_defocus_spreads_an_edge():
    rad = np.zeros((50, 50), np.float32)
    rad[:, 25:] = 1.0
    out = sn.defocus(rad, 2.0)
    assert 0.4 < out[25, 25] < 0.7 and out[25, 18] > 0.0
    assert np.array_equal(sn.defocus(rad, 0.0), rad)


def test_distortion_maps_invert_camera_projection():
    cam = Camera.from_intrinsics(930.9, 1163.6, 256.0, 240.0, 512, 480, dist=(-0.25, 0.08, 0.001, -0.0005, 0.0))
    mx, my = sn.distortion_maps(cam)
    ideal = Camera(cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height)
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-0.2, 0.2, 20), rng.uniform(-0.15, 0.15, 20), np.ones(20)])
    dist_px = cam.project(pts)
    ideal_px = ideal.project(pts)
    for (xd, yd), (xi, yi) in zip(dist_px, ideal_px):
        j, i = int(round(xd)), int(round(yd))
        # the map at the nearest pixel points back into the ideal image next to the ideal projection
        assert abs(mx[i, j] - (xi + (j - xd) * 1.0)) < 0.3
        assert abs(my[i, j] - (yi + (i - yd) * 1.0)) < 0.3


def test_conditions_validation():
    assert RenderConditions(lighting="bright").level == LIGHTING_LEVELS["bright"]
    assert RenderConditions().level is None
    assert RenderConditions(lighting=1.7).level == 1.7
    with pytest.raises(ValueError, match="unknown lighting"):
        RenderConditions(lighting="sunny")
    for bad in (dict(lighting=0.0), dict(lighting=float("nan")), dict(exposure=0.0), dict(defocus_px=-1.0),
                dict(velocity=(float("inf"), 0.0)), dict(velocity=(1.0,)), dict(exposure_time=-0.01)):
        with pytest.raises(ValueError):
            RenderConditions(**bad)
    assert lighting_level("map") is None


def test_mount_and_pose_validation():
    with pytest.raises(ValueError):
        CameraMount(height=0.0)
    with pytest.raises(ValueError):
        CameraMount(yaw=float("nan"))
    with pytest.raises(ValueError):
        CameraMount(pitch_sigma=-0.1)
    for bad in ((1.0, 2.0), (1.0, float("nan"), 0.0), "abc", (1.0, 2.0, float("inf"))):
        with pytest.raises(ValueError):
            check_pose(bad)


def test_mount_geometry():
    m = CameraMount.side_looking("right", height=1.0)
    pos, heading = m.camera_pose((2.0, 3.0, math.pi / 2))  # facing north: right is east
    assert heading == pytest.approx(0.0)
    assert pos == pytest.approx([2.3, 3.0, 1.0])
    assert m.vehicle_pose_for_camera(pos[:2], heading) == pytest.approx((2.0, 3.0, math.pi / 2))
    # a point 5 m straight ahead of a level camera and 0.2 m below it
    cp = CameraPose.from_vehicle(CameraMount(forward=0.0, height=1.0), (0.0, 0.0, 0.0))
    assert cp.to_camera([5.0, 0.0, 0.8]) == pytest.approx([0.0, 0.2, 5.0])
    assert cp.to_camera([5.0, 1.0, 1.0]) == pytest.approx([-1.0, 0.0, 5.0])  # north = left = -x


def test_depth_dependent_defocus():
    """Thin lens focused at 3 m: a surface at 3 m stays sharp, one at 0.8 m blurs by
    sigma = fx * aperture * |1/3 - 1/0.8| / 4 (about 1.7 px for the 16 mm lens at f/2)."""
    cam = Camera.thesis(16.0)
    rad = np.zeros((100, 200), np.float32)
    rad[:, 50:] = 1.0
    rad[:, 150:] = 0.0
    depth = np.full(rad.shape, 3.0, np.float32)
    depth[50:] = 0.8
    out = sn.defocus_depth(rad, depth, cam.fx, 0.008, 3.0)
    sharp, blurred = out[25], out[75]
    assert np.count_nonzero((sharp > 0.05) & (sharp < 0.95)) <= 2
    sigma = cam.fx * 0.008 * abs(1 / 3.0 - 1 / 0.8) / 4
    ramp = np.count_nonzero((blurred[:100] > 0.1) & (blurred[:100] < 0.9))  # 10-90 % width = 2.56 sigma
    assert ramp == pytest.approx(2.56 * sigma, abs=1.5)
    with pytest.raises(ValueError):
        RenderConditions(focus_distance=0.0)
