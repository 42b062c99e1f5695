"""Frames for the envelope benchmark, from a pipeline independent of the localizer's own.

A printed two-bar target (:class:`localizer.TargetSpec` geometry, ink reflectance
``BLACK``, paper ``WHITE``; positive or negative) hangs on a wall with clutter (panels,
posters, strips, labels, lettering, shelf edges: nothing that is a target); where the wall
ends the far room shows (a smooth field). A level pinhole camera sees it supersampled: the
wall and the print are textures on the one wall plane, mapped into a fine frame by their
homographies (``cv2.warpPerspective``, bilinear, premultiplied by a coverage channel so
their borders are antialiased) and area-averaged (``cv2.INTER_AREA``, an exact box of fine
pixels) to the output pixels. The print is rendered at ``SUPERSAMPLE`` (4) times the output
resolution from a texture whose texels (one fine pixel at the print's farthest point: the
texture is magnified everywhere) hold the exact area share of the bars; the wall (``WALL_TEXELS_PER_PX`` texels per output pixel) at
``WALL_SUPERSAMPLE`` times, in bands of rows to bound the memory. The radiance is lit by a
smooth illumination field and handed to the camera
(:func:`agvsim.bench.envelope_sensor.expose`: PSF, vignetting, exposure, noise, Bayer, sRGB, JPEG).

Randomness: the scene of frame ``index`` comes from ``default_rng([seed, index, with_target])``
(the same wall, clutter and target pose under every condition of one resolution), the
sensor's draws from a generator that adds the settings to that key: one seed gives the same
frames, bit for bit, whichever conditions are run.
"""
from __future__ import annotations

import math
import string
import zlib
from dataclasses import dataclass

import numpy as np

from agvsim.bench.envelope_sensor import REFERENCE_WIDTH, FrameSettings, expose
from localizer.model.camera import Camera
from localizer.model.geometry import TargetPose
from localizer.model.target import TargetSpec

#: reflectances of the printed target: ink and paper
BLACK, WHITE = 0.05, 0.85
#: fine pixels per output pixel along each axis: the target's print, the wall
SUPERSAMPLE, WALL_SUPERSAMPLE = 4, 2
#: pose envelope: distance (m) and orientation alpha (rad)
DISTANCE_RANGE = (1.5, 5.0)
ALPHA_MAX = math.radians(60.0)
#: the whole printed target stays this many px (at 512 px width, scaled) inside the frame
FRAME_MARGIN_PX = 4.0
#: the wall texture's larger side (texels) per output pixel of width, and its cap
WALL_TEXELS_PER_PX, WALL_TEXELS_MAX = 2, 4096
#: output rows per band of the wall's fine render (bounds its memory)
BAND_ROWS = 128
#: the peers' printed markers (``--peers``): black square side (m), white quiet zone (share of
#: the side), gap from the target's print (m)
MARKER_SIDE, MARKER_QUIET, MARKER_GAP = 0.12, 0.2, 0.06


@dataclass(frozen=True)
class Scene:
    """One frame's world: the target (absent when ``has_target`` is False), the wall and the light.

    Wall coordinates ``(u, v)`` (m) are the target plane's (u right, v down, origin at the
    target centre, :class:`localizer.TargetPose`); without a target the plane is posed the same way."""

    pose: TargetPose  # the target centre in the camera frame (m, rad); the wall plane's pose
    has_target: bool
    polarity: str  # "positive" (black bars on white) or "negative"
    wall: tuple[float, float, float, float]  # m, u_left, u_right, v_top, v_bottom of the wall
    paint: float  # reflectance of the wall paint
    clutter: tuple  # (kind, u0, v0, u1, v1, reflectance, text) items on the wall, m
    light: tuple[float, float, float]  # illumination: slopes across the frame in x and y (share per frame
    # width / height) and the sd of its smooth unevenness (share)
    far: tuple[float, float]  # reflectance of the far room at the top and the bottom of the frame
    markers: tuple = ()  # (name, u0, v0, side) printed peer markers (:func:`marker_layout`), m; drawn over the clutter


