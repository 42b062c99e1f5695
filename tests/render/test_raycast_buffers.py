"""The raycaster's reused memory: kernel arguments, the frame's work arrays and the caller's
frame buffers.

* the frame kernels, compiled without reference counts, leave their arguments' counts as
  they were (frames drawn, exposed and blurred);
* a frame drawn after frames of other poses (and another lighting) is the same as drawn first:
  nothing of one frame's work arrays leaks into the next;
* every pixel of the frame is written, radiance and depth, whatever the buffers held (a span
  boundary on a pixel centre, as where a corridor wall meets the floor, included);
* ``draw_level(out=)`` writes into the caller's buffers the same frame as new arrays, and refuses
  buffers of another shape, type or layout (row-major among them) with a ``ValueError``;
* :func:`frame_buffers` are column-major and start on a page;
* the frame is column-major, its values those of the image: a row-major copy of it is the same
  picture, and the renderer's 8-bit frame, made from the column-major radiance, is row-major
  and the same image with noise off as a row-major radiance exposed;
* a still, level frame exposed as it is drawn (``draw_exposed``, what ``render()`` does when
  nothing lies between the scene and the sensor) is, noise included, bit for bit the stored
  radiance exposed afterwards, at widths that are not a multiple of the store's block too.
"""
from __future__ import annotations

import sys

import numpy as np
import pytest

from agvsim.sensors.render.raycast import frame_buffers
from agvsim.sensors.render.renderer import CameraRenderer
from agvsim.sensors.render.strip import route_poses
from agvsim.world import load_map
from localizer import Camera


@pytest.fixture(scope="module")
def plant():
    m = load_map("plant_floor")
    camera = Camera.thesis(16.0)
    return m, camera, CameraRenderer(m, camera, mount=m.camera_mount, backend="raycast")


def test_frame_kernels_leave_their_arguments_reference_counts_alone(plant):
    from agvsim.sensors.render.renderer import RenderConditions

    m, camera, r = plant
    e = r.engine
    arrays = [a for record in (e.solids, e.faces, e.decals, e.textures, e.light) for a in record
              if isinstance(a, np.ndarray)]
    rng = np.random.default_rng(0)
    poses = route_poses(m, 3, lookahead_target=False)
    r.render(poses[0], RenderConditions(velocity=(1.0, 0.3)), rng)  # (compiled, scratch made)
    counts = [sys.getrefcount(a) for a in arrays]
    for p in poses:
        r.render(p, RenderConditions(), rng)
        r.render(p, RenderConditions(velocity=(1.0, 0.3)), rng)
    assert [sys.getrefcount(a) for a in arrays] == counts


def test_a_frame_does_not_depend_on_the_frames_before_it(plant):
    m, camera, r = plant
    poses = route_poses(m, 8, lookahead_target=False)
    first = [r.engine.draw(camera, r.camera_pose(p), None) for p in poses[:1]][0]
    for p in poses[1:]:  # other poses (and another lighting level) through the same work arrays
        r.engine.draw(camera, r.camera_pose(p), None)
        r.engine.draw(camera, r.camera_pose(p), 0.4)
    again = r.engine.draw(camera, r.camera_pose(poses[0]), None)
    assert np.array_equal(first[0], again[0]) and np.array_equal(first[1], again[1])
    # and a renderer that never drew anything else draws it the same
    fresh = CameraRenderer(m, camera, mount=m.camera_mount, backend="raycast")
    alone = fresh.engine.draw(camera, fresh.camera_pose(poses[0]), None)
    assert np.array_equal(first[0], alone[0]) and np.array_equal(first[1], alone[1])


@pytest.mark.parametrize("map_name, lens", [("corridor", 16.0), ("corridor", 8.0), ("plant_floor", 16.0)])
def test_every_pixel_of_the_frame_is_written(map_name, lens):
    m = load_map(map_name)
    camera = Camera.thesis(lens)
    r = CameraRenderer(m, camera, backend="raycast")
    out = frame_buffers(camera.width, camera.height)
    for k, p in enumerate(route_poses(m, 20, lookahead_target=False)):
        out[0][:] = np.nan
        out[1][:] = np.nan
        r.engine.draw(camera, r.camera_pose(p), None, out)
        assert not np.isnan(out[0]).any(), f"pose {k}: radiance not written at {np.argwhere(np.isnan(out[0]))[:3]}"
        assert not np.isnan(out[1]).any(), f"pose {k}: depth not written at {np.argwhere(np.isnan(out[1]))[:3]}"


