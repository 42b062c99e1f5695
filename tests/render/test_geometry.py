"""The rendered pixel grid agrees with localizer.Camera: bar edges found in rendered frames by a
plain gradient scan lie within 0.5 px of the target's corners and edges projected by the camera
model (pyrender's y flip and half-pixel offset handled), for several poses and both lenses."""
from __future__ import annotations

import math

import numpy as np
import pytest

from agvsim.sensors.render.placement import vehicle_pose_for_target
from agvsim.sensors.render.renderer import RenderConditions
from localizer.model.geometry import TargetPose

pytestmark = pytest.mark.render

#: (lens mm, d m, alpha deg, beta deg)
POSES = [
    (16, 1.5, 0.0, 0.0), (16, 3.0, 30.0, 5.0), (16, 5.0, -45.0, -8.0), (16, 8.0, 60.0, 3.0),
    (50, 5.0, 20.0, 1.0), (50, 10.0, -40.0, -2.0), (50, 15.0, 10.0, 0.5),
]


def _gradient_peak(profile: np.ndarray, guess: float, sign: float, window: float = 2.0) -> float:
    """Subpixel position of the strongest step of the given ``sign`` (+1: dark to bright along the
    profile) within ``window`` px of ``guess``: the peak of the signed first difference
    (differences sit between pixel centres), refined by a parabola."""
    g = sign * np.diff(profile.astype(float))
    lo = max(1, int(math.floor(guess - window)))
    hi = min(len(g) - 2, int(math.ceil(guess + window)))
    j = lo + int(np.argmax(g[lo:hi + 1]))
    a, b, c = g[j - 1], g[j], g[j + 1]
    den = a - 2 * b + c
    off = 0.5 * (a - c) / den if den != 0 else 0.0
    return j + 0.5 + float(np.clip(off, -0.5, 0.5))


def measure_edges(image: np.ndarray, camera, pose: TargetPose, spec, polarity: str = "positive"):
    """Measured vs projected: x of the 4 vertical bar edges (mean over mid rows), y of the bars'
    tops and bottoms at the bar centre columns. Returns ``(measured, predicted)`` arrays."""
    b, hh = spec.bar_width, spec.bar_height / 2
    us = np.array([-1.5, -0.5, 0.5, 1.5]) * b
    top = camera.project(pose.points(us, -hh))
    bot = camera.project(pose.points(us, hh))
    meas, pred = [], []
    y0 = max(top[:, 1].max(), 0) + 0.3 * (bot[:, 1].min() - top[:, 1].max())
    y1 = min(bot[:, 1].min(), image.shape[0] - 1) - 0.3 * (bot[:, 1].min() - top[:, 1].max())
    rows = np.arange(int(math.ceil(y0)), int(math.floor(y1)) + 1)
    assert len(rows) >= 3
    pol = 1.0 if polarity == "positive" else -1.0  # positive: black bars on white
    for k in range(4):
        sign = pol * (-1.0 if k % 2 == 0 else 1.0)  # into a bar, out of a bar
        xs = [_gradient_peak(image[r], top[k, 0], sign) for r in rows]
        meas.append(float(np.mean(xs)))
        pred.append(float(top[k, 0]))
    for bar in range(2):  # bar centre columns
        uc = (-1.0 if bar == 0 else 1.0) * b
        for v, sign in ((-hh, -pol), (hh, pol)):
            p = camera.project(pose.points(np.array([uc]), v))[0]
            col = int(round(p[0]))
            cols = [col - 1, col, col + 1]
            ys = []
            for c in cols:
                # predicted y of the (slanted) edge at this exact column
                pa = camera.project(pose.points(np.array([uc - 0.5 * b, uc + 0.5 * b]), v))
                yc = np.interp(c, pa[:, 0], pa[:, 1]) if pa[1, 0] != pa[0, 0] else pa[0, 1]
                ys.append(_gradient_peak(image[:, c], yc, sign) - yc)
            meas.append(float(np.mean(ys)) + p[1])
            pred.append(float(p[1]))
    return np.array(meas), np.array(pred)


@pytest.mark.parametrize("lens,d,alpha,beta", POSES)
def test_rendered_edges_match_camera_model(hall_renderers, hall, mount, lens, d, alpha, beta):
    r = hall_renderers[lens]
    target = hall.target("P")
    vpose = vehicle_pose_for_target(mount, target, d, math.radians(alpha), math.radians(beta))
    image, truth = r.render(vpose, RenderConditions.ideal())
    t = truth.target("P")
    assert t.visible
    # the truth is the requested pose, in the localizer's conventions
    assert t.distance == pytest.approx(d, abs=1e-9)
    assert t.alpha == pytest.approx(math.radians(alpha), abs=1e-9)
    assert t.beta == pytest.approx(math.radians(beta), abs=1e-9)
    pose = TargetPose(t.distance, t.beta, t.alpha, t.height)
    spec = target.spec
    b, hh = spec.bar_width, spec.bar_height / 2
    corners = r.camera.project(pose.points(np.array([-1.5, 1.5, 1.5, -1.5]) * b, np.array([-hh, -hh, hh, hh])))
    np.testing.assert_allclose(t.corners, corners, atol=1e-9)
    meas, pred = measure_edges(image, r.camera, pose, spec)
    err = meas - pred
    assert np.max(np.abs(err)) < 0.5, f"edge errors (px): {np.round(err, 3)}"


def test_half_pixel_convention_is_not_off_by_half(hall_renderers, hall, mount):
    """Guard the test itself: shifting the prediction by half a pixel must break agreement."""
    r = hall_renderers[16]
    target = hall.target("P")
    vpose = vehicle_pose_for_target(mount, target, 1.5, 0.0, 0.0)
    image, truth = r.render(vpose, RenderConditions.ideal())
    t = truth.target("P")
    pose = TargetPose(t.distance, t.beta, t.alpha, t.height)
    meas, pred = measure_edges(image, r.camera, pose, target.spec)
    assert np.max(np.abs(meas - pred)) < 0.25
    assert np.max(np.abs(meas - (pred + 0.5))) > 0.25
