"""localizer.tools.calibrate on synthetic chessboard views through a known camera (lens distortion
included): corners to a tenth of a pixel, intrinsics to a fraction of a percent, bad input refused."""
from __future__ import annotations

import numpy as np
import pytest

from localizer import Camera
from localizer.tools.calibrate import MIN_VIEWS, board_points, calibrate_views, find_chessboard, tilt_spread
from tests.cli.chessboard_views import COLS, POSES, ROWS, SQUARE, TRUE_CAMERA, pose, render_view, true_corners


@pytest.fixture(scope="module")
def views():
    """``[(image, true corners (px), rvec, tvec)]`` for every pose of POSES."""
    out = []
    for n, (tilt, centre) in enumerate(POSES):
        rvec, tvec = pose(tilt, centre)
        out.append((render_view(TRUE_CAMERA, rvec, tvec, seed=n), true_corners(TRUE_CAMERA, rvec, tvec), rvec, tvec))
    return out


def test_board_points_are_in_opencv_order():
    pts = board_points(4, 3, 0.03)
    assert pts.shape == (12, 3) and pts.dtype == np.float32
    assert np.allclose(pts[1], [0.03, 0, 0]) and np.allclose(pts[4], [0, 0.03, 0]) and np.allclose(pts[-1], [0.09, 0.06, 0])


def test_corners_are_found_to_a_tenth_of_a_pixel(views):
    for img, truth, _, _ in views:
        found = find_chessboard(img, COLS, ROWS)
        assert found is not None and found.shape == (COLS * ROWS, 2)
        err = np.linalg.norm(found - truth, axis=1)
        assert err.max() < 0.1, err.max()


def test_corners_searched_in_a_shrunk_image_are_refined_on_the_full_one(views):
    """Large pictures are searched shrunk (the search's cost grows fast with the size): 640 x 480
    searched at 320 x 240 (squares 20 px wide there) still gives corners to a tenth of a pixel."""
    for img, truth, _, _ in views[:4]:
        found = find_chessboard(img, COLS, ROWS, max_side=320)
        assert found is not None and np.linalg.norm(found - truth, axis=1).max() < 0.1


def test_no_board_and_the_wrong_board_give_none(views):
    rng = np.random.default_rng(1)
    noise = rng.integers(0, 256, (480, 640), dtype=np.uint8)
    assert find_chessboard(noise, COLS, ROWS) is None
    assert find_chessboard(np.full((480, 640), 128, np.uint8), COLS, ROWS) is None
    assert find_chessboard(views[0][0], COLS + 1, ROWS) is None  # 10x6 is not a 9x6 board


def test_calibration_recovers_the_camera(views):
    result = calibrate_views([find_chessboard(v[0], COLS, ROWS) for v in views], (640, 480), COLS, ROWS, SQUARE)
    cam = result.camera
    assert isinstance(cam, Camera) and cam.size == (640, 480)
    assert abs(cam.fx / TRUE_CAMERA.fx - 1) < 0.01 and abs(cam.fy / TRUE_CAMERA.fy - 1) < 0.01
    assert abs(cam.cx - TRUE_CAMERA.cx) < 3 and abs(cam.cy - TRUE_CAMERA.cy) < 3
    assert abs(cam.dist[0] - TRUE_CAMERA.dist[0]) < 0.01 and cam.dist[4] == 0.0  # k3 held at 0
    assert result.rms < 0.1 and result.view_rms.shape == (len(views),) and np.all(result.view_rms < 0.1)
    assert 0 < result.sigma["fx"] < 2 and result.sigma["k3"] == 0.0
    assert 60 < np.degrees(result.tilt_spread) < 80  # POSES: (25, 25) against (-25, -25) degrees
    # the poses come back: the board's first corner (m), scaled by the square
    assert np.allclose(result.tvecs, [v[3] for v in views], atol=0.005)
    half = calibrate_views([find_chessboard(v[0], COLS, ROWS) for v in views], (640, 480), COLS, ROWS, SQUARE / 2)
    assert np.allclose(half.tvecs, result.tvecs / 2, atol=1e-4) and abs(half.camera.fx - cam.fx) < 1e-3
    # the projections it predicts are where the corners are
    assert np.abs(cam.project(np.array([[0.1, -0.05, 0.6]])) - TRUE_CAMERA.project(np.array([[0.1, -0.05, 0.6]]))).max() < 2


