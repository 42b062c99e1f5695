"""What crosses the boundary of the raycaster's compiled kernels: named tuples and enums.

The scene is flattened once per map into the array tuples below (:class:`Solids`,
:class:`Faces`, :class:`Decals`, :class:`Textures`, :class:`Light`, :class:`Floor`) by
:mod:`agvsim.sensors.render.raycast` and held together as one :class:`Scene`; each frame
adds a :class:`View`, and the frame kernels hand the scalar records :class:`SubColumn`,
:class:`FaceSpan`, :class:`TexelColumns` and :class:`SpanLight` to their helpers (scalars
only: no array is copied per column or span). Units: metres,
pixels, radians; map frame x east, y north, z up. The sensor stages take a
:class:`SensorParams` (:mod:`agvsim.sensors.render._sensor_kernels`) and a
:class:`MotionBlurParams` (:mod:`agvsim.sensors.render._motion_blur_kernels`) per frame and a
:class:`BlurScratch` per camera. This module imports no numba.
"""
from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple

import numpy as np

__all__ = ["BlurScratch", "Decals", "EXPOSE_BLOCK", "FaceSpan", "Faces", "Floor", "FrameScratch", "Hits", "Light", "MotionBlurParams",
           "Scene", "SensorParams", "Solids", "SpanBuffer", "SpanKind", "SpanLight", "SubColumn", "TexelColumns", "Textures", "View"]


class SpanKind(IntEnum):
    """What a run of rows of one image column shows."""

    FACE = 0  # a vertical face of a solid (wall piece, obstacle side), decals on it
    FLAT = 1  # a horizontal surface: the floor (id -1) or the top of a solid (id = solid)
    BACKGROUND = 2  # nothing: the unmodelled roof / beyond the floor


class View(NamedTuple):
    """One level camera (optical axis horizontal, rows level; thesis §3.5) for one frame.

    A pixel column at image ``x`` is the ray ``C + Z (f + (x - cx) / fx · r)`` in the floor
    plan, ``Z`` the depth along the optical axis; row ``y`` at depth ``Z`` is at height
    ``cam_z - (y - cy) Z / fy``.
    """

    fx: float  # px
    fy: float  # px
    cx: float  # px
    cy: float  # px
    width: int  # px
    height: int  # px
    cam_x: float  # m, lens centre
    cam_y: float  # m
    cam_z: float  # m, lens height above the floor
    fwd_x: float  # unit optical axis in the floor plan
    fwd_y: float
    right_x: float  # unit camera x (right) in the floor plan
    right_y: float
    level: float  # lighting override (relative), or -1 for the map's zones
    background_level: float  # lighting level of the background
    near: float  # m, nothing nearer than this along the axis is drawn
    subcolumns: int  # sub-column rays of a column that a silhouette crosses


class Solids(NamedTuple):
    """Convex prisms standing on the floor; edge ``e`` of solid ``p`` is ``start[p] <= e < start[p + 1]``."""

    start: np.ndarray  # (P + 1,) int64
    height: np.ndarray  # (P,) float64, m
    top_albedo: np.ndarray  # (P,) float64, reflectance of the top
    edge_x: np.ndarray  # (E,) float64, m, a point of the edge's line
    edge_y: np.ndarray  # (E,) float64
    edge_nx: np.ndarray  # (E,) float64, outward unit normal
    edge_ny: np.ndarray  # (E,) float64
    edge_face: np.ndarray  # (E,) int64, face index, -1 for an inner edge


class Faces(NamedTuple):
    """Vertical faces: ``s`` (m) runs along the face from its left end seen from the front."""

    x: np.ndarray  # (F,) float64, m, left end
    y: np.ndarray  # (F,) float64
    ex: np.ndarray  # (F,) float64, unit direction left -> right
    ey: np.ndarray  # (F,) float64
    length: np.ndarray  # (F,) float64, m
    nx: np.ndarray  # (F,) float64, outward unit normal
    ny: np.ndarray  # (F,) float64
    height: np.ndarray  # (F,) float64, m
    texture: np.ndarray  # (F,) int64
    u0: np.ndarray  # (F,) float64, texture u at s = 0
    u1: np.ndarray  # (F,) float64, texture u at s = length
    v0: np.ndarray  # (F,) float64, texture v at z = 0
    v1: np.ndarray  # (F,) float64, texture v at z = height
    decal_start: np.ndarray  # (F + 1,) int64, decals of face f: decal_start[f] .. decal_start[f + 1]


