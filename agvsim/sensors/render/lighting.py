"""Illumination: ambient light, a grid of ceiling lamps, and the map's lighting zones.

The renderer draws surface reflectance (albedo) with OpenGL and lights it
here, per pixel, from the depth buffer (deferred shading, all linear):

    radiance = albedo * (ambient + lamps(point, normal)) * level(point)

* ``ambient``: light from everywhere (fraction of the normal illumination).
* ``lamps``: downward-facing Lambertian lamps on a square ceiling grid,
  ``cos(emission) cos(incidence) / r^2`` from the 3 x 3 lamps nearest each point, scaled so that a vertical wall at
  camera height receives at most 1.0 (ambient included) -- "normal" light.
* ``level``: the map's lighting level at the point's floor position (``Map.lighting_at``:
  1 normal, < 1 dim, > 1 bright), sampled from a raster built once; or one
  level for the whole frame when the render conditions override it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from localizer.numeric import check_number

#: Named lighting levels for ``RenderConditions.lighting`` / ``agvsim render --lighting``
#: (relative illumination; 2.8 saturates the white of a target exposed for normal light,
#: like the thesis's Fig. 5.5).
LIGHTING_LEVELS: dict[str, float] = {"dim": 0.3, "normal": 1.0, "bright": 2.8}

AMBIENT = 0.6  # fraction of normal illumination on a wall that comes from everywhere
LAMP_SPACING = 6.0  # m between ceiling lamps
MAX_LAMP_HEIGHT = 6.0  # m
RASTER_RES = 0.1  # m per cell of the lighting-zone raster
RASTER_BLOCK_ROWS = 32  # raster rows computed at a time (each cell on its own: the same raster)


def lighting_level(value) -> float | None:
    """Resolve a lighting override: None (use the map's zones), a name of
    :data:`LIGHTING_LEVELS` or a positive finite level.

    Raises:
        ValueError: unknown name or a level that is not finite and > 0.
    """
    if value is None:
        return None
    if isinstance(value, str):
        key = value.strip().lower()
        if key in ("map", "zones"):
            return None
        if key == "saturated":
            key = "bright"
        if key not in LIGHTING_LEVELS:
            raise ValueError(f"unknown lighting {value!r}; expected one of "
                             f"{', '.join(LIGHTING_LEVELS)}, 'map' or a positive number")
        return LIGHTING_LEVELS[key]
    return check_number("lighting level", value, low=0.0, low_open=True)


@dataclass(frozen=True, eq=False)
class Illumination:
    """Lighting of one map (built once by :meth:`from_map`).

    Attributes:
        ambient: ambient irradiance (relative).
        lamp_origin: ``(2,)`` map position of lamp (0, 0) (m).
        lamp_spacing: grid pitch (m).
        lamp_height: lamp height above the floor (m).
        lamp_gain: lamp intensity (relative irradiance * m^2).
        zone_raster: ``(R, C)`` float32 lighting level, cell ``(i, j)`` centred at
            ``raster_origin + (j, i) * raster_res``.
        raster_origin: ``(2,)`` m. raster_res: m per cell.
    """

    ambient: float
    lamp_origin: np.ndarray
    lamp_spacing: float
    lamp_height: float
    lamp_gain: float
    zone_raster: np.ndarray
    raster_origin: np.ndarray
    raster_res: float

    @classmethod
    def from_map(cls, world_map, ambient: float = AMBIENT, spacing: float = LAMP_SPACING) -> "Illumination":
        from agvsim.world import geometry as geo

        xmin, ymin, xmax, ymax = world_map.bounds
        heights = [w.height for w in world_map.walls] or [3.0]
        lamp_h = min(max(heights), MAX_LAMP_HEIGHT)
        origin = np.array([xmin + spacing / 2, ymin + spacing / 2])
        # zone raster
        res = RASTER_RES
        xs = np.arange(xmin - 1.0, xmax + 1.0 + res, res)
        ys = np.arange(ymin - 1.0, ymax + 1.0 + res, res)
        raster = np.empty((len(ys), len(xs)), np.float32)
        for r0 in range(0, len(ys), RASTER_BLOCK_ROWS):  # in blocks of rows: the tests' temporaries stay small
            gx, gy = np.meshgrid(xs, ys[r0:r0 + RASTER_BLOCK_ROWS])
            pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
            level = np.full(len(pts), float(world_map.lighting_default))
            for zone in world_map.lighting_zones:  # the last zone wins, as Map.lighting_at
                level[geo.points_in_polygon(pts, zone.polygon)] = zone.level
            raster[r0:r0 + RASTER_BLOCK_ROWS] = level.reshape(gy.shape)
        tmp = cls(ambient, origin, spacing, lamp_h, 1.0, raster, np.array([xs[0], ys[0]]), res)
        # normalise: a vertical surface at 1.2 m gets at most 1.0 (ambient included), wherever
        # it stands in a lamp cell and whichever way it faces
        u = (np.arange(12) + 0.5) / 12 * spacing
        px, py = np.meshgrid(origin[0] + u, origin[1] + u)
        p = np.stack([px.ravel(), py.ravel(), np.full(px.size, 1.2)], axis=1)
        peak = 0.0
        for n in ((1, 0, 0), (0, 1, 0), (-1, 0, 0), (0, -1, 0)):
            peak = max(peak, float(tmp.lamp_irradiance(p, np.broadcast_to(np.array(n, float), p.shape)).max()))
        gain = (1.0 - ambient) / max(peak, 1e-12)
        return cls(ambient, origin, spacing, lamp_h, float(gain), raster, tmp.raster_origin, res)

    def lamp_irradiance(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Irradiance from the 3 x 3 nearest ceiling lamps (relative units).

        Args:
            points: ``(..., 3)`` map points (m). normals: ``(..., 3)`` unit normals.
        Returns:
            ``(...)`` float32.
        """
        p = np.asarray(points, dtype=np.float32)
        n = np.asarray(normals, dtype=np.float32)
        s = np.float32(self.lamp_spacing)
        i0 = np.rint((p[..., 0] - self.lamp_origin[0]) / s)
        j0 = np.rint((p[..., 1] - self.lamp_origin[1]) / s)
        dz = np.float32(self.lamp_height) - p[..., 2]
        total = np.zeros(p.shape[:-1], np.float32)
        for di in (-1.0, 0.0, 1.0):
            dx = (np.float32(self.lamp_origin[0]) + (i0 + di) * s) - p[..., 0]
            for dj in (-1.0, 0.0, 1.0):
                dy = (np.float32(self.lamp_origin[1]) + (j0 + dj) * s) - p[..., 1]
                r2 = dx * dx + dy * dy + dz * dz
                cos_r = dx * n[..., 0] + dy * n[..., 1] + dz * n[..., 2]
                # Lambertian downlight: intensity ~ cos(emission angle) = dz / r
                total += np.maximum(cos_r, 0.0) * np.maximum(dz, 0.0) / (r2 * r2)
        return total * np.float32(self.lamp_gain)

    def irradiance(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Ambient plus lamps at ``points`` with ``normals`` (``(..., 3)``), relative (1 = normal wall)."""
        return np.float32(self.ambient) + self.lamp_irradiance(points, normals)

    def zone_level(self, xy: np.ndarray) -> np.ndarray:
        """Lighting level (``Map.lighting_at``, bilinear between raster cells) at ``(..., 2)`` map points."""
        import cv2

        q = np.asarray(xy, dtype=np.float32)
        shape = q.shape[:-1]
        if q.ndim != 3:  # remap wants an image-shaped map: pad to rows of 256
            flat = q.reshape(-1, 2)
            cols = 256
            rows = -(-len(flat) // cols)
            q = np.zeros((rows * cols, 2), np.float32)
            q[:len(flat)] = flat
            q = q.reshape(rows, cols, 2)
        mx = (q[..., 0] - np.float32(self.raster_origin[0])) / np.float32(self.raster_res)
        my = (q[..., 1] - np.float32(self.raster_origin[1])) / np.float32(self.raster_res)
        out = cv2.remap(self.zone_raster, mx.astype(np.float32), my.astype(np.float32), cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE)
        return out.reshape(-1)[:int(np.prod(shape, dtype=int))].reshape(shape)