def test_wrong_truth_would_fail(views):
    """The test can fail: corners from a camera 5 % longer are not recovered as TRUE_CAMERA."""
    long = Camera.from_intrinsics(840.0, 840.0, 326.0, 236.0, 640, 480, TRUE_CAMERA.dist)
    pts = [true_corners(long, v[2], v[3]) for v in views]
    cam = calibrate_views(pts, (640, 480), COLS, ROWS, SQUARE).camera
    assert abs(cam.fx - 840.0) < 0.5 and abs(cam.fx / TRUE_CAMERA.fx - 1) > 0.04


def test_parallel_boards_are_refused():
    """Boards in parallel planes (here all tilted 30 degrees the same way) fit a wrong focal length
    (about 1234 px for 800) with a small error and standard deviation: refused, not reported."""
    pts = [true_corners(TRUE_CAMERA, *pose((30, 0, roll), centre))
           for roll, centre in ((0, (0, 0, 0.55)), (0, (0.05, 0, 0.6)), (10, (-0.05, 0.02, 0.5)))]
    with pytest.raises(ValueError, match="do not determine the focal length.*within 0.[0-9] degrees of parallel"):
        calibrate_views(pts, (640, 480), COLS, ROWS, SQUARE)


def test_tilt_spread():
    rvecs = [pose(tilt, (0, 0, 0.6))[0] for tilt in ((0, 0, 0), (0, 0, 40), (20, 0, 0), (0, -30, 0))]
    assert tilt_spread(rvecs[:2]) == pytest.approx(0.0, abs=1e-9)
    assert np.degrees(tilt_spread(rvecs)) == pytest.approx(np.degrees(np.arccos(np.cos(np.radians(20))
                                                                                * np.cos(np.radians(30)))))


@pytest.mark.parametrize("call, needle", [
    (lambda pts: calibrate_views(pts[:2], (640, 480), COLS, ROWS, SQUARE), f"at least {MIN_VIEWS} views"),
    (lambda pts: calibrate_views(pts, (640, 480), COLS, ROWS, 0.0), "square must be a finite number > 0 (m)"),
    (lambda pts: calibrate_views(pts, (640, 480), COLS, ROWS, float("nan")), "square"),
    (lambda pts: calibrate_views(pts, (640, 480), 2, ROWS, SQUARE), "cols must be a whole number >= 3"),
    (lambda pts: calibrate_views(pts, (640, 480), COLS, ROWS - 1, SQUARE), "view 0: expected a finite (45, 2)"),
    (lambda pts: calibrate_views(pts, (0, 480), COLS, ROWS, SQUARE), "image width"),
    (lambda pts: calibrate_views([p[:10] for p in pts], (640, 480), COLS, ROWS, SQUARE), "view 0"),
    (lambda pts: calibrate_views([np.full_like(pts[0], np.nan)] + pts, (640, 480), COLS, ROWS, SQUARE), "finite"),
    (lambda pts: find_chessboard(np.zeros((480, 640, 3), np.uint8), COLS, ROWS), "uint8 grey"),
    (lambda pts: find_chessboard(np.zeros((480, 640)), COLS, ROWS), "uint8 grey"),
    (lambda pts: find_chessboard(np.zeros((480, 640), np.uint8), 9.5, ROWS), "whole number"),
    (lambda pts: find_chessboard(np.zeros((480, 640), np.uint8), COLS, ROWS, max_side=10), "max_side"),
])
def test_bad_input_is_a_value_error(views, call, needle):
    pts = [v[1] for v in views]
    with pytest.raises(ValueError) as info:
        call(pts)
    assert needle in str(info.value)
