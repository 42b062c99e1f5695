"""The 3-D scene of a map, as plain numpy geometry (built once per map, no OpenGL).

:func:`build_scene` turns a :class:`agvsim.world.map.Map` into textured
triangle meshes grouped by texture: the floor, every wall (a box per
polyline segment, 3 m+ high, its surface look), every obstacle (an extruded
polygon with a look per kind: racks with shelving uprights, machines and
pillars with hazard tape, pallets), every target (a quad with the exact
printed face of its :class:`~localizer.model.target.TargetSpec`, margin included) and
procedural distractors on free wall faces (striped signs, barcodes, hazard
signs, almost-targets). Door frames, shelving uprights and hazard tape are in
the wall and obstacle textures.

Distractors are placed deterministically from the map's name (CRC-32 seed),
at least :data:`DISTRACTOR_CLEARANCE` along the wall from every target.

Targets and distractors lie exactly on the wall surface (the map's geometry);
the rendered wall boxes are :data:`WALL_INSET` thinner on each side so the
quads never depth-fight with the wall behind them.

Coordinates: map frame (x east, y north, z up), metres. A quad's texture ``v``
runs bottom (0) to top (1) -- pyrender flips texture rows on upload, so row 0
of a texture array is the top of the surface.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np

from agvsim.sensors.render import textures as tx

WALL_INSET = 0.002  # m, rendered wall faces sit this far behind the map's wall surface
DISTRACTOR_CLEARANCE = 1.0  # m along the wall from any target's centre to a distractor's edge
DISTRACTOR_EVERY = 5.0  # m of free wall face per distractor, on average
FLOOR_MARGIN = 2.0  # m the floor extends beyond the map's bounds


@dataclass(frozen=True, eq=False)
class MeshPart:
    """Triangles sharing one texture.

    Attributes:
        texture: key into :attr:`SceneDescription.textures`.
        positions: ``(N, 3)`` float32 vertices (m, map frame).
        uvs: ``(N, 2)`` float32 texture coordinates (``v`` up).
        indices: ``(M, 3)`` int32 triangles, counter-clockwise seen from the front.
        tiled: whether the texture repeats (else clamped: targets, distractors).
    """

    texture: str
    positions: np.ndarray
    uvs: np.ndarray
    indices: np.ndarray
    tiled: bool = True


@dataclass(frozen=True)
class Distractor:
    """A procedural distractor quad on a wall face."""

    kind: str
    wall: str
    centre: tuple[float, float, float]  # m, map frame, on the wall surface
    normal: tuple[float, float]  # unit, the direction it faces
    size: tuple[float, float]  # m, width x height


@dataclass(frozen=True)
class FaceLook:
    """The texture of one vertical face of a :class:`Solid` (seen from outside).

    Attributes:
        texture: key into :attr:`SceneDescription.textures`.
        u: texture ``u`` at the face's left and right ends, seen from the front.
        v: texture ``v`` at the bottom (``z = 0``) and top (``z = height``) of the face.
        tiled: whether the texture repeats.
    """

    texture: str
    u: tuple[float, float]
    v: tuple[float, float]
    tiled: bool = True


@dataclass(frozen=True, eq=False)
class Solid:
    """A vertical prism standing on the floor: a wall piece or an obstacle, in the map's geometry.

    Attributes:
        polygon: ``(K, 2)`` float64 convex outline (m), counter-clockwise; edge ``k`` runs
            from vertex ``k`` to ``k + 1`` and, seen from outside, vertex ``k`` is on the left.
        height: m.
        faces: per edge, its :class:`FaceLook` (None for an edge inside a split polygon).
        top: ``(texture key, (u, v))``: the top is drawn in that one texel of the texture.
        mesh_inset: per edge, how far the OpenGL mesh's face sits inside this outline (m;
            :data:`WALL_INSET` on a wall's long sides, so decals never depth-fight with it).
    """

    polygon: np.ndarray
    height: float
    faces: tuple[FaceLook | None, ...]
    top: tuple[str, tuple[float, float]]
    mesh_inset: tuple[float, ...] = ()


@dataclass(frozen=True)
class Decal:
    """A printed quad on a wall face (a target or a distractor): texture ``u`` runs 0 -> 1 from
    ``left`` to ``right`` seen from the front, ``v`` 0 -> 1 from ``z[0]`` to ``z[1]``.

    Attributes:
        texture: key into :attr:`SceneDescription.textures`.
        left, right: ``(x, y)`` ends on the wall surface (m). z: ``(bottom, top)`` (m).
        normal: ``(2,)`` unit, the direction it faces.
    """

    texture: str
    left: tuple[float, float]
    right: tuple[float, float]
    z: tuple[float, float]
    normal: tuple[float, float]


@dataclass(frozen=True, eq=False)
class SceneDescription:
    """Everything a renderer needs once: meshes (for OpenGL), solids and decals (for the
    raycaster), textures (reflectance) and distractors; both describe the same scene."""

    name: str
    parts: tuple[MeshPart, ...]
    textures: Mapping[str, np.ndarray]
    distractors: tuple[Distractor, ...]
    bounds: tuple[float, float, float, float]
    background: float = 0.12  # reflectance-equivalent radiance of the unmodelled roof
    n_triangles: int = field(default=0)
    solids: tuple[Solid, ...] = ()
    decals: tuple[Decal, ...] = ()
    floor: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # m, (x0, y0, x1, y1) of the floor


class _Builder:
    """Accumulates quads per texture."""

    def __init__(self) -> None:
        self.geo: dict[str, list] = {}
        self.tiled: dict[str, bool] = {}

    def quad(self, key: str, corners: np.ndarray, uv: np.ndarray, tiled: bool = True) -> None:
        """``corners`` ``(4, 3)`` TL, TR, BR, BL seen from the front; ``uv`` ``(4, 2)``."""
        self.polygon(key, corners, uv, np.array([[0, 3, 2], [0, 2, 1]]), tiled)

    def polygon(self, key: str, pts: np.ndarray, uv: np.ndarray, tris: np.ndarray, tiled: bool = True) -> None:
        g = self.geo.setdefault(key, [[], [], [], 0])
        g[0].append(np.asarray(pts, np.float32))
        g[1].append(np.asarray(uv, np.float32))
        g[2].append(np.asarray(tris, np.int32) + g[3])
        g[3] += len(pts)
        self.tiled[key] = tiled

    def vertical_quad(self, key: str, p_left, p_right, z0: float, z1: float, u: tuple[float, float],
                      v: tuple[float, float], tiled: bool = True) -> None:
        """A vertical rectangle seen from the side where ``p_left`` is on the viewer's left."""
        pl, pr = np.asarray(p_left, float), np.asarray(p_right, float)
        corners = np.array([[*pl, z1], [*pr, z1], [*pr, z0], [*pl, z0]])
        uv = np.array([[u[0], v[1]], [u[1], v[1]], [u[1], v[0]], [u[0], v[0]]])
        self.quad(key, corners, uv, tiled)

    def parts(self) -> tuple[MeshPart, ...]:
        out = []
        for key, (pos, uv, idx, _) in self.geo.items():
            out.append(MeshPart(key, np.concatenate(pos), np.concatenate(uv), np.concatenate(idx), self.tiled[key]))
        return tuple(out)


