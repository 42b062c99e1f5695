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
    u0, v0, u1, v1 = view.map_box  # the map area, inside the gutters for the axes' labels
    assert np.allclose(corners[0], [u0, v0])
    assert np.allclose(corners[1], [u1, v1], atol=1.0)  # +y is up: ymin is at the bottom


def test_render_is_rgb_and_draws_the_vehicle_where_it_is(floor):
    view = TopDownView(floor, pixels_per_metre=10.0)
    station = floor.stations[0]
    x, y, theta = station.pose
    empty = view.render(legend=False)
    with_vehicle = view.render(vehicle_pose=(x, y, theta), legend=False)
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
    base = view.render(legend=False)
    img = view.render((Trajectory(route, (255, 0, 0), "route"),),
                      ellipses=((route[0, :2], np.diag([0.5, 0.1]), (0, 0, 255)),), legend=False)
    red = np.all(img == (255, 0, 0), axis=2).sum()
    assert red > 100  # the polyline
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


def _three_paths(floor):
    route = np.array([s.pose for s in floor.route("default")])
    return (Trajectory(route, (30, 150, 40), "true"),
            Trajectory(route + [0.8, 0.4, 0.0], (210, 40, 40), "dead reckoning"),
            Trajectory(route, (40, 90, 220), "EKF estimate")), route


@pytest.mark.parametrize("side", ["bottom", "right"])
def test_the_key_is_beside_the_map_not_on_it(floor, side):
    view = TopDownView(floor, key=side)
    paths, route = _three_paths(floor)
    img = view.render(paths, vehicle_pose=tuple(route[0]), ellipses=((route[1, :2], np.diag([0.2, 0.1]), (40, 90, 220)),))
    kx0, ky0, kx1, ky1 = view.key_box
    u0, v0, u1, v1 = view.map_box
    assert kx0 >= u1 or ky0 >= v1 + 10  # beside or below the map and its axis labels
    assert kx1 <= img.shape[1] and ky1 <= img.shape[0]
    for t in floor.targets:
        u, v = view.to_pixels(t.position)
        assert not (kx0 <= u <= kx1 and ky0 <= v <= ky1), t.id


def test_the_truth_is_drawn_above_the_estimate(floor):
    view = TopDownView(floor)
    paths, route = _three_paths(floor)  # the estimate lies exactly on the truth
    img = view.render(paths)
    mid = 0.5 * (route[0, :2] + route[1, :2])
    u, v = np.round(view.to_pixels(mid)).astype(int)
    assert tuple(img[v, u]) == (30, 150, 40)
    # and the estimate, drawn beneath and wider, still shows on either side of it
    near = img[v - 4:v + 5, u - 4:u + 5].reshape(-1, 3)
    assert any(tuple(p) == (40, 90, 220) for p in near)


def test_axes_and_scale_bar(floor):
    from agvsim.analysis.topdown_key import nice_step

    view = TopDownView(floor)
    img = view.render(_three_paths(floor)[0])
    kx0, ky0, kx1, ky1 = view.key_box
    key = img[ky0:ky1, kx0:kx1]
    dark = np.all(key < 60, axis=2)
    length = nice_step(view.scale, 0.4 * 160) * view.scale  # the bar: half dark, half white, outlined
    assert dark.sum(axis=1).max() >= 0.5 * length
    u0, v0, u1, v1 = view.map_box
    below = img[v1 + 4:v1 + 22, u0:u1]  # the x axis's tick labels, in metres
    assert np.any(np.all(below < 100, axis=2))
    left = img[v0:v1, :u0 - 4]
    assert np.any(np.all(left < 100, axis=2))