def camera_for(width: int, height: int) -> Camera:
    """The thesis camera (16 mm lens) at 512 x 480, else square pixels with its horizontal
    field of view (``fx = fy = fx_thesis * width / 512``), principal point at the centre."""
    thesis = Camera.thesis(16.0)
    if (width, height) == (thesis.width, thesis.height):
        return thesis
    f = thesis.fx * width / REFERENCE_WIDTH
    return Camera.from_intrinsics(f, f, width / 2.0, height / 2.0, width, height)


def _corners(pose: TargetPose, target: TargetSpec) -> np.ndarray:
    u, v = 0.5 * target.outer_width, 0.5 * target.outer_height
    return pose.points(np.array([-u, u, u, -u]), np.array([-v, -v, v, v]))


def _fits(d: float, beta, alpha: float, height, camera: Camera, target: TargetSpec, margin: float) -> np.ndarray:
    """Whether the whole print of a target at (d, beta, alpha, height) (m, rad; arrays of beta
    and height broadcast) lies ``margin`` px inside the frame, in front of the camera."""
    u = 0.5 * target.outer_width * np.array([-1.0, 1.0, 1.0, -1.0])
    v = 0.5 * target.outer_height * np.array([-1.0, -1.0, 1.0, 1.0])
    beta, height = np.asarray(beta, float)[..., None], np.asarray(height, float)[..., None]
    ca, sa = math.cos(alpha), math.sin(alpha)
    z = d * np.cos(beta) - u * sa
    zs = np.where(z > 0.1, z, np.inf)
    x = camera.cx + camera.fx * (d * np.sin(beta) + u * ca) / zs
    y = camera.cy + camera.fy * (height + v) / zs
    inside = ((z > 0.1) & (x >= margin - 0.5) & (x <= camera.width - 0.5 - margin)
              & (y >= margin - 0.5) & (y <= camera.height - 0.5 - margin))
    return inside.all(axis=-1)


def sample_pose(rng: np.random.Generator, camera: Camera, target: TargetSpec = TargetSpec()) -> TargetPose:
    """A target pose in the envelope that shows the whole printed target: distance uniform
    in ``DISTANCE_RANGE`` (m), alpha uniform within +-``ALPHA_MAX`` (rad), then bearing and
    height uniform over the range that keeps the target inside the frame. Four uniform draws
    are mapped onto the camera's feasible ranges, so cameras with the same field of view get
    the same poses from the same generator."""
    d, a, ub, uh = rng.uniform(*DISTANCE_RANGE), rng.uniform(-ALPHA_MAX, ALPHA_MAX), rng.random(), rng.random()
    margin = FRAME_MARGIN_PX * camera.width / REFERENCE_WIDTH
    half = math.atan(0.5 * camera.width / camera.fx)
    betas = np.linspace(-half, half, 481)
    for _ in range(60):
        ok = betas[_fits(d, betas, a, 0.0, camera, target, margin)]
        if ok.size:
            beta = float(ok[0] + ub * (ok[-1] - ok[0]))
            hmax = d * math.cos(beta) * (0.5 * camera.height) / camera.fy  # generous bound (m)
            hs = np.linspace(-hmax, hmax, 481)
            okh = hs[_fits(d, beta, a, hs, camera, target, margin)]
            if okh.size:
                return TargetPose(d, beta, a, float(okh[0] + uh * (okh[-1] - okh[0])))
        d *= 1.05  # too near to fit (or too slanted): step back
    raise ValueError(f"no pose shows the target whole in a {camera.width}x{camera.height} frame")


def _text(rng, n) -> str:
    return "".join(rng.choice(list(string.ascii_uppercase + string.digits + "  -")) for _ in range(n))


