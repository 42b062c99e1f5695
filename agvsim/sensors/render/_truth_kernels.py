"""The compiled frame truth (:mod:`agvsim.sensors.render.truth`): every target's level-frame
pose, the image geometry of those in front of the lens and the depth-buffer test of those in
view, into one table per frame.

IEEE double arithmetic in the order written (:data:`localizer._jit.jit`, no ``fastmath``): the
matrix products are the three-term sums of the target frame's rows, in row order.

The table's columns (:data:`COLUMNS`, ``(n, 21)`` float64, row ``t`` for target ``t``): ``d``,
``beta``, ``alpha``, ``z``, ``height`` (the level-frame pose), the active corners TL, TR, BR, BL
(x, y each), the printed face's bbox ``x0, y0, x1, y1``, the narrowest bar (px), the shortest
bar (rows), the occluded fraction, and the flags ``facing``, ``in_front``, ``in_view``,
``visible``, ``in_envelope`` as 0.0 / 1.0. Rows of targets not in front of the lens keep NaN
corners and bbox (the table is filled from :func:`blank_table`).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from agvsim.sensors.render.kernel_jit import exact_helper
from localizer._jit import jit

__all__ = ["COLUMNS", "CameraRotation", "TargetPoints", "TruthParams", "blank_table", "frame_table", "image_geometry", "occlusion_verdicts",
           "target_poses"]

#: the table's columns, in order (module docstring)
COLUMNS = ("d", "beta", "alpha", "z", "height", "x_tl", "y_tl", "x_tr", "y_tr", "x_br", "y_br", "x_bl", "y_bl",
           "bbox_x0", "bbox_y0", "bbox_x1", "bbox_y1", "bar_width_px", "bar_rows", "occluded", "facing",
           "in_front", "in_view", "visible", "in_envelope")
_D, _BETA, _ALPHA, _Z, _HEIGHT, _CORNERS, _BBOX, _BAR_W, _BAR_ROWS, _OCC = 0, 1, 2, 3, 4, 5, 13, 17, 18, 19
_FACING, _IN_FRONT, _IN_VIEW, _VISIBLE, _IN_ENV = 20, 21, 22, 23, 24
N_COLUMNS = len(COLUMNS)


class TruthParams(NamedTuple):
    """The camera and the thresholds of one frame's truth (SI units, pixels)."""

    fx: float  # px
    fy: float  # px
    cx: float  # px
    cy: float  # px
    width: int  # px
    height: int  # px
    supersample: int  # the depth buffer's pixels per image pixel, per axis
    near: float  # m: a printed face's corners nearer the lens plane than this are not in front
    min_bar_px: float  # px: the envelope's narrowest bar
    min_rows: float  # rows: the envelope's shortest bar
    max_alpha: float  # rad: the envelope's largest |alpha|


class TargetPoints(NamedTuple):
    """The map's targets as the truth kernels read them (:class:`~agvsim.sensors.render.truth.TruthGeometry`)."""

    frame: np.ndarray  # (n, 3, 3) float64, rows across, down, centre (m, map frame)
    outer_uv: np.ndarray  # (n, 4, 3) float64, rows [u, v, 1] of the printed face's corners (m)
    image_uv: np.ndarray  # (n, 16, 3) float64, the points projected for the image geometry
    grid_uv: np.ndarray  # (n, k, 3) float64, the occlusion grid's face points


class CameraRotation(NamedTuple):
    """Where the camera is and how it is turned (:func:`target_poses`'s ``position .. jittered``)."""

    position: np.ndarray  # (3,) float64, m, the lens in the map frame
    rot: np.ndarray  # (3, 3) float64, camera-to-map rotation of the actual camera
    level: np.ndarray  # (3, 3) float64, the same of the level camera
    jittered: bool  # False when the two are the same


def blank_table(n: int) -> np.ndarray:
    """A new ``(n, N_COLUMNS)`` table: NaN corners and bbox, zeros elsewhere."""
    table = np.zeros((n, N_COLUMNS))
    table[:, _CORNERS:_BAR_W] = np.nan
    return table


