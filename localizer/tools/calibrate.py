"""Camera calibration from views of a flat chessboard (OpenCV's calibration, Zhang's method).

The result is a :class:`~localizer.model.camera.Camera` (intrinsics, image size, lens distortion),
the camera the localizer needs for real frames: :meth:`Camera.to_opencv_yaml` writes it as the
file ``agvsim localize --camera`` and :meth:`Camera.from_opencv_yaml` read.

A board is named by its **inner corners** (the points where four squares meet): a board of
10 x 7 squares has 9 x 6 inner corners. Its corners are numbered as OpenCV finds them, along
a row first (``cols`` of them), then row by row (``rows`` rows); in the board's own frame
corner ``(c, r)`` lies at ``(c * square, r * square, 0)`` metres. The board needs a white
margin of about one square around its outer squares for the corners to be found.

Typical use, on grey images of one camera::

    corners = [find_chessboard(img, 9, 6) for img in images]      # (54, 2) px or None each
    result = calibrate_views([c for c in corners if c is not None], (w, h), 9, 6, 0.025)
    result.camera.to_opencv_yaml("calib.yaml")

Views should tilt the board (20 to 45 degrees, about both axes) and cover the frame, the
corners included; views that all face the camera square on leave the focal length undetermined
(:attr:`Calibration.sigma` shows it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from localizer.model.camera import Camera
from localizer.numeric import check_number

__all__ = ["DETECT_SIDE", "DIST_NAMES", "MIN_TILT_SPREAD", "MIN_VIEWS", "Calibration", "board_points", "calibrate_views",
           "check_board", "find_chessboard", "tilt_spread"]

#: the fewest views :func:`calibrate_views` accepts (OpenCV needs more than one plane for the
#: principal point; three tilted views are the least that determine fx, fy, cx, cy and k1, k2)
MIN_VIEWS = 3
#: the longer side (px) of the image :func:`find_chessboard` searches by default (larger ones are
#: shrunk for the search; the corners are refined on the full image)
DETECT_SIDE = 1280
#: the least angle between two views' boards (rad) :func:`calibrate_views` accepts: boards that
#: all lie in parallel planes leave the focal length undetermined (with a small reprojection
#: error and a small, meaningless standard deviation: 1235 px found for a true 800)
MIN_TILT_SPREAD = 5.0 * math.pi / 180.0


def check_board(cols, rows) -> tuple[int, int]:
    """``(cols, rows)`` inner corners as ints, or a ``ValueError``: each a whole number >= 3
    (OpenCV finds no board with fewer; a 3 x 3 board has 4 x 4 squares)."""
    return (check_number("chessboard cols", cols, low=3, high=1000, integer=True, unit="inner corners"),
            check_number("chessboard rows", rows, low=3, high=1000, integer=True, unit="inner corners"))


def board_points(cols: int, rows: int, square: float) -> np.ndarray:
    """The board's inner corners in its own frame: ``(cols * rows, 3)`` float32 array of
    ``(x, y, 0)`` metres, ``x = c * square`` along a row, ``y = r * square`` down the rows, in
    :func:`find_chessboard`'s order (row ``r``, then column ``c``).

    Raises:
        ValueError: a bad board (:func:`check_board`) or ``square`` not a finite number > 0 (m).
    """
    cols, rows = check_board(cols, rows)
    square = check_number("chessboard square", square, low=0.0, low_open=True, unit="m")
    c, r = np.meshgrid(np.arange(cols), np.arange(rows))
    pts = np.zeros((rows * cols, 3), np.float32)
    pts[:, 0] = c.ravel() * square
    pts[:, 1] = r.ravel() * square
    return pts


def _grey(image) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim != 2 or img.dtype != np.uint8 or min(img.shape) < 8:
        raise ValueError(f"image must be an (H, W) uint8 grey array of at least 8 x 8 pixels, "
                         f"got {img.dtype} {img.shape}")
    return np.ascontiguousarray(img)


def find_chessboard(image, cols: int, rows: int, max_side: int = DETECT_SIDE) -> np.ndarray | None:
    """The inner corners of a ``cols x rows`` chessboard in ``image``, to a tenth of a pixel or
    better, or None when the whole board is not seen.

    ``cv2.findChessboardCorners`` (adaptive threshold, normalized image, a fast check) on the
    image shrunk to at most ``max_side`` pixels along its longer side, then ``cv2.cornerSubPix``
    on the full image with a window as large as the board's smallest square allows (at most
    23 x 23 pixels). The search's cost grows quickly with the image on pictures without a board
    (a 4000 x 3000 picture of noise: 150 s at full size); shrunk, the board's squares must still
    be about 10 pixels wide.

    Args:
        image: ``(H, W)`` uint8 grey image.
        cols, rows: inner corners along a row and down a column (whole numbers >= 3).
        max_side: the longer side (px) of the image the board is searched in (whole number >= 64).
    Returns:
        ``(cols * rows, 2)`` float64 array of ``(x, y)`` pixel coordinates (pixel centres at
        whole numbers, as :mod:`localizer.model.camera`), in :func:`board_points`' order; or None.
    Raises:
        ValueError: ``image`` is not a grey uint8 image, or a bad board.
    """
    import cv2

    img = _grey(image)
    cols, rows = check_board(cols, rows)
    max_side = check_number("find_chessboard max_side", max_side, low=64, integer=True, unit="px")
    scale = min(1.0, max_side / max(img.shape))
    small = img if scale == 1.0 else cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
    found, corners = cv2.findChessboardCorners(small, (cols, rows), flags=flags)
    if not found or corners is None or len(corners) != cols * rows:
        return None
    if scale != 1.0:  # back to the full image (pixel centres at whole numbers in both)
        corners = ((corners.astype(float) + 0.5) * np.array([img.shape[1] / small.shape[1],
                                                             img.shape[0] / small.shape[0]]) - 0.5)
    grid = corners.reshape(rows, cols, 2).astype(float)
    spacing = min(np.linalg.norm(np.diff(grid, axis=0), axis=2).min(),
                  np.linalg.norm(np.diff(grid, axis=1), axis=2).min())
    half = int(min(11, max(2, math.floor(0.4 * spacing))))  # the window stops short of the next corner
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    refined = cv2.cornerSubPix(img, corners.astype(np.float32), (half, half), (-1, -1), criteria)
    out = refined.reshape(-1, 2).astype(float)
    if not np.all(np.isfinite(out)):  # pragma: no cover - OpenCV keeps corners inside the image
        return None
    return out


@dataclass(frozen=True)
class Calibration:
    """What :func:`calibrate_views` found.

    Attributes:
        camera: intrinsics (px), image size (px) and distortion coefficients in OpenCV order.
        rms: root-mean-square reprojection error over all corners of all views (px).
        view_rms: ``(n,)`` the same per view (px), in the order given.
        sigma: standard deviations of the estimate (OpenCV's, from the residuals) by name:
            ``fx``, ``fy``, ``cx``, ``cy`` (px) and the distortion coefficients (unitless).
        rvecs, tvecs: ``(n, 3)`` each view's board pose in the camera frame: Rodrigues vector
            (rad) and translation of the board's first corner (m).
        tilt_spread: the largest angle between the boards of two views (rad).
    """

    camera: Camera
    rms: float
    view_rms: np.ndarray
    sigma: dict
    rvecs: np.ndarray
    tvecs: np.ndarray
    tilt_spread: float


def tilt_spread(rvecs) -> float:
    """The largest angle (rad) between the board normals of the views with board poses
    ``rvecs`` (``(n, 3)`` Rodrigues vectors, rad)."""
    import cv2

    normals = np.array([cv2.Rodrigues(np.asarray(r, dtype=float).reshape(3))[0][:, 2] for r in rvecs])
    cosines = np.clip(normals @ normals.T, -1.0, 1.0)
    return float(np.arccos(cosines.min())) if len(normals) else 0.0


#: names of OpenCV's distortion coefficients, in its order
DIST_NAMES = ("k1", "k2", "p1", "p2", "k3")


def calibrate_views(image_points: Sequence, image_size: tuple[int, int], cols: int, rows: int, square: float,
                    k3: bool = False) -> Calibration:
    """Intrinsics and lens distortion from the corners of ``n >= 3`` views of one chessboard.

    ``cv2.calibrateCameraExtended`` with the distortion model ``(k1, k2, p1, p2, k3)``; ``k3``
    is held at 0 unless ``k3=True`` (wide-angle lenses): with a handful of views it soaks up
    noise and makes the edges of the frame worse, not better.

    Args:
        image_points: ``n`` arrays of ``(cols * rows, 2)`` pixel coordinates, as
            :func:`find_chessboard` returns them.
        image_size: ``(width, height)`` of the images (px).
        cols, rows: the board's inner corners (whole numbers >= 3).
        square: side of one square (m); it scales only ``tvecs``, not the intrinsics.
        k3: estimate the third radial coefficient too.
    Returns:
        A :class:`Calibration`.
    Raises:
        ValueError: fewer than :data:`MIN_VIEWS` views, a view of the wrong shape or with
            non-finite points, a bad size, board or square, views that do not determine the
            camera (boards within :data:`MIN_TILT_SPREAD` of parallel, or a non-positive focal
            length), or OpenCV failing on them.
    """
    import cv2

    obj = board_points(cols, rows, square)
    width = check_number("image width", image_size[0], low=8, integer=True, unit="px")
    height = check_number("image height", image_size[1], low=8, integer=True, unit="px")
    views = [np.asarray(v, dtype=float) for v in image_points]
    if len(views) < MIN_VIEWS:
        raise ValueError(f"calibration needs at least {MIN_VIEWS} views of the chessboard, got {len(views)}")
    for i, v in enumerate(views):
        if v.shape != (len(obj), 2) or not np.all(np.isfinite(v)):
            raise ValueError(f"view {i}: expected a finite ({len(obj)}, 2) array of pixel coordinates "
                             f"({cols} x {rows} corners), got shape {v.shape}")
    img_pts = [v.astype(np.float32).reshape(-1, 1, 2) for v in views]
    obj_pts = [obj.reshape(-1, 1, 3)] * len(views)
    flags = 0 if k3 else cv2.CALIB_FIX_K3
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    try:
        rms, k, dist, rvecs, tvecs, sd_int, _sd_ext, view_err = cv2.calibrateCameraExtended(
            obj_pts, img_pts, (width, height), None, None, flags=flags, criteria=criteria)
    except cv2.error as exc:
        raise ValueError(f"OpenCV could not calibrate from these views ({exc.msg.strip()})") from None
    spread = tilt_spread(rvecs)
    if spread < MIN_TILT_SPREAD:
        raise ValueError(f"the views do not determine the focal length: the boards of all {len(views)} views lie "
                         f"within {math.degrees(spread):.1f} degrees of parallel; expected views tilted 20 to 45 "
                         f"degrees in different directions (at least {math.degrees(MIN_TILT_SPREAD):g} apart)")
    dist = np.ravel(dist)[:5]
    try:
        camera = Camera.from_intrinsics(k[0, 0], k[1, 1], k[0, 2], k[1, 2], width, height, dist)
    except ValueError as exc:
        raise ValueError(f"the views do not determine the camera ({exc}); tilt the board more") from None
    sd = np.ravel(sd_int)
    sigma = {name: float(sd[i]) for i, name in enumerate(("fx", "fy", "cx", "cy") + DIST_NAMES)}
    return Calibration(camera=camera, rms=float(rms), view_rms=np.ravel(view_err).astype(float), sigma=sigma,
                       rvecs=np.asarray(rvecs, dtype=float).reshape(-1, 3),
                       tvecs=np.asarray(tvecs, dtype=float).reshape(-1, 3), tilt_spread=spread)
