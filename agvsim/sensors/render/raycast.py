"""The compiled column raycaster: radiance and depth of a camera frame without OpenGL.

:class:`RaycastBackend` flattens a :class:`~agvsim.sensors.render.scene.SceneDescription`
(its solids, decals and textures: the same scene the pyrender backend draws) into the
arrays of :mod:`agvsim.sensors.render.ray_records` once, then draws each frame with
:func:`agvsim.sensors.render._raycast_frame.render_view` (numba, one core).

A level camera sees exactly one floor-plan ray per image column (thesis §3.5), so the
frame is exact, not an approximation; pitch and roll jitter are a rotation about the lens
centre, drawn as the homography of a level frame rendered a little larger
(:meth:`RaycastBackend.draw`). Lighting is that of :mod:`agvsim.sensors.render.lighting`.
"""
from __future__ import annotations

import hashlib
import math

import numpy as np

from agvsim.sensors.render.lighting import Illumination
from agvsim.sensors.render.mount import CameraPose
from agvsim.sensors.render.ray_records import (Decals, Faces, Floor, FrameScratch, Light, Scene, SensorParams, Solids,
                                               Textures, View)
from agvsim.sensors.render.scene import SceneDescription
from agvsim.sensors.render.textures import SURFACE_TILE
from localizer.model.camera import Camera

__all__ = ["FLOOR_KEY", "NEAR", "SUBCOLUMNS", "RaycastBackend", "frame_buffers"]

NEAR = 0.05  # m, as the pyrender backend's near plane
SUBCOLUMNS = 4  # sub-column rays of a column that a silhouette crosses
DECAL_TOLERANCE = 0.005  # m, how far a decal may lie off its wall face
FLOOR_KEY = "floor-plane:surface:floor"  # the floor's texture entry: scene texture "surface:floor"
_NO_SENSOR = SensorParams(1.0, 0.0, 1.0, 0.0, 0.0, 0)  # (render_view's sensor when the radiance is stored)
_NO_IMAGE = np.zeros((0, 0), np.uint8)