def test_draw_level_into_the_callers_buffers(plant):
    m, camera, r = plant
    pose = route_poses(m, 3, lookahead_target=False)[1]
    view = r.engine.view(camera, r.camera_pose(pose), None)
    rad, dep = r.engine.draw_level(view)
    out = frame_buffers(camera.width, camera.height)
    out[0][:] = -1.0
    out[1][:] = -1.0
    got = r.engine.draw_level(view, out)
    assert got[0] is out[0] and got[1] is out[1]
    assert np.array_equal(out[0], rad) and np.array_equal(out[1], dep)
    for bad in [(np.empty((camera.height, camera.width + 1), np.float32), out[1]),
                (out[0], np.empty((camera.height, camera.width), np.float64)),
                (np.empty((camera.height, camera.width), np.float32), out[1]),  # row-major
                (out[0][::-1], out[1])]:
        with pytest.raises(ValueError, match="draw_level"):
            r.engine.draw_level(view, bad)


def test_frame_buffers_are_column_major_and_start_on_a_page():
    rad, dep = frame_buffers(512, 480)
    for a in (rad, dep):
        assert a.shape == (480, 512) and a.dtype == np.float32 and a.flags.f_contiguous
        assert not a.flags.c_contiguous and a.ctypes.data % 4096 == 0


def test_the_column_major_frame_is_the_image(plant):
    from agvsim.sensors.render import RenderConditions
    from agvsim.sensors.render._sensor_kernels import expose
    from agvsim.sensors.render.ray_records import SensorParams

    m, camera, r = plant
    pose = route_poses(m, 3, lookahead_target=False)[1]
    rad, dep = r.engine.draw(camera, r.camera_pose(pose), None)
    assert rad.flags.f_contiguous and dep.flags.f_contiguous
    # (that it is not transposed: the fidelity tests hold it against pyrender's row-major frames)
    image, truth = r.render(pose, RenderConditions(noise=False), None)
    assert image.flags.c_contiguous and image.shape == (camera.height, camera.width)
    s = r.sensor
    params = SensorParams(float(s.gain), float(s.flare), float(s.full_well / 255.0), float(s.read_noise), 0.0, 0)
    row_major = np.empty_like(image)
    expose(np.ascontiguousarray(rad), params, row_major)
    assert np.array_equal(image, row_major)
    assert np.array_equal(np.ascontiguousarray(rad), rad)


@pytest.mark.parametrize("map_name, lens, crop", [("plant_floor", 16.0, None), ("corridor", 8.0, (3, 2, 500, 477))])
def test_a_frame_exposed_as_it_is_drawn_is_the_stored_radiance_exposed(map_name, lens, crop):
    from agvsim.sensors.render import RenderConditions
    from agvsim.sensors.render._sensor_kernels import expose_columns, expose_scratch

    m = load_map(map_name)
    camera = Camera.thesis(lens)
    if crop is not None:
        camera = camera.cropped(*crop)
    r = CameraRenderer(m, camera, backend="raycast")
    calls = []
    draw_exposed = r.engine.draw_exposed
    r.engine.draw_exposed = lambda *a: calls.append(1) or draw_exposed(*a)
    for k, p in enumerate(route_poses(m, 6, lookahead_target=False)):
        for cond in (RenderConditions(), RenderConditions(lighting="dim", noise=False)):
            image, _ = r.render(p, cond, np.random.default_rng(k))
            rng = np.random.default_rng(k)  # the same draws: the jitter (none), then the noise's seed
            rad, dep = r.engine.draw(camera, r.camera_pose(p, cond, rng), cond.level)
            stored = np.empty_like(image)
            expose_columns(rad.T, r._sensor_params(cond, rng if cond.noise else None), stored,
                           expose_scratch(camera.height))
            assert np.array_equal(image, stored), f"pose {k}, {cond.lighting}: {np.count_nonzero(image != stored)} pixels differ"
    assert len(calls) == 12  # (the frames did go through draw_exposed)
