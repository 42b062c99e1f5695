"""Synthetic chessboard views through a known camera (lens distortion included), for the
calibration tests: each image pixel is traced back through the lens (``cv2.undistortPoints``)
and the board's plane to a point of a printed board, sampled from a fine texture of it."""
from __future__ import annotations

import functools

import cv2
import numpy as np

from localizer import Camera

#: the camera the views are made with: fx = fy = 800 px, principal point off centre, barrel
#: distortion k1 = -0.08, k2 = 0.02
TRUE_CAMERA = Camera.from_intrinsics(800.0, 800.0, 326.0, 236.0, 640, 480, (-0.08, 0.02, 0.0, 0.0, 0.0))
COLS, ROWS, SQUARE = 9, 6, 0.025  # inner corners, m
TEXTURE_PX = 24  # texture pixels per square

#: board poses: (tilt about x, tilt about y, roll about z) in degrees, board centre (x, y, z) in m
POSES = (
    ((0, 0, 0), (0.0, 0.0, 0.55)),
    ((30, 0, 5), (0.02, -0.01, 0.6)),
    ((-30, 0, -5), (-0.02, 0.02, 0.6)),
    ((0, 35, 10), (0.03, 0.0, 0.6)),
    ((0, -35, -10), (-0.03, 0.0, 0.6)),
    ((25, 25, 20), (-0.08, -0.05, 0.7)),
    ((-25, -25, -15), (0.08, 0.05, 0.7)),
    ((20, -30, 0), (0.06, -0.06, 0.65)),
)


def board_texture(cols: int = COLS, rows: int = ROWS, px: int = TEXTURE_PX) -> np.ndarray:
    """The printed board: ``cols + 1`` x ``rows + 1`` squares (dark at the top-left) in a
    white margin of one square; square ``(i, j)`` covers texture pixels ``[(i+1)px, (i+2)px)``."""
    w, h = (cols + 3) * px, (rows + 3) * px
    tex = np.full((h, w), 235, np.uint8)
    for r in range(rows + 1):
        for c in range(cols + 1):
            if (r + c) % 2 == 0:
                tex[(r + 1) * px:(r + 2) * px, (c + 1) * px:(c + 2) * px] = 25
    return tex


@functools.lru_cache(maxsize=4)
def _rays(camera: Camera) -> np.ndarray:
    """``(H, W, 2)`` undistorted normalized image coordinates of every pixel centre."""
    j, i = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    pix = np.stack([j.ravel(), i.ravel()], axis=1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    norm = cv2.undistortPoints(pix, camera.K, np.asarray(camera.dist or (0.0,) * 5), criteria=crit)
    return norm.reshape(camera.height, camera.width, 2)


def pose(tilt_deg, centre) -> tuple[np.ndarray, np.ndarray]:
    """``(rvec, tvec)`` of the board (its first inner corner) with its centre at ``centre`` (m)."""
    ax, ay, az = np.radians(tilt_deg)
    rx = cv2.Rodrigues(np.array([ax, 0.0, 0.0]))[0]
    ry = cv2.Rodrigues(np.array([0.0, ay, 0.0]))[0]
    rz = cv2.Rodrigues(np.array([0.0, 0.0, az]))[0]
    r = ry @ rx @ rz
    mid = np.array([(COLS - 1) * SQUARE / 2, (ROWS - 1) * SQUARE / 2, 0.0])
    t = np.asarray(centre, float) - r @ mid
    return cv2.Rodrigues(r)[0].ravel(), t


def render_view(camera: Camera, rvec, tvec, noise: float = 1.0, seed: int = 0) -> np.ndarray:
    """``(H, W)`` uint8 image of the board at pose ``(rvec, tvec)`` (board frame of
    :func:`localizer.tools.calibrate.board_points`), slightly blurred, with Gaussian noise (grey levels)."""
    r = cv2.Rodrigues(np.asarray(rvec, float))[0]
    h_inv = np.linalg.inv(np.column_stack([r[:, 0], r[:, 1], np.asarray(tvec, float)]))
    rays = _rays(camera)
    homog = np.concatenate([rays, np.ones(rays.shape[:2] + (1,))], axis=2) @ h_inv.T
    w = homog[..., 2]
    # board metres -> texture pixels: inner corner (0, 0) sits 2 squares in; boundaries at half-pixels
    scale = TEXTURE_PX / SQUARE
    map_x = np.where(w > 0, homog[..., 0] / w * scale + 2 * TEXTURE_PX - 0.5, -1e4).astype(np.float32)
    map_y = np.where(w > 0, homog[..., 1] / w * scale + 2 * TEXTURE_PX - 0.5, -1e4).astype(np.float32)
    img = cv2.remap(board_texture(), map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=110).astype(float)
    img = cv2.GaussianBlur(img, (0, 0), 0.7)
    img += np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def true_corners(camera: Camera, rvec, tvec) -> np.ndarray:
    """``(COLS * ROWS, 2)`` where the board's inner corners project (px)."""
    from localizer.tools.calibrate import board_points

    pts, _ = cv2.projectPoints(board_points(COLS, ROWS, SQUARE).astype(float), np.asarray(rvec, float),
                               np.asarray(tvec, float), camera.K, np.asarray(camera.dist or (0.0,) * 5))
    return pts.reshape(-1, 2)


def write_views(folder, camera: Camera = TRUE_CAMERA, poses=POSES, prefix: str = "view") -> list:
    """Render ``poses`` through ``camera`` into ``folder/PREFIX_NN.png``; the paths."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for n, (tilt, centre) in enumerate(poses):
        rvec, tvec = pose(tilt, centre)
        path = folder / f"{prefix}_{n:02d}.png"
        cv2.imwrite(str(path), render_view(camera, rvec, tvec, seed=n))
        paths.append(path)
    return paths
