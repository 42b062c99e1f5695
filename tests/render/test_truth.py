"""Ground truth: occluded and out-of-view targets are not visible; the truth's corners sit on the
rendered bars (also with pitch/roll jitter); bright lighting saturates; same seed, same frame."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from agvsim.sensors.render.placement import vehicle_pose_for_target
from agvsim.sensors.render.renderer import RenderConditions

pytestmark = pytest.mark.render


def test_target_behind_crate_is_occluded(hall_renderers, hall, mount):
    r = hall_renderers[16]
    vpose = vehicle_pose_for_target(mount, hall.target("O"), 5.0, 0.0, 0.0)
    image, truth = r.render(vpose, RenderConditions.ideal())
    o = truth.target("O")
    assert o.in_view and o.facing
    assert o.occluded_fraction == 1.0
    assert not o.visible and not o.in_envelope
    # the same target seen from beside the crate is visible
    vpose = vehicle_pose_for_target(mount, hall.target("O"), 4.0, math.radians(-55.0), 0.0)
    _, truth = r.render(vpose, RenderConditions.ideal())
    assert truth.target("O").visible


def test_out_of_view_targets_are_not_visible(hall_renderers, hall, mount):
    r = hall_renderers[16]
    # target P at 3 m but the camera turned 40 deg away (beta beyond the half field of view)
    vpose = vehicle_pose_for_target(mount, hall.target("P"), 3.0, 0.3, math.radians(40.0))
    _, truth = r.render(vpose, RenderConditions.ideal())
    assert not truth.target("P").in_view and not truth.target("P").visible
    # half out of the image at the left edge
    half_fov = math.atan(r.camera.cx / r.camera.fx)
    vpose = vehicle_pose_for_target(mount, hall.target("P"), 3.0, -half_fov, -half_fov)
    _, truth = r.render(vpose, RenderConditions.ideal())
    p = truth.target("P")
    assert p.bbox[0] < 0 < p.bbox[2]
    assert not p.in_view and not p.visible
    # the camera faces away from the wall entirely: nothing visible
    x, y, th = vehicle_pose_for_target(mount, hall.target("P"), 3.0, 0.0, 0.0)
    _, truth = r.render((x, y, th + math.pi), RenderConditions.ideal())
    assert truth.visible == ()


def _bars_mean(image, corners):
    """Mean grey inside the left and right bars (shrunk by 25 %) given active-area corners TL, TR, BR, BL."""
    tl, tr, br, bl = corners
    x0, x1 = tl[0], tr[0]
    w = (x1 - x0) / 3
    y0, y1 = max(tl[1], tr[1]), min(bl[1], br[1])
    out = []
    for a in (x0, x0 + w, x0 + 2 * w):
        xs = slice(int(math.ceil(a + 0.25 * w)), int(math.floor(a + 0.75 * w)) + 1)
        ys = slice(int(math.ceil(y0 + 0.25 * (y1 - y0))), int(math.floor(y1 - 0.25 * (y1 - y0))) + 1)
        out.append(float(image[ys, xs].mean()))
    return out  # left bar, gap, right bar


@pytest.mark.parametrize("target_id,dark_bars", [("P", True), ("N", False)])
def test_corners_and_polarity_match_the_image(hall_renderers, hall, mount, target_id, dark_bars):
    r = hall_renderers[16]
    vpose = vehicle_pose_for_target(mount, hall.target(target_id), 2.5, math.radians(25.0), math.radians(-6.0))
    image, truth = r.render(vpose, RenderConditions.ideal())
    t = truth.target(target_id)
    left, gap, right = _bars_mean(image, t.corners)
    if dark_bars:
        assert left < 40 and right < 40 and gap > 120
    else:
        assert left > 120 and right > 120 and gap < 40
    assert t.polarity == ("positive" if dark_bars else "negative")


def test_jitter_moves_the_image_and_the_truth_together(hall, gl_context, rng):
    """With pitch/roll jitter the image shifts by about fy * pitch rows and the truth's corners follow."""
    from agvsim.sensors.render.mount import CameraMount
    from agvsim.sensors.render.renderer import CameraRenderer
    from localizer import Camera

    mount = CameraMount(height=1.2, pitch_sigma=math.radians(1.0), roll_sigma=math.radians(0.5))
    r = CameraRenderer(hall, Camera.thesis(16), mount, context=gl_context, backend="pyrender")
    vpose = vehicle_pose_for_target(mount, hall.target("P"), 2.0, 0.2, 0.0)
    _, still = r.render(vpose, RenderConditions.ideal())
    image, truth = r.render(vpose, RenderConditions(noise=False, jitter=True), np.random.default_rng(7))
    cp = truth.camera_pose
    assert cp.pitch != 0.0 and cp.roll != 0.0
    t0, t1 = still.target("P"), truth.target("P")
    # pitch up moves the target down the image; the truth's d, alpha, beta are the level-camera ones
    shift = np.mean(t1.corners[:, 1] - t0.corners[:, 1])
    assert shift == pytest.approx(r.camera.fy * math.tan(cp.pitch), rel=0.1, abs=1.0)
    assert (t1.distance, t1.alpha, t1.beta) == pytest.approx((t0.distance, t0.alpha, t0.beta))
    left, gap, right = _bars_mean(image, t1.corners)
    assert left < 40 and right < 40 and gap > 120