class Decals(NamedTuple):
    """Printed quads on faces, in their face's ``(s, z)``: texture u 0 -> 1 over ``s0 .. s1``."""

    texture: np.ndarray  # (D,) int64
    s0: np.ndarray  # (D,) float64, m
    s1: np.ndarray  # (D,) float64, m
    z0: np.ndarray  # (D,) float64, m
    z1: np.ndarray  # (D,) float64, m


class Textures(NamedTuple):
    """Every texture twice, flat: its summed-area table (exact box integrals, for decals:
    texture ``k`` is ``(h + 1) x (w + 1)`` float64 at ``offset[k]``, ``sat[i, j]`` = sum of
    the texels of rows ``< i`` from the bottom and columns ``< j``) and its mip levels
    (bilinear samples at the footprint's scale, for wall, obstacle and floor surfaces)."""

    sat: np.ndarray  # (N,) float64
    offset: np.ndarray  # (T,) int64
    width: np.ndarray  # (T,) int64, texels
    height: np.ndarray  # (T,) int64, texels
    tiled: np.ndarray  # (T,) bool
    mip: np.ndarray  # (M,) float32, box-filtered mip levels, rows from the bottom (v up); row-major or column-major (below)
    mip_offset: np.ndarray  # (T, L) int64, level l of texture k at mip[mip_offset[k, l]:]
    mip_width: np.ndarray  # (T, L) int64, texels of level l
    mip_height: np.ndarray  # (T, L) int64
    mip_levels: np.ndarray  # (T,) int64, number of levels
    column_major: np.ndarray  # (T,) bool: texel (r, c) of a level at mip_offset + c * height + r (faces'), else r * width + c (the floor's)


class Floor(NamedTuple):
    """The floor rectangle and its tiled texture (``u = x / tile_w``, ``v = y / tile_h``)."""

    x0: float  # m
    y0: float
    x1: float
    y1: float
    texture: int
    tile_w: float  # m
    tile_h: float  # m
    background: float  # reflectance-equivalent radiance of what is beyond the scene


class Light(NamedTuple):
    """The map's illumination (:class:`agvsim.sensors.render.lighting.Illumination`)."""

    ambient: float
    lamp_x0: float  # m, lamp (0, 0)
    lamp_y0: float
    spacing: float  # m
    lamp_z: float  # m
    gain: float
    zone: np.ndarray  # (R, C) float32 lighting level raster
    floor_irradiance: np.ndarray  # (R, C) float32 ambient + lamps on the floor, same cells
    floor_zone_irradiance: np.ndarray  # (R, C) float32 the two multiplied
    raster_x0: float  # m, centre of cell (0, 0)
    raster_y0: float
    raster_res: float  # m per cell
    face_irr: np.ndarray  # (N,) float32 ambient + lamps on every face, rows of face_cols samples
    face_offset: np.ndarray  # (F,) int64, face f's table starts at face_irr[face_offset[f]]
    face_cols: np.ndarray  # (F,) int64, samples along s (every face_res m from s = 0)
    face_rows: np.ndarray  # (F,) int64, samples up z (every face_res m from z = 0)
    face_res: float  # m between samples


class Scene(NamedTuple):
    """A map's scene as the frame kernels read it: the records above, made once per map
    (:class:`agvsim.sensors.render.raycast.RaycastBackend`)."""

    solids: Solids
    faces: Faces
    decals: Decals
    tex: Textures
    light: Light
    floor: Floor


class SubColumn(NamedTuple):
    """The (sub-)column ``x0 .. x1`` of image column ``j`` whose spans are being shaded (a column
    the same spans cross whole, or one of its ``View.subcolumns`` parts)."""

    j: int  # image column
    x0: float  # px, left edge
    x1: float  # px, right edge
    weight: float  # its share of the column's radiance (1, or 1 / subcolumns)
    write_depth: bool  # its spans write the column's depth (it holds the column's centre)
    skip_lo: int  # rows a floor span covers whole that the floor pass drew: taken from the pass,
    skip_hi: int  #   neither shaded nor given a depth here (none if skip_hi < skip_lo)


