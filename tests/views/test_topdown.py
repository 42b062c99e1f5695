"""The top-down view draws the map and what moves on it where it should."""
import numpy as np
import pytest

from agvsim.analysis.topdown import TopDownView, Trajectory
from agvsim.world import load_map


@pytest.fixture(scope="module")
def floor():
    return load_map("plant_floor")


def test_pixels_and_metres_agree(floor):
    view = TopDownView(floor, pixels_per_metre=10.0, margin=1.0)
    xmin, ymin, xmax, ymax = floor.bounds
    corners = view.to_pixels(np.array([[xmin - 1.0, ymax + 1.0], [xmax + 1.0, ymin - 1.0]]))
    assert np.allclose(corners[0], [0.0, 0.0])
    w, h = view.size
    assert np.allclose(corners[1], [w, h], atol=1.0)  # +y is up: ymin is at the bottom


def test_render_is_rgb_and_draws_the_vehicle_where_it_is(floor):
    view = TopDownView(floor, pixels_per_metre=10.0)
    station = floor.stations[0]
    x, y, theta = station.pose
    empty = view.render()
    with_vehicle = view.render(vehicle_pose=(x, y, theta))
    assert empty.dtype == np.uint8 and empty.ndim == 3 and empty.shape[2] == 3
    diff = np.any(empty != with_vehicle, axis=2)
    rows, cols = np.nonzero(diff)
    u, v = view.to_pixels(np.array([x, y]))
    assert abs(cols.mean() - u) < 3 and abs(rows.mean() - v) < 3
    # the chassis footprint is about 1.0 x 0.7 m = 70 px² at 10 px/m
    assert 40 < diff.sum() < 200


def test_trajectories_and_ellipses_are_drawn(floor):
    view = TopDownView(floor, pixels_per_metre=10.0)
    route = np.array([s.pose for s in floor.route("default")])
    base = view.render()
    img = view.render((Trajectory(route, (255, 0, 0), "route"),),
                      ellipses=((route[0, :2], np.diag([0.5, 0.1]), (0, 0, 255)),))
    red = np.all(img == (255, 0, 0), axis=2).sum()
    assert red > 100  # the polyline (and its legend swatch)
    # the 2σ ellipse: blue-dominant pixels about 2*sqrt(0.5) m = 14 px from its centre
    blue = (img[..., 2].astype(int) - img[..., 0] > 80) & (img[..., 2] > 150)
    rows, cols = np.nonzero(blue)
    u, v = view.to_pixels(route[0, :2])
    radii = np.hypot(cols - u, rows - v)
    assert len(radii) > 20
    assert radii.max() == pytest.approx(2 * np.sqrt(0.5) * view.scale, abs=1.5)
    assert not np.array_equal(base, img)


def test_save_png_round_trip(floor, tmp_path):
    import cv2

    view = TopDownView(floor, pixels_per_metre=5.0)
    img = view.render()
    path = TopDownView.save_png(img, tmp_path / "a" / "floor.png")
    back = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)
    assert np.array_equal(back, img)