def sample_scene(rng: np.random.Generator, camera: Camera, target: TargetSpec = TargetSpec(),
                 with_target: bool = True) -> Scene:
    """A random :class:`Scene`: pose (:func:`sample_pose`), polarity, the wall's extent and
    paint, 8-25 clutter items where the frame shows the wall, kept 0.08 m clear of the target's print (when there is one),
    illumination slopes and the far room."""
    pose = sample_pose(rng, camera, target)
    polarity = "positive" if rng.random() < 0.5 else "negative"
    wall = (-rng.uniform(0.6, 4.0), rng.uniform(0.6, 4.0), -rng.uniform(0.5, 1.5), rng.uniform(0.5, 1.5))
    paint = rng.uniform(0.35, 0.8)
    keep_u, keep_v = 0.5 * target.outer_width + 0.08, 0.5 * target.outer_height + 0.08
    vu0, vu1, vv0, vv1 = _visible_wall(pose, wall, camera)
    vu0, vu1 = max(vu0, -3.0 * pose.distance), min(vu1, 3.0 * pose.distance)  # where clutter can be seen
    items = []
    for _ in range(int(rng.integers(8, 26))):
        kind = rng.choice(["panel", "panel", "strip", "label", "text", "shelf", "frame"])
        u0, v0 = rng.uniform(vu0 - 0.3, vu1), rng.uniform(vv0 - 0.3, vv1)
        refl, text = float(rng.uniform(0.04, 0.9)), ""
        if kind == "panel" or kind == "frame":
            w, h = rng.uniform(0.05, 1.2), rng.uniform(0.05, 1.0)
        elif kind == "strip":  # a pipe, a cable duct, a door frame
            w, h = rng.uniform(0.01, 0.15), rng.uniform(0.3, 2.5)
            refl = float(rng.choice([rng.uniform(0.04, 0.3), rng.uniform(0.7, 0.9)]))
        elif kind == "shelf":
            w, h = rng.uniform(0.3, 3.0), rng.uniform(0.005, 0.04)
        else:  # lettering, alone or on a white label
            n = int(rng.integers(3, 14))
            h = rng.uniform(0.015, 0.08)
            w = 0.6 * h * n
            text = _text(rng, n)
            refl = float(rng.uniform(0.04, 0.25)) if kind == "text" or rng.random() < 0.7 else 0.9
        item = (str(kind), u0, v0, u0 + w, v0 + h, refl, text)
        if with_target and u0 < keep_u and u0 + w > -keep_u and v0 < keep_v and v0 + h > -keep_v:
            continue
        items.append(item)
    light = (float(rng.uniform(-0.15, 0.15)), float(rng.uniform(-0.15, 0.15)), 0.03)
    far = (float(rng.uniform(0.05, 0.6)), float(rng.uniform(0.05, 0.6)))
    return Scene(pose, with_target, polarity, wall, float(paint), tuple(items), light, far)


def marker_layout(pose: TargetPose, camera: Camera, target: TargetSpec = TargetSpec()) -> tuple:
    """Where a wall beside the target holds the peers' markers (:mod:`agvsim.bench.peers`):
    one above the other, ``MARKER_GAP`` beside the print on the side of the frame's centre (no
    random draw: the rest of the scene is unchanged). Returns ``((name, u0, v0, side), ...)``,
    each marker's black square from ``(u0, v0)`` (m, wall coordinates), ``side`` m across."""
    from agvsim.bench.peers import MARKER_NAMES

    x = camera.project(pose.points(np.zeros(1), np.zeros(1)))[0, 0]
    q = MARKER_QUIET * MARKER_SIDE
    u = 0.5 * target.outer_width + MARKER_GAP + q
    u0 = u if x < camera.cx else -u - MARKER_SIDE
    v0s = (-MARKER_SIDE - q, q)  # above and below the centre row
    return tuple((name, u0, v0, MARKER_SIDE) for name, v0 in zip(MARKER_NAMES, v0s))


# ------------------------------------------------------------------ textures and homographies
def _plane_to_fine(pose: TargetPose, camera: Camera, s: int) -> np.ndarray:
    """3 x 3 homography from wall coordinates (u, v, 1) (m) to the pixels of the frame
    supersampled ``s`` times (fine pixel ``J`` covers ``[J / s - 0.5, (J + 1) / s - 0.5]``)."""
    k = np.array([[camera.fx * s, 0, (camera.cx + 0.5) * s - 0.5], [0, camera.fy * s, (camera.cy + 0.5) * s - 0.5],
                  [0, 0, 1.0]])
    ca, sa = math.cos(pose.alpha), math.sin(pose.alpha)
    return k @ np.column_stack([[ca, 0.0, -sa], [0.0, 1.0, 0.0], pose.centre])