class FaceSpan(NamedTuple):
    """One face span of a (sub-)column as the face kernels read it
    (:func:`agvsim.sensors.render._raycast_face.shade_face`); scalars only."""

    face: int  # face index (:class:`Faces`)
    z: float  # m, depth along the optical axis
    y0: float  # px, the span's rows y0 .. y1 (pixel i covers i - 0.5 .. i + 0.5)
    y1: float
    s_a: float  # m along the face where the sub-column's edge rays meet it (clamped to the face)
    s_b: float
    hc: float  # m, lens height
    cy: float  # px
    zpy: float  # m of height per image row at depth z
    gain: float  # sub-column weight x the lighting level at the span
    u_c: float  # texture u at the sub-column's centre
    u_half: float  # texture units from the centre to each of the two subsample columns
    va: float  # texture v of image row y: va + vb y
    vb: float
    d_lo: float  # m, the heights that decals crossing the footprint reach (d_hi < d_lo: none)
    d_hi: float


class TexelColumns(NamedTuple):
    """A face span's filtered texture: its one or two mip levels' texel columns in
    ``FrameScratch.texels``, each already weighted by its trilinear weight (scalars only)."""

    b0: int  # offset of the first level's column
    n0: int  # its texels
    t0a: float  # its texel coordinate of image row y: t0a + t0b y
    t0b: float
    b1: int  # the second level's, likewise (n1 == 0: none; its samples would be +0.0)
    n1: int
    t1a: float
    t1b: float


class SpanLight(NamedTuple):
    """A face span's irradiance: samples at rows ``y0 + m step`` in ``FrameScratch.irr[:n]``, linear between."""

    y0: float  # px
    step: float  # px
    inv_step: float  # 1 / px
    n: int  # samples (>= 2)


class SensorParams(NamedTuple):
    """Exposure and noise of one frame (:class:`agvsim.sensors.render.sensor.SensorModel`)."""

    scale: float  # grey levels per unit radiance (gain x exposure)
    flare: float  # grey levels
    electrons_per_grey: float  # full well / 255
    read_noise: float  # grey levels, sigma
    noise_scale: float  # multiplies both sigmas; 0 = no noise
    seed: int  # this frame's noise stream (drawn from the run's Generator)


class MotionBlurParams(NamedTuple):
    """The camera's motion over one exposure (:func:`agvsim.sensors.render.sensor.exposure_motion`):
    ``p(0) = rot p(t) + tr`` takes a point from the camera frame at the exposure's start (``a``)
    or end (``b``) to the camera frame at mid-exposure (camera axes, m)."""

    fx: float  # px
    fy: float  # px
    cx: float  # px
    cy: float  # px
    rot_a: np.ndarray  # (3, 3) float64
    tr_a: np.ndarray  # (3,) float64, m
    rot_b: np.ndarray  # (3, 3) float64
    tr_b: np.ndarray  # (3,) float64, m