def test_bright_lighting_saturates_normal_does_not(hall_renderers, hall, mount, rng):
    r = hall_renderers[16]
    vpose = vehicle_pose_for_target(mount, hall.target("P"), 2.0, 0.0, 0.0)
    frames = {}
    for light in ("normal", "bright"):
        image, truth = r.render(vpose, RenderConditions(lighting=light), rng)
        x0, y0, x1, y1 = (int(round(v)) for v in truth.target("P").bbox)
        frames[light] = image[y0 + 3:y1 - 3, x0 + 3:x1 - 3]
    assert np.mean(frames["normal"] == 255) < 0.001
    white = frames["bright"] > 128
    assert np.mean(frames["bright"][white] == 255) > 0.95  # the paper clips
    assert np.median(frames["bright"][~white]) > np.median(frames["normal"][frames["normal"] < 128])


def test_map_zones_light_the_frame(hall, gl_context, rng):
    """Without an override, a surface in the hall's dim corner (level 0.3) images darker."""
    from agvsim.sensors.render.mount import CameraMount
    from agvsim.sensors.render.renderer import CameraRenderer

    r = CameraRenderer(hall, mount=CameraMount(height=1.2), context=gl_context, backend="pyrender")
    # look at the west wall: first inside the dim corner (y 20..30), then outside it
    dim, _ = r.render((3.5, 25.0, math.pi), RenderConditions.ideal())
    lit, _ = r.render((3.5, 12.0, math.pi), RenderConditions.ideal())
    assert np.median(dim) < 0.45 * np.median(lit)


def test_same_seed_same_frame(hall_renderers, hall, mount):
    r = hall_renderers[16]
    vpose = vehicle_pose_for_target(mount, hall.target("P"), 3.0, 0.4, 0.05)
    cond = RenderConditions(defocus_px=0.7)
    a, ta = r.render(vpose, cond, np.random.default_rng(3))
    b, tb = r.render(vpose, cond, np.random.default_rng(3))
    c, _ = r.render(vpose, cond, np.random.default_rng(4))
    assert np.array_equal(a, b)
    assert json.dumps(ta.to_dict()) == json.dumps(tb.to_dict())
    assert not np.array_equal(a, c)
    assert np.abs(a.astype(int) - c.astype(int)).mean() < 3  # only the noise differs


def test_rgb_on_request(hall_renderers, hall, mount):
    r = hall_renderers[16]
    vpose = vehicle_pose_for_target(mount, hall.target("N"), 3.0, 0.2, 0.0)
    grey, _ = r.render(vpose, RenderConditions(), np.random.default_rng(9))
    rgb, _ = r.render(vpose, RenderConditions(rgb=True), np.random.default_rng(9))
    assert grey.shape == (480, 512) and rgb.shape == (480, 512, 3) and rgb.dtype == np.uint8
    assert all(np.array_equal(rgb[..., k], grey) for k in range(3))


def test_renderers_of_one_map_share_the_gl_scene(hall, gl_context, hall_renderers, mount):
    """A second camera on the same map (here side-looking) reuses the uploaded scene; frames
    interleaved with it are unchanged."""
    from agvsim.sensors.render.mount import CameraMount
    from agvsim.sensors.render.renderer import CameraRenderer

    front = hall_renderers[16]
    side = CameraRenderer(hall, mount=CameraMount.side_looking("right", height=1.2), context=gl_context, backend="pyrender")
    vpose = vehicle_pose_for_target(mount, hall.target("P"), 3.0, 0.0, 0.0)
    a, _ = front.render(vpose, RenderConditions.ideal())
    s, truth = side.render(vpose, RenderConditions.ideal())
    b, _ = front.render(vpose, RenderConditions.ideal())
    assert side.engine.gl_scene[1] is front.engine.gl_scene[1]
    assert np.array_equal(a, b) and not np.array_equal(a, s)
    assert not truth.target("P").visible  # the side camera looks along the wall
    side.close()