def triangulate(poly: np.ndarray) -> np.ndarray:
    """Ear-clipping triangulation of a simple counter-clockwise polygon ``(K, 2)`` -> ``(K-2, 3)``."""
    idx = list(range(len(poly)))
    tris = []

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    guard = 0
    while len(idx) > 3 and guard < 10000:
        guard += 1
        for k in range(len(idx)):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            a, b, c = poly[i0], poly[i1], poly[i2]
            if cross(a, b, c) <= 1e-12:
                continue
            inside = False
            for j in idx:
                if j in (i0, i1, i2):
                    continue
                p = poly[j]
                if cross(a, b, p) >= 0 and cross(b, c, p) >= 0 and cross(c, a, p) >= 0:
                    inside = True
                    break
            if not inside:
                tris.append((i0, i1, i2))
                idx.pop(k)
                break
        else:  # degenerate: fan the rest
            break
    for k in range(1, len(idx) - 1):
        tris.append((idx[0], idx[k], idx[k + 1]))
    return np.array(tris, dtype=np.int32)


def _free_face(world_map, point2: np.ndarray, normal2: np.ndarray) -> bool:
    """Whether the wall face at ``point2`` facing ``normal2`` looks onto free floor."""
    probe = point2 + 0.6 * normal2
    xmin, ymin, xmax, ymax = world_map.bounds
    if not (xmin < probe[0] < xmax and ymin < probe[1] < ymax):
        return False
    return world_map.clearance(float(probe[0]), float(probe[1])) > 0.4