@jit
def target_poses(frame, position, rot, level, jittered, outer_uv, near, act, table):
    """Each target's pose in the level camera frame, whether it faces the lens and whether its
    printed face lies in front of the lens.

    Args:
        frame: ``(n, 3, 3)`` float64 per target, rows: across, down, centre (m, map frame;
            :class:`~agvsim.sensors.render.truth.TruthGeometry`).
        position: ``(3,)`` the lens (m, map frame). rot, level: ``(3, 3)`` camera-to-map rotations of
            the actual and the level camera; ``jittered``: False when they are the same.
        outer_uv: ``(n, 4, 3)`` rows ``[u, v, 1]`` of the printed face's corners (m).
        near: m. act: ``(n, 3, 3)`` out: the target frames in the actual camera (rows: across, down,
            lens -> centre). table: ``(n, N_COLUMNS)`` out: the pose columns, ``facing``, ``in_front``.

    The pose: ``p`` the centre, ``(cos α, 0, -sin α)`` across, in the level camera;
    ``d = hypot(p_x, p_z)``, ``β = atan2(p_x, p_z)``, ``α = atan2(-across_z, across_x)``,
    ``z = d cos β``; facing: ``normal . (lens - centre) > 0``.
    """
    n = frame.shape[0]
    lv = np.empty((3, 3))
    for t in range(n):
        for r in range(3):
            a = frame[t, r, 0] - (position[0] if r == 2 else 0.0)
            b = frame[t, r, 1] - (position[1] if r == 2 else 0.0)
            c = frame[t, r, 2] - (position[2] if r == 2 else 0.0)
            for k in range(3):
                lv[r, k] = a * level[0, k] + b * level[1, k] + c * level[2, k]
                act[t, r, k] = (a * rot[0, k] + b * rot[1, k] + c * rot[2, k]) if jittered else lv[r, k]
        d = math.hypot(lv[2, 0], lv[2, 2])
        beta = math.atan2(lv[2, 0], lv[2, 2])
        table[t, _D] = d
        table[t, _BETA] = beta
        table[t, _ALPHA] = math.atan2(-lv[0, 2], lv[0, 0])
        table[t, _Z] = d * math.cos(beta)
        table[t, _HEIGHT] = lv[2, 1]
        table[t, _FACING] = 1.0 if lv[0, 2] * lv[2, 0] - lv[0, 0] * lv[2, 2] < 0.0 else 0.0
        zmin = math.inf
        for q in range(outer_uv.shape[1]):
            zmin = min(zmin, outer_uv[t, q, 0] * act[t, 0, 2] + outer_uv[t, q, 1] * act[t, 1, 2]
                       + outer_uv[t, q, 2] * act[t, 2, 2])
        table[t, _IN_FRONT] = 1.0 if zmin > near else 0.0


@exact_helper
def _store_geometry(px, i, t, width, height, table):
    """Image geometry of one target from its 16 projected points ``px[i]`` into ``table[t]``:
    corners, bbox, ``in_view`` (the bbox inside the image), narrowest bar, shortest bar."""
    for q in range(4):
        table[t, _CORNERS + 2 * q] = px[i, q, 0]
        table[t, _CORNERS + 2 * q + 1] = px[i, q, 1]
    x0 = x1 = px[i, 4, 0]
    y0 = y1 = px[i, 4, 1]
    for q in range(5, 8):
        x, y = px[i, q, 0], px[i, q, 1]
        x0 = min(x0, x)
        x1 = max(x1, x)
        y0 = min(y0, y)
        y1 = max(y1, y)
    table[t, _BBOX] = x0
    table[t, _BBOX + 1] = y0
    table[t, _BBOX + 2] = x1
    table[t, _BBOX + 3] = y1
    inside = x0 >= -0.5 and y0 >= -0.5 and x1 <= width - 0.5 and y1 <= height - 0.5
    table[t, _IN_VIEW] = 1.0 if inside else 0.0
    bar = abs(px[i, 9, 0] - px[i, 8, 0])  # bar q between edges 8 + q and 9 + q
    for q in range(9, 11):
        bar = min(bar, abs(px[i, q + 1, 0] - px[i, q, 0]))
    tall = px[i, 12, 1] - px[i, 8, 1]  # edge q: bottom 12 + q - top 8 + q
    for q in range(1, 4):
        tall = min(tall, px[i, 12 + q, 1] - px[i, 8 + q, 1])
    table[t, _BAR_W] = bar
    table[t, _BAR_ROWS] = tall


@jit
def image_geometry(px, rows, width, height, table):
    """The image geometry of targets from their projected points (any projection: the
    distorted one is NumPy's, :meth:`localizer.model.camera.Camera.project`).

    Args:
        px: ``(m, 16, 2)`` float64 pixel x, y of each target's active-area corners TL, TR, BR, BL
            (points 0-3), printed-face corners (4-7), bar edges' tops (8-11) and bottoms (12-15)
            (:data:`agvsim.sensors.render.truth.IMAGE`).
        rows: ``(m,)`` int64, the targets' rows of ``table``.
        table: ``(n, N_COLUMNS)``, written at ``rows``: corners, bbox, bars, ``in_view``.
    """
    for i in range(px.shape[0]):
        _store_geometry(px, i, rows[i], width, height, table)