class BlurScratch(NamedTuple):
    """Work arrays of the column-major motion blur
    (:func:`~agvsim.sensors.render._motion_blur_kernels.blur_columns`) for one image size,
    allocated once (:meth:`of`) and overwritten by every frame: every image row's prefix sums,
    stored a column at a time, and the current column's per-pixel paths."""

    prefix: np.ndarray  # (W + 1, H) float32, prefix[j, i] = sum of pixels 0 .. j - 1 of image row i
    offsets: np.ndarray  # (3, H) int32, per pixel i of the column j: floor(x0) - j, floor(x1) - j, first path row - i
    weights: np.ndarray  # (4, H) float32, per pixel: shares of the path's first and last pixel, row weights / length
    breaks: np.ndarray  # (H + 8 rounded up to a multiple of 8,) uint8, 1 where the offsets change down the column
    column: np.ndarray  # (H,) float32: the blurred column, when the frame is exposed as it is blurred
    exposed: np.ndarray  # (EXPOSE_BLOCK, H rounded up to 8) uint8: a block of exposed columns, likewise

    @classmethod
    def of(cls, height: int, width: int) -> BlurScratch:
        """Scratch for ``(height, width)`` images."""
        if height < 2 or width < 1:
            raise ValueError(f"BlurScratch needs height >= 2, width >= 1; got {height}, {width}")
        return cls(np.zeros((width + 1, height), np.float32), np.zeros((3, height), np.int32),
                   np.zeros((4, height), np.float32), np.ones(-(-(height + 8) // 8) * 8, np.uint8),
                   np.zeros(height, np.float32), np.zeros((EXPOSE_BLOCK, -(-height // 8) * 8), np.uint8))


#: columns exposed between two stores of the 8-bit frame (8 bytes: one 64-bit store a row;
#: :func:`agvsim.sensors.render._sensor_kernels.expose_columns`)
EXPOSE_BLOCK = 8

#: floats past the width in each row of :attr:`FrameScratch.floor_img` (a row of 512 would be 2 kB)
FLOOR_PAD = 16


class Hits(NamedTuple):
    """The prisms one ray crosses, in order of entry depth (``K`` at most)."""

    t_in: np.ndarray  # (K,) float64, m: entry depth
    t_out: np.ndarray  # (K,) float64, m: exit depth
    solid: np.ndarray  # (K,) int64
    edge: np.ndarray  # (K,) int64, the edge it enters by


class SpanBuffer(NamedTuple):
    """Spans of rays (``S`` per ray), front to back: rows ``y0 .. y1`` (px), kind
    (:class:`SpanKind`), id (face; solid or -1 for flat; -2 background), value (depth Z of a
    face, m; height of a flat span, m)."""

    y0: np.ndarray  # (N,) float64, px
    y1: np.ndarray  # (N,) float64, px
    kind: np.ndarray  # (N,) int64, SpanKind
    id: np.ndarray  # (N,) int64
    val: np.ndarray  # (N,) float64, m

    @classmethod
    def of(cls, n: int) -> SpanBuffer:
        return cls(np.zeros(n), np.zeros(n), np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n))


class FrameScratch(NamedTuple):
    """Work arrays of the raycaster's level frame for one image size (``W`` x ``H``), allocated
    once (:meth:`of`) and overwritten by every frame
    (:func:`agvsim.sensors.render._raycast_frame.render_view`): one backend draws one frame at
    a time. ``S`` spans per ray, ``K`` hits per ray."""

    hits: Hits  # (K,) each: a ray's prisms
    edges: SpanBuffer  # ((W + 1) S,) each: the spans of column edge ray r at r S ..
    e_n: np.ndarray  # (W + 1,) int64, spans of each edge ray
    drawn: np.ndarray  # (W, H) uint8, 1 where the floor pass drew the pixel
    row_lo: np.ndarray  # (H,) int64, first column of each row the floor pass draws
    row_hi: np.ndarray  # (H,) int64, last column
    floor_img: np.ndarray  # (H, W + FLOOR_PAD) float32: the floor pass's radiance (columns 0 .. W - 1)
    floor_depth: np.ndarray  # (H,) float32, m: the floor's depth per row
    floor_idx: np.ndarray  # (4 W,) uint64: the floor pass's texel and raster indices of a row
    floor_wts: np.ndarray  # (4 W,) float32: and their weights
    spans: SpanBuffer  # (S,) each: the spans of the column (or sub-column) being shaded
    acc: np.ndarray  # (H,) float64: a column's radiance
    irr: np.ndarray  # (H + 2,) float64: a face span's irradiance samples (SpanLight)
    cover: np.ndarray  # (2 H,) float64: a face span's decal coverage per row (printed mean x share, share)
    texels: np.ndarray  # (2 (4 H + 8),) float32: a face span's two texel columns (TexelColumns)
    column: np.ndarray  # (H,) float32: a column's radiance, when the frame is exposed as it is drawn
    exposed: np.ndarray  # (EXPOSE_BLOCK, H rounded up to 8) uint8: a block of exposed columns, likewise

    @classmethod
    def of(cls, width: int, height: int, spans: int, hits: int) -> FrameScratch:
        """Scratch for ``width`` x ``height`` frames, ``spans`` spans and ``hits`` prisms per ray."""
        if width < 1 or height < 1 or spans < 4 or hits < 1:
            raise ValueError(f"FrameScratch needs positive sizes; got {width}, {height}, {spans}, {hits}")
        f8, i8 = np.float64, np.int64
        return cls(Hits(np.zeros(hits), np.zeros(hits), np.zeros(hits, i8), np.zeros(hits, i8)),
                   SpanBuffer.of((width + 1) * spans), np.zeros(width + 1, i8),
                   np.zeros((width, height), np.uint8), np.zeros(height, i8), np.zeros(height, i8),
                   np.zeros((height, width + FLOOR_PAD), np.float32), np.zeros(height, np.float32),
                   np.zeros(4 * width, np.uint64), np.zeros(4 * width, np.float32), SpanBuffer.of(spans),
                   np.zeros(height), np.zeros(height + 2, f8), np.zeros(2 * height, f8),
                   np.zeros(2 * (4 * height + 8), np.float32), np.zeros(height, np.float32),
                   np.zeros((EXPOSE_BLOCK, -(-height // 8) * 8), np.uint8))