def _place_distractors(world_map, rng: np.random.Generator) -> list[Distractor]:
    kinds = tuple(tx.DISTRACTOR_SIZES)
    out: list[Distractor] = []
    for wall in world_map.walls:
        if wall.surface in ("door", "glass"):
            continue
        r = wall.thickness / 2
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(wall.points, axis=0), axis=1))])
        for k, (a, b) in enumerate(zip(wall.points[:-1], wall.points[1:])):
            seg_len = float(np.linalg.norm(b - a))
            e = (b - a) / seg_len
            for side, n in (("left", np.array([-e[1], e[0]])), ("right", np.array([e[1], -e[0]]))):
                n_want = int(rng.poisson(seg_len / DISTRACTOR_EVERY))
                for _ in range(n_want):
                    kind = kinds[int(rng.integers(len(kinds)))]
                    w, h = tx.DISTRACTOR_SIZES[kind]
                    s = float(rng.uniform(0.3 + w / 2, max(0.3 + w / 2, seg_len - 0.3 - w / 2)))
                    zc = float(rng.uniform(0.8, 1.8))
                    if seg_len < w + 0.6 or zc + h / 2 > wall.height:
                        continue
                    centre2 = a + e * s + n * r
                    if not _free_face(world_map, centre2, n):
                        continue
                    at = cum[k] + s
                    clash = False
                    for t in world_map.targets:
                        if t.wall == wall.id and float(np.dot(t.normal, n)) > 0.9 and \
                                abs(t.at - at) < DISTRACTOR_CLEARANCE + w / 2:
                            clash = True
                    for d in out:
                        if d.wall == wall.id and float(np.dot(d.normal, n)) > 0.9 and \
                                np.hypot(d.centre[0] - centre2[0], d.centre[1] - centre2[1]) < (w + d.size[0]) / 2 + 0.3:
                            clash = True
                    if not clash:
                        out.append(Distractor(kind, wall.id, (float(centre2[0]), float(centre2[1]), zc),
                                              (float(n[0]), float(n[1])), (w, h)))
    return out


def build_scene(world_map, seed: int | None = None) -> SceneDescription:
    """The scene of ``world_map`` (pure numpy; deterministic).

    Args:
        world_map: an :class:`agvsim.world.map.Map`.
        seed: texture and distractor seed; default the CRC-32 of the map's name.
    """
    if seed is None:
        seed = zlib.crc32(world_map.name.encode("utf-8"))
    rng = np.random.default_rng(seed)
    textures: dict[str, np.ndarray] = {}
    bld = _Builder()
    solids: list[Solid] = []
    decals: list[Decal] = []

    # floor
    xmin, ymin, xmax, ymax = world_map.bounds
    fx0, fy0, fx1, fy1 = xmin - FLOOR_MARGIN, ymin - FLOOR_MARGIN, xmax + FLOOR_MARGIN, ymax + FLOOR_MARGIN
    tw, th = tx.SURFACE_TILE["floor"]
    textures["surface:floor"] = tx.surface_texture("floor", rng)
    corners = np.array([[fx0, fy1, 0.0], [fx1, fy1, 0.0], [fx1, fy0, 0.0], [fx0, fy0, 0.0]])
    bld.quad("surface:floor", corners, corners[:, :2] / np.array([tw, th]))

    _add_walls(world_map, rng, textures, bld, solids)
    _add_obstacles(world_map, rng, textures, bld, solids)
    distractors = _add_decals(world_map, rng, textures, bld, decals)

    parts = bld.parts()
    return SceneDescription(
        name=world_map.name, parts=parts, textures=MappingProxyType(textures), distractors=tuple(distractors),
        bounds=(xmin, ymin, xmax, ymax), n_triangles=int(sum(len(p.indices) for p in parts)),
        solids=tuple(solids), decals=tuple(decals), floor=(fx0, fy0, fx1, fy1))