class RaycastBackend:
    """Draws level frames of one scene (create once per map, reuse; holds no GL context; one frame
    at a time: the kernel's work arrays are the backend's).

    Args:
        scene: the scene (:func:`~agvsim.sensors.render.scene.build_scene`).
        illumination: the map's lighting.
        lighting_default: the map's default lighting level (for the background).
        subcolumns: sub-column rays of columns a silhouette crosses (1..16).
        mesh_geometry: draw the wall faces where the OpenGL meshes have them
            (:attr:`Solid.mesh_inset`, 2 mm inside the map's surface) instead of on the map's
            surface; only for comparisons with the pyrender reference.
    """

    def __init__(self, scene: SceneDescription, illumination: Illumination, lighting_default: float,
                 subcolumns: int = SUBCOLUMNS, mesh_geometry: bool = False) -> None:
        if isinstance(subcolumns, bool) or not isinstance(subcolumns, (int, np.integer)) or not 1 <= subcolumns <= 16:
            raise ValueError(f"subcolumns must be an integer 1..16, got {subcolumns!r}")
        self.subcolumns = int(subcolumns)
        self.lighting_default = float(lighting_default)
        keys: dict[str, int] = {}
        self.solids, self.faces, self.decals = _flatten_geometry(scene, keys, bool(mesh_geometry))
        floor_key = FLOOR_KEY  # its own entry (stored row-major), even if a face uses the same look
        keys.setdefault(floor_key, len(keys))
        tw, th = SURFACE_TILE["floor"]
        x0, y0, x1, y1 = scene.floor
        self.floor = Floor(float(x0), float(y0), float(x1), float(y1), keys[floor_key], float(tw), float(th),
                           float(scene.background))
        #: the scene's texture key of each texture index of the kernels' records (the floor's
        #: entry is FLOOR_KEY, its scene texture "surface:floor")
        self.texture_keys = tuple(sorted(keys, key=keys.get))
        self.textures = _summed_area_tables(scene, keys, {d.texture for d in scene.decals}, floor_key)
        self.solids = self.solids._replace(top_albedo=_top_albedo(scene, keys))
        self.light = _light(illumination, self.faces)
        #: what the frame kernels read of the map (one record: the kernels' one argument for it)
        self.scene = Scene(self.solids, self.faces, self.decals, self.textures, self.light, self.floor)
        self._work: FrameScratch | None = None  # the kernel's work arrays, for the last frame size

    # --------------------------------------------------------------- frame
    def view(self, camera: Camera, cam_pose: CameraPose, level: float | None, margin: int = 0) -> View:
        """The :class:`View` of a level camera at ``cam_pose`` (its jitter ignored), with the
        image grown by ``margin`` px on every side."""
        h = cam_pose.heading
        c, s = math.cos(h), math.sin(h)
        x, y, z = cam_pose.position.tolist()  # (floats: one call, not three numpy scalars)
        return View(float(camera.fx), float(camera.fy), float(camera.cx + margin), float(camera.cy + margin),
                    int(camera.width + 2 * margin), int(camera.height + 2 * margin), x, y, z,
                    c, s, s, -c, -1.0 if level is None else float(level),
                    float(self.lighting_default if level is None else level), NEAR, self.subcolumns)

    def draw_level(self, view: View, out: tuple[np.ndarray, np.ndarray] | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
        """``(radiance, depth)``, both ``(H, W)`` float32 in column-major order (Fortran order:
        the kernel draws a column at a time and stores each contiguously), of a level view: new
        arrays, or ``out`` overwritten (two writeable ``(H, W)`` float32 arrays in Fortran
        order, e.g. from :func:`frame_buffers`, reused frame after frame: pages already mapped).
        ``np.ascontiguousarray`` gives a row-major copy where one is needed."""
        from agvsim.sensors.render._raycast_frame import render_view
        from agvsim.sensors.render._raycast_kernels import bin_solids

        radiance, depth = out if out is not None else frame_buffers(view.width, view.height)
        shape = (view.height, view.width)
        for a in (radiance, depth):
            if (not isinstance(a, np.ndarray) or a.shape != shape or a.dtype != np.float32
                    or not a.T.flags.c_contiguous or not a.flags.writeable):
                got = f"{a.dtype} {a.shape}, {'F' if a.flags.f_contiguous else 'not F'}-contiguous" \
                    if isinstance(a, np.ndarray) else type(a).__name__
                raise ValueError(f"draw_level(out=) needs two writeable {shape} float32 arrays in column-major "
                                 f"(Fortran) order, as frame_buffers() makes; got {got}")
        render_view(view, self.scene, bin_solids(view, self.solids), radiance.T, depth.T,
                    self._scratch(view.width, view.height), _NO_SENSOR, _NO_IMAGE)
        return radiance, depth

    def draw_exposed(self, view: View, params: SensorParams, image: np.ndarray, depth: np.ndarray) -> None:
        """A level view exposed by the sensor as it is drawn: ``image`` ``(H, W)`` uint8, C-contiguous,
        overwritten with what :func:`~agvsim.sensors.render._sensor_kernels.expose_columns` makes of
        :meth:`draw_level`'s radiance with ``params`` (bit for bit), and ``depth`` (as
        :meth:`draw_level`'s ``out``) with the depth; the radiance is never stored."""
        from agvsim.sensors.render._raycast_frame import render_view
        from agvsim.sensors.render._raycast_kernels import bin_solids

        shape = (view.height, view.width)
        if (not isinstance(image, np.ndarray) or image.shape != shape or image.dtype != np.uint8
                or not image.flags.c_contiguous or not image.flags.writeable):
            raise ValueError(f"draw_exposed(image=) needs a writeable C-contiguous {shape} uint8 array")
        if (not isinstance(depth, np.ndarray) or depth.shape != shape or depth.dtype != np.float32
                or not depth.T.flags.c_contiguous or not depth.flags.writeable):
            raise ValueError(f"draw_exposed(depth=) needs a writeable {shape} float32 array in column-major order")
        render_view(view, self.scene, bin_solids(view, self.solids), depth.T, depth.T,
                    self._scratch(view.width, view.height), params, image)

    def _scratch(self, width: int, height: int) -> FrameScratch:
        """The kernel's work arrays for ``width`` x ``height`` frames (made at the first such frame)."""
        if self._work is None or self._work.floor_depth.shape[0] != height or self._work.e_n.shape[0] != width + 1:
            from agvsim.sensors.render._raycast_kernels import MAX_HITS, MAX_SPANS

            self._work = FrameScratch.of(width, height, MAX_SPANS, MAX_HITS)
        return self._work

    def draw(self, camera: Camera, cam_pose: CameraPose, level: float | None,
             out: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(radiance, depth)``: ``(H, W)`` float32 (depth m along the optical axis, 0 = nothing),
        new arrays or ``out`` overwritten (as :meth:`draw_level`'s), column-major (Fortran order).

        With pitch/roll jitter the level frame is drawn ``margin`` px larger and resampled
        through the homography ``K_m J K^-1`` of the rotation ``J`` about the lens centre
        (bilinear for radiance, nearest for depth, which is converted to the tilted axis).
        OpenCV resamples in row-major order; the results are stored into the column-major
        arrays.
        """
        if cam_pose.pitch == 0.0 and cam_pose.roll == 0.0:
            return self.draw_level(self.view(camera, cam_pose, level), out)
        import cv2

        from agvsim.sensors.render.mount import jitter_rotation

        jit = jitter_rotation(cam_pose.pitch, cam_pose.roll)
        reach = abs(cam_pose.pitch) * camera.fy + abs(cam_pose.roll) * 0.5 * math.hypot(camera.width, camera.height)
        margin = int(math.ceil(reach * 1.2)) + 2
        view = self.view(camera, cam_pose, level, margin)
        rad_level, depth_level = self.draw_level(view)
        k = camera.K
        km = k.copy()
        km[0, 2] += margin
        km[1, 2] += margin
        hom = km @ jit @ np.linalg.inv(k)  # actual pixel -> level pixel
        size = (camera.width, camera.height)
        flags = cv2.WARP_INVERSE_MAP
        rad, dep = out if out is not None else frame_buffers(camera.width, camera.height)
        rad[...] = cv2.warpPerspective(np.ascontiguousarray(rad_level), hom, size, flags=cv2.INTER_LINEAR | flags,
                                       borderMode=cv2.BORDER_REPLICATE)
        depth = cv2.warpPerspective(np.ascontiguousarray(depth_level), hom, size, flags=cv2.INTER_NEAREST | flags,
                                    borderMode=cv2.BORDER_REPLICATE)
        # depth along the tilted axis: Z_act = Z_level / (J (x_n, y_n, 1))_z (in float64, stored float32)
        jj, ii = np.meshgrid(np.arange(camera.width, dtype=np.float64), np.arange(camera.height, dtype=np.float64))
        lam = jit[2, 0] * (jj - camera.cx) / camera.fx + jit[2, 1] * (ii - camera.cy) / camera.fy + jit[2, 2]
        np.divide(depth, lam, out=dep, casting="same_kind")
        return rad, dep


def frame_buffers(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Two new ``(height, width)`` float32 arrays for a level frame's radiance and depth, in
    column-major (Fortran) order, as :meth:`RaycastBackend.draw_level` writes them: each the
    transpose of a C-contiguous ``(width, height)`` buffer starting on a 4096-byte boundary
    (NumPy aligns to 16 bytes; the kernel stores a column at a time, and a column that starts
    mid cache line costs it one more)."""
    out = []
    size = width * height * 4
    for _ in range(2):
        buf = np.empty(size + 4096, np.uint8)
        start = -buf.ctypes.data % 4096
        out.append(buf[start:start + size].view(np.float32).reshape(width, height).T)
    return out[0], out[1]


# ------------------------------------------------------------------ building
def _flatten_geometry(scene: SceneDescription, keys: dict[str, int], mesh_geometry: bool = False
                      ) -> tuple[Solids, Faces, Decals]:
    def tex(key: str) -> int:
        return keys.setdefault(key, len(keys))

    start, height, ex, ey, enx, eny, eface = [0], [], [], [], [], [], []
    fx, fy, fex, fey, flen, fnx, fny, fh, ftex, fu0, fu1, fv0, fv1 = ([] for _ in range(13))
    for solid in scene.solids:
        poly = np.asarray(solid.polygon, float)
        k = len(poly)
        for a in range(k):
            p, q = poly[a], poly[(a + 1) % k]
            d = q - p
            length = float(np.hypot(*d))
            e = d / length
            n = np.array([e[1], -e[0]])  # outward: right of p -> q on a CCW outline
            if mesh_geometry and solid.mesh_inset:
                p = p - n * solid.mesh_inset[a]
            ex.append(p[0])
            ey.append(p[1])
            enx.append(n[0])
            eny.append(n[1])
            look = solid.faces[a]
            if look is None:
                eface.append(-1)
                continue
            eface.append(len(fx))
            fx.append(p[0])
            fy.append(p[1])
            fex.append(e[0])
            fey.append(e[1])
            flen.append(length)
            fnx.append(n[0])
            fny.append(n[1])
            fh.append(solid.height)
            ftex.append(tex(look.texture))
            fu0.append(look.u[0])
            fu1.append(look.u[1])
            fv0.append(look.v[0])
            fv1.append(look.v[1])
        start.append(len(ex))
        height.append(solid.height)
    f64 = lambda v: np.ascontiguousarray(v, dtype=np.float64)  # noqa: E731
    faces_xy = np.column_stack([fx, fy]) if fx else np.zeros((0, 2))
    # decals: each on the face whose plane it lies in and whose extent holds its centre
    owners: list[list[tuple]] = [[] for _ in fx]
    for dec in scene.decals:
        left, right = np.asarray(dec.left, float), np.asarray(dec.right, float)
        centre = 0.5 * (left + right)
        best = None
        for f in range(len(fx)):
            if fnx[f] * dec.normal[0] + fny[f] * dec.normal[1] < 0.999:
                continue
            rel = centre - faces_xy[f]
            off = abs(rel[0] * fnx[f] + rel[1] * fny[f])
            s = rel[0] * fex[f] + rel[1] * fey[f]
            if off <= DECAL_TOLERANCE + (0.0025 if mesh_geometry else 0.0) and -1e-9 <= s <= flen[f] + 1e-9 and (best is None or off < best[0]):
                best = (off, f)
        if best is None and not mesh_geometry:
            raise ValueError(f"scene {scene.name!r}: decal {dec.texture!r} at ({centre[0]:.3f}, {centre[1]:.3f}) "
                             "lies on no wall face; expected every target and distractor on a wall surface")
        f = best[1]
        s0 = float(np.dot(left - faces_xy[f], (fex[f], fey[f])))
        s1 = float(np.dot(right - faces_xy[f], (fex[f], fey[f])))
        owners[f].append((tex(dec.texture), s0, s1, float(dec.z[0]), float(dec.z[1])))
    dstart, dtex, ds0, ds1, dz0, dz1 = [0], [], [], [], [], []
    for lst in owners:
        for t, s0, s1, z0, z1 in lst:
            dtex.append(t)
            ds0.append(s0)
            ds1.append(s1)
            dz0.append(z0)
            dz1.append(z1)
        dstart.append(len(dtex))
    solids = Solids(np.asarray(start, np.int64), f64(height), np.zeros(len(height)), f64(ex), f64(ey), f64(enx),
                    f64(eny), np.asarray(eface, np.int64))
    faces = Faces(f64(fx), f64(fy), f64(fex), f64(fey), f64(flen), f64(fnx), f64(fny), f64(fh),
                  np.asarray(ftex, np.int64), f64(fu0), f64(fu1), f64(fv0), f64(fv1), np.asarray(dstart, np.int64))
    decals = Decals(np.asarray(dtex, np.int64), f64(ds0), f64(ds1), f64(dz0), f64(dz1))
    return solids, faces, decals


def _summed_area_tables(scene: SceneDescription, keys: dict[str, int], decal_keys: set[str],
                        floor_key: str) -> Textures:
    """The textures in ``keys``: summed-area tables (float64, rows from the bottom: ``v`` up) of
    the decals' (they are integrated exactly), mip levels of the surfaces' (sampled as the
    reference samples them: the floor's stored row by row, the faces' column by column); each
    texture gets only what the kernels read of it.

    A decal's table is of its texels at their information content (:func:`_coarsest_texels`: a
    target's bars and margins are blocks of 128 x 128 equal texels, integrated the same over
    one); decals with the same texels share one table (a map's hazard signs are all alike);
    each table is summed in place, so building holds no temporaries of its size."""
    tiled = {p.texture: p.tiled for p in scene.parts}
    order = sorted(keys, key=keys.get)
    images = {k: scene.textures[k.split(":", 1)[1] if k == floor_key else k] for k in order}
    tables: dict[tuple, int] = {}  # (shape, digest of the texels) -> offset of their table
    offset = np.zeros(len(order), np.int64)
    width, height, unique = [], [], []
    size = 0
    for k, key in enumerate(order):
        tex = np.ascontiguousarray(images[key])
        if key in decal_keys:
            tex = _coarsest_texels(tex)
        height.append(tex.shape[0])
        width.append(tex.shape[1])
        if key not in decal_keys:
            continue
        same = (tex.shape, tex.dtype.str, hashlib.sha256(tex).digest())
        if same not in tables:
            tables[same] = size
            unique.append((size, tex))
            size += (tex.shape[0] + 1) * (tex.shape[1] + 1)
        offset[k] = tables[same]
    sat = np.zeros(max(size, 1), np.float64)
    for off, tex in unique:
        h, w = tex.shape
        table = sat[off:off + (h + 1) * (w + 1)].reshape(h + 1, w + 1)[1:, 1:]
        table[...] = tex[::-1]  # row 0 at v = 0
        np.cumsum(table, axis=0, out=table)
        np.cumsum(table, axis=1, out=table)
    levels = [_mip_levels(np.asarray(images[k], np.float32)[::-1], tiled.get(k, True))
              if k not in decal_keys else [np.zeros((1, 1), np.float32)] for k in order]
    column_major = [k != floor_key for k in order]  # the faces' are read a texel column at a time
    n_lev = max(len(lv) for lv in levels)
    mip_offset = np.zeros((len(order), n_lev), np.int64)
    mip_w = np.ones((len(order), n_lev), np.int64)
    mip_h = np.ones((len(order), n_lev), np.int64)
    chunks, pos = [], 0
    for k, lv in enumerate(levels):
        for lvl, img in enumerate(lv):
            mip_offset[k, lvl] = pos
            mip_h[k, lvl], mip_w[k, lvl] = img.shape
            chunks.append(img.T.ravel() if column_major[k] else img.ravel())
            pos += img.size
    mip = np.concatenate(chunks).astype(np.float32, copy=False)
    return Textures(sat, offset, np.asarray(width, np.int64), np.asarray(height, np.int64),
                    np.asarray([tiled.get(k, True) for k in order], np.bool_), mip,
                    mip_offset, mip_w, mip_h, np.asarray([len(lv) for lv in levels], np.int64),
                    np.asarray(column_major, np.bool_))


def _coarsest_texels(tex: np.ndarray) -> np.ndarray:
    """``tex`` on the coarsest texel grid on which it is the same piecewise-constant picture: each
    texel of the result is a ``fy x fx`` block of equal texels of ``tex``, ``fx`` the greatest
    common divisor of the width and of every column where the texels change (``fy`` likewise
    for rows). Its integral over any box is the same function of the box as ``tex``'s."""
    h, w = tex.shape
    cols = np.flatnonzero(np.any(tex[:, 1:] != tex[:, :-1], axis=0)) + 1
    rows = np.flatnonzero(np.any(tex[1:] != tex[:-1], axis=1)) + 1
    fx = math.gcd(w, *cols.tolist())
    fy = math.gcd(h, *rows.tolist())
    return np.ascontiguousarray(tex[::fy, ::fx])


def _mip_levels(img: np.ndarray, tiled: bool) -> list[np.ndarray]:
    """Box-filtered levels of ``img`` down to one texel (each half the size, rounded up)."""
    out = [np.ascontiguousarray(img, np.float32)]
    while out[-1].shape[0] > 1 or out[-1].shape[1] > 1:
        out.append(_half_size(out[-1]))
    return out


def _half_size(img: np.ndarray) -> np.ndarray:
    """``img`` (float32) at half its size, each texel the mean of the 2 x 2 (or 2, along a side of
    one texel) texels it covers, ``((a + b) + (c + d)) / 4`` in float32 (OpenCV's ``INTER_AREA``
    for a factor of two; it sums the last columns of a row in another order). An odd side goes
    to OpenCV's area resampling, which rounds it up."""
    h, w = img.shape
    if (h > 1 and h % 2) or (w > 1 and w % 2):
        import cv2

        return cv2.resize(img, (max(1, (w + 1) // 2), max(1, (h + 1) // 2)), interpolation=cv2.INTER_AREA)
    if w > 1:
        img = img[:, 0::2] + img[:, 1::2]
    if h > 1:
        img = img[0::2] + img[1::2]
    return img * np.float32(0.25 if h > 1 and w > 1 else 0.5)


def _top_albedo(scene: SceneDescription, keys: dict[str, int]) -> np.ndarray:
    """Reflectance of each solid's top: its texture sampled bilinearly at the top's ``(u, v)``."""
    out = []
    for solid in scene.solids:
        key, (u, v) = solid.top
        t = np.asarray(scene.textures[key], np.float64)
        h, w = t.shape
        x = (u % 1.0) * w - 0.5
        y = (1.0 - v % 1.0) * h - 0.5
        j, i = int(math.floor(x)), int(math.floor(y))
        fj, fi = x - j, y - i
        val = 0.0
        for di, wi in ((0, 1 - fi), (1, fi)):
            for dj, wj in ((0, 1 - fj), (1, fj)):
                val += wi * wj * t[(i + di) % h, (j + dj) % w]
        out.append(val)
    return np.asarray(out, np.float64)


FACE_LIGHT_RES = 0.25  # m between the samples of a face's irradiance table


def _light(ill: Illumination, faces: Faces) -> Light:
    """The kernel's lighting: the zone raster, on the same cells the floor's irradiance, and
    an irradiance table over every face (lamps are smooth at these scales)."""
    rows, cols = ill.zone_raster.shape
    xs = ill.raster_origin[0] + np.arange(cols) * ill.raster_res
    ys = ill.raster_origin[1] + np.arange(rows) * ill.raster_res
    floor_irr = np.empty((rows, cols), np.float32)
    for r0 in range(0, rows, 32):  # in blocks of rows (each cell on its own): small temporaries
        gx, gy = np.meshgrid(xs, ys[r0:r0 + 32])
        pts = np.stack([gx, gy, np.zeros_like(gx)], axis=-1)
        floor_irr[r0:r0 + 32] = ill.irradiance(pts, np.broadcast_to(np.array([0.0, 0.0, 1.0]), pts.shape))
    zone = np.ascontiguousarray(ill.zone_raster, np.float32)
    res = FACE_LIGHT_RES
    tables, offsets, cols, rows, pos = [], [], [], [], 0
    for f in range(len(faces.x)):
        nc = int(math.ceil(faces.length[f] / res)) + 1
        nr = int(math.ceil(faces.height[f] / res)) + 1
        ss, zz = np.meshgrid(np.arange(nc) * res, np.arange(nr) * res)
        p = np.stack([faces.x[f] + ss * faces.ex[f], faces.y[f] + ss * faces.ey[f], zz], axis=-1)
        n = np.broadcast_to(np.array([faces.nx[f], faces.ny[f], 0.0]), p.shape)
        tables.append(ill.irradiance(p, n).astype(np.float32).ravel())
        offsets.append(pos)
        cols.append(nc)
        rows.append(nr)
        pos += nc * nr
    face_irr = np.concatenate(tables) if tables else np.zeros(1, np.float32)
    # the floor pass reads 2 x 2 cells: a raster one cell wide or high gets its edge repeated
    # (bilinear values unchanged: beyond the last cell the kernels repeat it anyway)
    grow = ((0, max(0, 2 - zone.shape[0])), (0, max(0, 2 - zone.shape[1])))
    zone, floor_irr = np.pad(zone, grow, mode="edge"), np.pad(floor_irr, grow, mode="edge")
    return Light(float(ill.ambient), float(ill.lamp_origin[0]), float(ill.lamp_origin[1]), float(ill.lamp_spacing),
                 float(ill.lamp_height), float(ill.lamp_gain), zone, np.ascontiguousarray(floor_irr),
                 np.ascontiguousarray(floor_irr * zone), float(ill.raster_origin[0]), float(ill.raster_origin[1]),
                 float(ill.raster_res), face_irr, np.asarray(offsets, np.int64), np.asarray(cols, np.int64),
                 np.asarray(rows, np.int64), res)