def _texel_map(u0: float, v0: float, tu: float, tv: float) -> np.ndarray:
    """Texel (column, row) centres -> wall coordinates (m) for a texture from (u0, v0), texels tu x tv m."""
    return np.array([[tu, 0, u0 + 0.5 * tu], [0, tv, v0 + 0.5 * tv], [0, 0, 1.0]])


def _coverage(n: int, t: float, u0: float, a: float, b: float) -> np.ndarray:
    """(n,) share of each texel [u0 + i t, u0 + (i+1) t] inside [a, b]."""
    lo = u0 + t * np.arange(n)
    return np.clip(np.minimum(lo + t, b) - np.maximum(lo, a), 0.0, t) / t


def target_texture(pose: TargetPose, camera: Camera, target: TargetSpec, polarity: str):
    """The printed target as a ``(rows, cols, 2)`` float32 texture (reflectance x coverage,
    coverage) and its texel map: texels one fine pixel at the target's farthest point,
    each holding the exact area share of the bars in it."""
    ow, oh = target.outer_width, target.outer_height
    zfar = pose.z + 0.5 * ow * abs(math.sin(pose.alpha))
    t = zfar / (max(camera.fx, camera.fy) * SUPERSAMPLE)
    nu, nv = min(4096, int(math.ceil(ow / t))), min(4096, int(math.ceil(oh / t)))
    tu, tv = ow / nu, oh / nv
    b, hh = target.bar_width, 0.5 * target.bar_height
    cu = _coverage(nu, tu, -0.5 * ow, -1.5 * b, -0.5 * b) + _coverage(nu, tu, -0.5 * ow, 0.5 * b, 1.5 * b)
    cv = _coverage(nv, tv, -0.5 * oh, -hh, hh)
    lo, hi = (BLACK, WHITE) if polarity == "positive" else (WHITE, BLACK)
    tex = np.empty((nv, nu, 2), np.float32)
    np.multiply.outer(cv.astype(np.float32) * np.float32(lo - hi), cu.astype(np.float32), out=tex[..., 0])
    tex[..., 0] += np.float32(hi)
    tex[..., 1] = 1.0
    return tex, _texel_map(-0.5 * ow, -0.5 * oh, tu, tv)


def _visible_wall(p: TargetPose, wall: tuple, camera: Camera) -> tuple[float, float, float, float]:
    """The part of the wall rectangle ``wall`` (m, u_left, u_right, v_top, v_bottom) on the plane
    of ``p`` that can show in the frame (and lies in front of the camera)."""
    ul, ur, vt, vb = wall
    ca, sa = math.cos(p.alpha), math.sin(p.alpha)
    tx, _, tz = p.centre
    us = []
    for x in (-0.5, camera.width - 0.5):  # the border columns' rays in the top view
        rx = (x - camera.cx) / camera.fx
        # the ray s (rx, 1) meets T + u (ca, -sa): s rx = tx + u ca, s = tz - u sa
        den = ca + rx * sa
        u = (rx * tz - tx) / den if abs(den) > 1e-9 else math.inf
        us.append(u if tz - u * sa > 1e-3 else None)
    u0 = us[0] if us[0] is not None else ul
    u1 = us[1] if us[1] is not None else ur
    u0, u1 = max(ul, min(u0, u1)), min(ur, max(u0, u1))
    if sa != 0.0:  # keep in front of the camera
        ucut = (tz - 0.05) / sa
        u0, u1 = (u0, min(u1, ucut)) if sa > 0 else (max(u0, ucut), u1)
    zmax = max(tz - u0 * sa, tz - u1 * sa)
    ty = p.height
    v0 = max(vt, zmax * (-0.5 - camera.cy) / camera.fy - ty)
    v1 = min(vb, zmax * (camera.height - 0.5 - camera.cy) / camera.fy - ty)
    return u0, u1, v0, v1