def _add_walls(world_map, rng: np.random.Generator, textures: dict, bld: _Builder, solids: list) -> None:
    """Each wall's pieces: its two faces, ends and top as meshes (2 mm inside the map's surface,
    ``WALL_INSET``), and the same box at full thickness as a raycaster :class:`Solid`; textures
    drawn from ``rng`` in wall order."""
    for wall in world_map.walls:
        surf = wall.surface
        key = f"surface:{surf}"
        stretched = surf in tx.STRETCHED_SURFACES
        if stretched:
            key = f"surface:{surf}:{wall.id}"
        if key not in textures:
            textures[key] = tx.surface_texture(surf, rng)
        tile_w, tile_h = tx.SURFACE_TILE.get(surf, tx.SURFACE_TILE["default"])
        r = max(wall.thickness / 2 - WALL_INSET, wall.thickness / 4)
        total = wall.length
        s0 = 0.0
        for a, b in zip(wall.points[:-1], wall.points[1:]):
            L = float(np.linalg.norm(b - a))
            e = (b - a) / L
            nl = np.array([-e[1], e[0]])
            h = wall.height

            def u_of(s):
                return (s / total) if stretched else s / tile_w

            v = (0.0, 1.0) if stretched else (0.0, h / tile_h)
            # left face (viewer's right is -e), right face (viewer's right is +e)
            bld.vertical_quad(key, b + nl * r, a + nl * r, 0.0, h, (u_of(s0 + L), u_of(s0)), v, not stretched)
            bld.vertical_quad(key, a - nl * r, b - nl * r, 0.0, h, (u_of(s0), u_of(s0 + L)), v, not stretched)
            # ends and top in the wall's plain look
            plain = "surface:painted" if stretched else key
            textures.setdefault("surface:painted", tx.surface_texture("painted", rng))
            tw_, th_ = tx.SURFACE_TILE["painted"]
            bld.vertical_quad(plain, a + nl * r, a - nl * r, 0.0, h, (0, 2 * r / tw_), (0, h / th_))
            bld.vertical_quad(plain, b - nl * r, b + nl * r, 0.0, h, (0, 2 * r / tw_), (0, h / th_))
            top = np.array([[*(a + nl * r), h], [*(b + nl * r), h], [*(b - nl * r), h], [*(a - nl * r), h]])
            bld.quad(plain, top, np.zeros((4, 2)))
            # the same box in the map's geometry (full thickness) for the raycaster: edges
            # right face, end b, left face, end a (counter-clockwise)
            rm = wall.thickness / 2
            side = FaceLook(key, (u_of(s0), u_of(s0 + L)), v, not stretched)
            end = FaceLook(plain, (0.0, 2 * rm / tw_), (0.0, h / th_), True)
            solids.append(Solid(np.array([a - nl * rm, b - nl * rm, b + nl * rm, a + nl * rm], float), h,
                                (side, end, FaceLook(key, (u_of(s0 + L), u_of(s0)), v, not stretched), end),
                                (plain, (0.0, 0.0)), (rm - r, 0.0, rm - r, 0.0)))
            s0 += L



def _add_obstacles(world_map, rng: np.random.Generator, textures: dict, bld: _Builder, solids: list) -> None:
    """Each obstacle's sides and top as meshes and as convex :class:`Solid` s (textures from ``rng``)."""
    for ob in world_map.obstacles:
        kind = ob.kind if ob.kind in tx.OBSTACLE_TILE else "other"
        key = f"obstacle:{kind}"
        if key not in textures:
            textures[key] = tx.obstacle_texture(kind, rng)
        tile = tx.OBSTACLE_TILE.get(kind, 2.0)
        poly = np.asarray(ob.polygon, float)
        s = 0.0
        looks = []
        for i in range(len(poly)):
            p, q = poly[i], poly[(i + 1) % len(poly)]
            L = float(np.linalg.norm(q - p))
            # CCW polygon: outside is on the right of p->q, so p is on the outside viewer's left
            bld.vertical_quad(key, p, q, 0.0, ob.height, (s / tile, (s + L) / tile), (0.0, 1.0))
            looks.append(FaceLook(key, (s / tile, (s + L) / tile), (0.0, 1.0)))
            s += L
        tris = triangulate(poly)
        top = np.column_stack([poly, np.full(len(poly), ob.height)])
        bld.polygon(key, top, np.full((len(poly), 2), 0.02), tris)
        solids.extend(_convex_solids(poly, looks, float(ob.height), (key, (0.02, 0.02)), tris))