@exact_helper
def _pinhole_geometry(image_uv, act, params, table, px):
    """:func:`image_geometry` of the targets in front of the lens through the pinhole
    ``x = fx X / Z + cx``, ``y = fy Y / Z + cy`` (``px``: ``(1, 16, 2)`` scratch)."""
    for t in range(act.shape[0]):
        if table[t, _IN_FRONT] == 0.0:
            continue
        for q in range(image_uv.shape[1]):
            u, v, w = image_uv[t, q, 0], image_uv[t, q, 1], image_uv[t, q, 2]
            x = u * act[t, 0, 0] + v * act[t, 1, 0] + w * act[t, 2, 0]
            y = u * act[t, 0, 1] + v * act[t, 1, 1] + w * act[t, 2, 1]
            z = u * act[t, 0, 2] + v * act[t, 1, 2] + w * act[t, 2, 2]
            px[0, q, 0] = x / z * params.fx + params.cx
            px[0, q, 1] = y / z * params.fy + params.cy
        _store_geometry(px, 0, t, params.width, params.height, table)


@jit
def occlusion_verdicts(grid_uv, act, params, depth_t, has_depth, table):
    """The depth-buffer test of the targets in view, then ``visible`` and ``in_envelope`` of all.

    Args:
        grid_uv: ``(n, k, 3)`` rows ``[u, v, 1]`` of the occlusion grid's face points (m).
        act: ``(n, 3, 3)`` from :func:`target_poses`. params: :class:`TruthParams`.
        depth_t: ``(W s, H s)`` float32, C-contiguous: the transpose of the ``(H s, W s)`` depth
            buffer (m along the optical axis, 0 = nothing; ``s`` = ``params.supersample``), read
            when ``has_depth`` (one layout for every backend: one compiled specialization).
        table: ``(n, N_COLUMNS)``: ``occluded``, ``visible``, ``in_envelope`` written.

    A point (pinhole, undistorted: the buffer is) samples the buffer at ``floor((px + 0.5) s)``
    (column, row); it is hidden when the buffer there is nothing (0) or nearer than
    ``z - (0.004 + 0.0005 z)``. The fraction is of the points that fall in the buffer, 1 when
    none does.
    """
    s = params.supersample
    w, h = depth_t.shape
    for t in range(act.shape[0]):
        occ = 0.0
        if has_depth and table[t, _IN_VIEW] != 0.0:
            n_ok = 0
            n_hidden = 0
            for q in range(grid_uv.shape[1]):
                u, v, one = grid_uv[t, q, 0], grid_uv[t, q, 1], grid_uv[t, q, 2]
                x = u * act[t, 0, 0] + v * act[t, 1, 0] + one * act[t, 2, 0]
                y = u * act[t, 0, 1] + v * act[t, 1, 1] + one * act[t, 2, 1]
                z = u * act[t, 0, 2] + v * act[t, 1, 2] + one * act[t, 2, 2]
                col = np.int64(math.floor((x / z * params.fx + params.cx + 0.5) * s))
                row = np.int64(math.floor((y / z * params.fy + params.cy + 0.5) * s))
                if 0 <= col < w and 0 <= row < h:
                    n_ok += 1
                    zb = depth_t[col, row]
                    if zb >= 0 and zb < z - (0.004 + 0.0005 * z):
                        n_hidden += 1
            occ = n_hidden / n_ok if n_ok > 0 else 1.0
        table[t, _OCC] = occ
        visible = table[t, _FACING] != 0.0 and table[t, _IN_VIEW] != 0.0 and occ == 0.0
        table[t, _VISIBLE] = 1.0 if visible else 0.0
        env = (visible and table[t, _BAR_W] >= params.min_bar_px and table[t, _BAR_ROWS] >= params.min_rows
               and abs(table[t, _ALPHA]) <= params.max_alpha)
        table[t, _IN_ENV] = 1.0 if env else 0.0


@jit
def frame_table(targets, pose, params, depth_t, has_depth, act, table, px):
    """The whole table of an undistorted frame: :func:`target_poses`, the pinhole image
    geometry of the targets in front, :func:`occlusion_verdicts` (``targets``:
    :class:`TargetPoints`, ``pose``: :class:`CameraRotation`, the rest as theirs; ``px``:
    ``(1, 16, 2)`` float64 scratch)."""
    target_poses(targets.frame, pose.position, pose.rot, pose.level, pose.jittered, targets.outer_uv, params.near,
                 act, table)
    _pinhole_geometry(targets.image_uv, act, params, table, px)
    occlusion_verdicts(targets.grid_uv, act, params, depth_t, has_depth, table)