def wall_texture(scene: Scene, camera: Camera, rng: np.random.Generator):
    """The visible wall (paint, the clutter drawn in) as a ``(rows, cols, 2)`` uint16 texture
    (reflectance x 65535, coverage 65535) and its texel map."""
    import cv2

    u0, u1, v0, v1 = _visible_wall(scene.pose, scene.wall, camera)
    if not (u1 > u0 and v1 > v0):
        return None, None
    n = min(WALL_TEXELS_MAX, WALL_TEXELS_PER_PX * camera.width)
    t = max((u1 - u0) / n, (v1 - v0) / n, 1e-5)
    nu, nv = max(2, int(math.ceil((u1 - u0) / t))), max(2, int(math.ceil((v1 - v0) / t)))
    img = np.full((nv, nu), int(round(255 * scene.paint)), np.uint8)  # reflectance x 255 (OpenCV draws text on 8 bits)
    sh = 4  # cv2 fixed-point fraction bits for subtexel corners

    def px(u, v):
        return [int(round(((u - u0) / t - 0.5) * 16)), int(round(((v - v0) / t - 0.5) * 16))]

    for kind, a0, b0, a1, b1, refl, text in scene.clutter:
        grey = int(round(255 * refl))
        if a1 < u0 or a0 > u1 or b1 < v0 or b0 > v1:
            continue
        if kind in ("text", "label"):
            if kind == "label":
                pad = 0.2 * (b1 - b0)
                poly = np.array([px(a0 - pad, b0 - pad), px(a1 + pad, b0 - pad), px(a1 + pad, b1 + pad),
                                 px(a0 - pad, b1 + pad)], np.int32)
                cv2.fillConvexPoly(img, poly, 224, cv2.LINE_AA, sh)
            scale = (b1 - b0) / t / 22.0
            org = (int(round((a0 - u0) / t)), int(round((b1 - v0) / t)))
            if scale * 22.0 >= 2.0 and max(abs(org[0]), abs(org[1])) < 1 << 20:
                cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, grey, max(1, int(round(2 * scale))),
                            cv2.LINE_AA)
            continue
        poly = np.array([px(a0, b0), px(a1, b0), px(a1, b1), px(a0, b1)], np.int32)
        if kind == "frame":
            cv2.polylines(img, [poly], True, grey, max(1, int(round(0.02 / t))), cv2.LINE_AA, sh)
        else:
            cv2.fillConvexPoly(img, poly, grey, cv2.LINE_AA, sh)
    if scene.markers:
        _draw_markers(img, scene.markers, u0, v0, t)
    tex = np.empty((nv, nu, 2), np.uint16)  # reflectance x 65535, coverage x 65535
    np.multiply(img, np.uint16(257), out=tex[..., 0], dtype=np.uint16)
    tex[..., 1] = 65535
    return tex, _texel_map(u0, v0, t, t)


def _draw_markers(img: np.ndarray, markers: tuple, u0: float, v0: float, t: float) -> None:
    """Print ``markers`` (:func:`marker_layout`) with their white quiet zones into the wall
    texture ``img`` (uint8 reflectance x 255, texels ``t`` m from ``(u0, v0)``), area-resampled."""
    import cv2

    from agvsim.bench.peers import marker_images

    images = marker_images()
    lo, hi = int(round(255 * BLACK)), int(round(255 * WHITE))
    for name, a0, b0, side in markers:
        m = np.where(images[name] > 127, hi, lo).astype(np.uint8)
        pad = int(round(MARKER_QUIET * m.shape[0]))
        m = cv2.copyMakeBorder(m, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=hi)
        q = MARKER_QUIET * side
        c0, r0 = int(round((a0 - q - u0) / t)), int(round((b0 - q - v0) / t))
        n = int(round((side + 2 * q) / t))
        if n < 4:
            continue
        tile = cv2.resize(m, (n, n), interpolation=cv2.INTER_AREA)
        ra, rb, ca, cb = max(r0, 0), min(r0 + n, img.shape[0]), max(c0, 0), min(c0 + n, img.shape[1])
        if ra < rb and ca < cb:
            img[ra:rb, ca:cb] = tile[ra - r0:rb - r0, ca - c0:cb - c0]