def _add_decals(world_map, rng: np.random.Generator, textures: dict, bld: _Builder, decals: list) -> list[Distractor]:
    """The targets (one texture per spec and polarity) and the distractors placed from ``rng``, as
    meshes and :class:`Decal` s; returns the distractors."""
    # targets: one texture per (spec, polarity)
    for t in world_map.targets:
        spec = t.spec
        key = f"target:{t.polarity}:{spec.bar_width:.6f}:{spec.bar_height:.6f}:{spec.margin:.6f}"
        if key not in textures:
            textures[key] = tx.target_texture(spec, t.polarity)
        u_dir = np.array([-t.normal[1], t.normal[0]])  # the target's right, seen from the front
        half = spec.outer_width / 2
        left, right = t.position - u_dir * half, t.position + u_dir * half
        z = (t.height - spec.outer_height / 2, t.height + spec.outer_height / 2)
        bld.vertical_quad(key, left, right, z[0], z[1], (0.0, 1.0), (0.0, 1.0), tiled=False)
        decals.append(Decal(key, tuple(map(float, left)), tuple(map(float, right)), z,
                            (float(t.normal[0]), float(t.normal[1]))))

    # distractors
    distractors = _place_distractors(world_map, rng)
    for i, d in enumerate(distractors):
        key = f"distractor:{i}:{d.kind}"
        textures[key] = tx.distractor_texture(d.kind, rng)
        n = np.array(d.normal)
        u_dir = np.array([-n[1], n[0]])
        c = np.array(d.centre[:2])
        w, h = d.size
        bld.vertical_quad(key, c - u_dir * w / 2, c + u_dir * w / 2, d.centre[2] - h / 2, d.centre[2] + h / 2,
                          (0.0, 1.0), (0.0, 1.0), tiled=False)
        decals.append(Decal(key, tuple(map(float, c - u_dir * w / 2)), tuple(map(float, c + u_dir * w / 2)),
                            (d.centre[2] - h / 2, d.centre[2] + h / 2), d.normal))

    return distractors


def _is_convex(poly: np.ndarray) -> bool:
    d = np.roll(poly, -1, axis=0) - poly
    cross = d[:, 0] * np.roll(d[:, 1], -1) - d[:, 1] * np.roll(d[:, 0], -1)
    return bool(np.all(cross >= -1e-12))


def _convex_solids(poly: np.ndarray, looks: list, height: float, top, tris: np.ndarray) -> list[Solid]:
    """One :class:`Solid` for a convex outline; a non-convex one is split into its triangles
    (their inner edges have no face: a ray inside the outline sees no new surface there)."""
    if _is_convex(poly):
        return [Solid(poly.copy(), height, tuple(looks), top)]
    k = len(poly)
    out = []
    for tri in tris:
        faces = []
        for a, b in zip(tri, np.roll(tri, -1)):
            faces.append(looks[a] if (b - a) % k == 1 else None)
        out.append(Solid(poly[tri].copy(), height, tuple(faces), top))
    return out


def target_u_direction(normal2) -> np.ndarray:
    """``(2,)`` the target's right (its ``u`` axis) seen from the front, for a face normal ``normal2``."""
    n = np.asarray(normal2, float)
    return np.array([-n[1], n[0]])


__all__ = ["DISTRACTOR_CLEARANCE", "Decal", "Distractor", "FaceLook", "MeshPart", "SceneDescription", "Solid",
           "WALL_INSET", "build_scene", "target_u_direction", "triangulate"]