def _warp(tex: np.ndarray, h: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    import cv2

    return cv2.warpPerspective(tex, h, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                               borderValue=(0.0, 0.0, 0.0, 0.0))


def render_radiance(scene: Scene, camera: Camera, target: TargetSpec, rng: np.random.Generator) -> np.ndarray:
    """The scene's radiance ``(H, W)`` float32 (reflectance x illumination): each pixel the
    mean of its ``SUPERSAMPLE x SUPERSAMPLE`` fine pixels of the target's print and of its
    ``WALL_SUPERSAMPLE x WALL_SUPERSAMPLE`` ones of the wall (whose texture holds
    ``WALL_TEXELS_PER_PX`` texels per pixel: finer samples would add nothing); the print is
    laid over the wall with its area-averaged coverage (the wall is plain around it)."""
    import cv2

    h, w = camera.shape
    value = np.zeros((h, w), np.float32)
    cover = np.zeros((h, w), np.float32)
    wall, wall_map = wall_texture(scene, camera, rng)
    if wall is not None:
        s = WALL_SUPERSAMPLE
        hw = _plane_to_fine(scene.pose, camera, s) @ wall_map
        for r0 in range(0, h, BAND_ROWS):
            r1 = min(h, r0 + BAND_ROWS)
            band = _warp(wall, np.array([[1.0, 0, 0], [0, 1.0, -r0 * s], [0, 0, 1.0]]) @ hw, (w * s, (r1 - r0) * s))
            small = cv2.resize(band, (w, r1 - r0), interpolation=cv2.INTER_AREA).astype(np.float32) / 65535.0
            value[r0:r1], cover[r0:r1] = small[..., 0], small[..., 1]
    if scene.has_target:
        s = SUPERSAMPLE
        ttex, tmap = target_texture(scene.pose, camera, target, scene.polarity)
        xy = camera.project(_corners(scene.pose, target))
        x0, y0 = (max(0, int(math.floor(c.min() + 0.5)) - 1) for c in (xy[:, 0], xy[:, 1]))
        x1, y1 = (min(n, int(math.ceil(c.max() + 0.5)) + 1) for c, n in ((xy[:, 0], w), (xy[:, 1], h)))
        ht = np.array([[1.0, 0, -x0 * s], [0, 1.0, -y0 * s], [0, 0, 1.0]]) @ _plane_to_fine(scene.pose, camera, s) @ tmap
        small = cv2.resize(_warp(ttex, ht, ((x1 - x0) * s, (y1 - y0) * s)), (x1 - x0, y1 - y0),
                           interpolation=cv2.INTER_AREA)
        keep = 1.0 - small[..., 1]
        value[y0:y1, x0:x1] = value[y0:y1, x0:x1] * keep + small[..., 0]
        cover[y0:y1, x0:x1] = cover[y0:y1, x0:x1] * keep + small[..., 1]
    yy = (np.arange(h, dtype=np.float32) / max(h - 1, 1))[:, None]
    xx = (np.arange(w, dtype=np.float32) / max(w - 1, 1))[None, :]
    far = scene.far[0] + (scene.far[1] - scene.far[0]) * yy
    mottle = cv2.resize(rng.normal(0.0, scene.light[2], (6, 8)).astype(np.float32), (w, h),
                        interpolation=cv2.INTER_CUBIC)
    light = 1.0 + scene.light[0] * (xx - 0.5) + scene.light[1] * (yy - 0.5) + mottle
    return ((value + far * (1.0 - cover)) * light).astype(np.float32)


@dataclass(frozen=True)
class Frame:
    """One rendered frame and its truth."""

    image: np.ndarray  # (H, W) uint8 grey frame
    camera: Camera  # its intrinsics
    scene: Scene  # the world it shows (``scene.pose``: the truth; ``scene.has_target``)
    settings: FrameSettings  # the camera settings it went through


def scene_rng(seed: int, index: int, with_target: bool) -> np.random.Generator:
    """The generator of frame ``index``'s scene."""
    return np.random.default_rng([int(seed), int(index), int(with_target)])


@dataclass(frozen=True)
class Radiance:
    """A scene rendered to linear radiance, before the camera's optics and sensor."""

    camera: Camera  # the intrinsics it was rendered with
    scene: Scene  # the world
    radiance: np.ndarray  # (H, W) float32, reflectance x illumination, area-averaged per pixel
    key: tuple  # (seed, index, with_target): the frame's place in the run


def render_scene(width: int, height: int, seed: int, index: int, target: TargetSpec = TargetSpec(),
                 with_target: bool = True, markers: bool = False) -> Radiance:
    """Scene ``index`` of run ``seed`` rendered for a ``width x height`` camera (:func:`camera_for`):
    every condition of that resolution shares it. ``markers``: the peers' markers hang beside the
    target (:func:`marker_layout`; the same scene otherwise)."""
    import dataclasses

    camera = camera_for(width, height)
    rng = scene_rng(seed, index, with_target)
    scene = sample_scene(rng, camera, target, with_target)
    if markers and with_target:
        scene = dataclasses.replace(scene, markers=marker_layout(scene.pose, camera, target))
    return Radiance(camera, scene, render_radiance(scene, camera, target, rng), (int(seed), int(index),
                                                                                 int(with_target)))


def expose_frame(settings: FrameSettings, rendered: Radiance) -> Frame:
    """``rendered`` through the camera ``settings`` (the sensor's draws keyed on the frame and the settings)."""
    if (settings.width, settings.height) != (rendered.camera.width, rendered.camera.height):
        raise ValueError(f"settings are for {settings.width}x{settings.height}, the scene was rendered for "
                         f"{rendered.camera.width}x{rendered.camera.height}")
    sensor = np.random.default_rng([*rendered.key, zlib.crc32(repr(settings).encode())])
    return Frame(expose(rendered.radiance, settings, rendered.camera, sensor), rendered.camera, rendered.scene,
                 settings)


def make_frame(settings: FrameSettings, seed: int, index: int, target: TargetSpec = TargetSpec(),
               with_target: bool = True) -> Frame:
    """Frame ``index`` of run ``seed`` under ``settings`` (reproducible bit for bit)."""
    return expose_frame(settings, render_scene(settings.width, settings.height, seed, index, target, with_target))


def bar_rows(pose: TargetPose, camera: Camera, target: TargetSpec = TargetSpec()) -> float:
    """Image height (rows) of the shorter bar of a target at ``pose``."""
    z = [pose.z - u * math.sin(pose.alpha) for u in (-target.bar_width, target.bar_width)]
    return camera.fy * target.bar_height / max(z)


def truth_dict(frame: Frame, target: TargetSpec = TargetSpec()) -> dict:
    """The frame's truth as JSON-ready fields (SI units, degrees for display)."""
    c, p, sc = frame.camera, frame.scene.pose, frame.scene
    out = {"camera": {"fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy, "width": c.width, "height": c.height},
           "has_target": sc.has_target, "settings": {k: getattr(frame.settings, k) for k in
                                                     frame.settings.__dataclass_fields__}}
    if sc.has_target:
        edges = c.project(p.points(np.array([-1.5, -0.5, 0.5, 1.5]) * target.bar_width, np.zeros(4)))[:, 0]
        out["target"] = {"distance_m": p.distance, "beta_rad": p.beta, "alpha_rad": p.alpha, "height_m": p.height,
                         "beta_deg": math.degrees(p.beta), "alpha_deg": math.degrees(p.alpha),
                         "polarity": sc.polarity, "bar_rows": bar_rows(p, c, target),
                         "edges_x_at_centre_row": edges.tolist()}
    return out
