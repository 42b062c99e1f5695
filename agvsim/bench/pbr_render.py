"""Render a :class:`~agvsim.bench.pbr_scene.PbrScene` with Mitsuba 3 (``scalar_rgb``): light
pass by light: the linear RGB radiance a camera's sensor would integrate, before any sensor effect.

A pixel integrates the light over its area: the scene is rendered ``k x k`` times finer (box
filter, ``spp / k^2`` samples per fine pixel, so ``spp`` per pixel) and area-averaged. Mitsuba's
cameras have square pixels and their principal point at the film's centre: the fine film has
square pixels of focal length ``k fy``, a width of ``W k fy / fx`` columns (the thesis camera's
``fx != fy`` comes out of the averaging), and is made ``2 (c + 1/2)`` fine pixels wide and
tall around the principal point ``c`` and cropped to the frame (OpenCV's convention: pixel
centres at integers), for the smallest ``k`` of :data:`SUPERSAMPLING` that makes all of these
whole numbers. The thin lens's aperture radius is ``f / (2 N)`` (m), its focal plane at ``focus``.
"""
from __future__ import annotations

import math

import numpy as np

from agvsim.bench.pbr_scene import PAPER_LIFT, WALL_HALF, PbrScene, camera_for, sheet_texture, wall_texture
from localizer.model.target import TargetSpec

#: Mitsuba's variant: the CPU, one ray at a time, RGB
VARIANT = "scalar_rgb"
#: the pip package that provides it (the ``pbr`` extra)
INSTALL = "pip install 'agvsim[pbr]'  (Mitsuba 3)"
#: the fine pixels per pixel (per axis) tried, smallest first
SUPERSAMPLING = (2, 4, 8)


def fine_film(camera) -> tuple[int, int, int, int, int]:
    """``(k, film_width, film_height, crop_width, crop_height)`` of :func:`render_radiance`'s fine
    film for ``camera`` (module docstring); a ``ValueError`` when no ``k`` gives whole numbers."""
    for k in SUPERSAMPLING:
        f = k * camera.fy
        sizes = (camera.width * f / camera.fx, 2.0 * (camera.cx + 0.5) * f / camera.fx,
                 2.0 * (camera.cy + 0.5) * k)
        if all(abs(x - round(x)) < 1e-6 for x in sizes):
            crop_w, film_w, film_h = (int(round(x)) for x in sizes)
            if film_w >= crop_w and film_h >= k * camera.height:
                return k, film_w, film_h, crop_w, k * camera.height
    raise ValueError(f"camera {camera}: no supersampling in {SUPERSAMPLING} puts its pixels on whole fine pixels")


def mitsuba():
    """The ``mitsuba`` module with :data:`VARIANT` set; an ``ImportError`` naming the extra if absent."""
    try:
        import mitsuba as mi
    except ImportError as exc:
        raise ImportError(f"the physically based frames need Mitsuba 3: {INSTALL}") from exc
    mi.set_variant(VARIANT)
    return mi


def _plane(mi, pose, centre_uv: tuple[float, float], half: tuple[float, float], lift: float):
    """A rectangle's ``to_world``: centred at target coordinates ``centre_uv`` (m: u right, v
    down, on the plane of ``pose``), ``half`` its half extents (m), ``lift`` m towards the camera;
    its local x is the plane's u, its local y points up (-v) and its normal faces the camera."""
    ca, sa = math.cos(pose.alpha), math.sin(pose.alpha)
    eu, ev = np.array([ca, 0.0, -sa]), np.array([0.0, -1.0, 0.0])
    n = np.cross(eu, ev)  # (-sin a, 0, -cos a): towards the camera
    c = pose.points(centre_uv[0], centre_uv[1]) + lift * n
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = eu * half[0], ev * half[1], n, c
    return mi.ScalarTransform4f(m.tolist())


def _bitmap(mi, rgb: np.ndarray):
    """A texture whose row 0 is its top (Mitsuba reads row 0 at the rectangle's local y = -1,
    which :func:`_plane` puts at the bottom)."""
    return mi.Bitmap(np.ascontiguousarray(rgb[::-1]))


#: the light passes :func:`render_radiance` sums (Mitsuba picks one emitter per sample: lights
#: rendered together would add the choice's noise), the room's light among them
PASSES = ("lamp", "panel", "room")


def scene_dict(scene: PbrScene, spp: int, light: str, target: TargetSpec = TargetSpec(), wall=None) -> dict:
    """The Mitsuba scene description of ``scene`` lit by one of :data:`PASSES`, ``spp`` samples per
    (coarse) pixel. ``"lamp"`` and ``"panel"``: the direct integrator, that light alone (its
    radiance, W/(m^2 sr)); ``"room"``: the surfaces' albedo at the first hit (an AOV), which times the
    room's radiance is what a uniform ambient light makes of them. ``wall``: the wall's texture
    when already made (:func:`~agvsim.bench.pbr_scene.wall_texture`)."""
    from localizer.numeric import check_choice

    mi = mitsuba()
    light = check_choice("light", light, PASSES)
    camera = camera_for(scene.width, scene.height, scene.focal_mm)
    k, film_w, film_h, crop_w, crop_h = fine_film(camera)
    pose = scene.pose
    sensor = {
        "type": "thinlens", "fov_axis": "y", "fov": math.degrees(2.0 * math.atan(0.5 * film_h / (k * camera.fy))),
        "aperture_radius": scene.focal_mm / 1000.0 / (2.0 * scene.f_number), "focus_distance": scene.focus,
        "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, -1, 0]),
        "film": {"type": "hdrfilm", "width": film_w, "height": film_h, "crop_width": crop_w, "crop_height": crop_h,
                 "pixel_format": "rgb", "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": max(1, int(round(spp / k ** 2)))},
    }
    texture = wall if wall is not None else wall_texture(scene)
    out = {"type": "scene", "sensor": sensor,
           "integrator": {"type": "aov", "aovs": "albedo:albedo"} if light == "room" else {"type": "direct"},
           "wall": {"type": "rectangle", "to_world": _plane(mi, pose, (0.0, 0.0), WALL_HALF, 0.0),
                    "bsdf": _diffuse(mi, texture)}}
    if light == "lamp":
        out["lamp"] = {"type": "point", "position": list(scene.lamp),
                       "intensity": {"type": "rgb", "value": [scene.lamp_power] * 3}}
    if light == "panel":
        m = mi.ScalarTransform4f().translate(list(scene.panel)) @ mi.ScalarTransform4f().rotate([1, 0, 0], -90) \
            @ mi.ScalarTransform4f().scale([0.5, 0.25, 1.0])
        out["panel"] = {"type": "rectangle", "to_world": m,
                        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [scene.panel_radiance] * 3}}}
    if scene.has_target:
        rgb, (w, h), (cu, cv) = sheet_texture(scene.polarity, scene.cut, target)
        out["sheet"] = {"type": "rectangle", "to_world": _plane(mi, pose, (w / 2 - cu, h / 2 - cv), (w / 2, h / 2),
                                                                 PAPER_LIFT),
                        "bsdf": _diffuse(mi, rgb)}
    return out


def _diffuse(mi, rgb: np.ndarray) -> dict:
    return {"type": "diffuse", "reflectance": {"type": "bitmap", "bitmap": _bitmap(mi, rgb), "filter_type": "bilinear",
                                               "raw": True}}


def render_radiance(scene: PbrScene, spp: int, seed: int, target: TargetSpec = TargetSpec()) -> np.ndarray:
    """``(height, width, 3)`` float32 linear RGB radiance of ``scene`` (W/(m^2 sr); ``spp`` samples
    per pixel, Mitsuba's sampler seeded from ``seed``), at the camera's intrinsics: the lamp's pass,
    the panel's (when it is lit) and the room's ambient light times the albedo pass, summed."""
    import cv2

    mi = mitsuba()
    wall = wall_texture(scene)
    total = None
    for n, light in enumerate(PASSES):
        if (light == "panel" and scene.panel_radiance <= 0) or (light == "lamp" and scene.lamp_power <= 0):
            continue  # (a light that is off adds nothing)
        image = np.asarray(mi.render(mi.load_dict(scene_dict(scene, spp, light, target, wall)),
                                     seed=int(seed) * len(PASSES) + n), np.float32)
        image = image * scene.ambient if light == "room" else image
        total = image if total is None else total + image
    return np.ascontiguousarray(cv2.resize(total, (scene.width, scene.height), interpolation=cv2.INTER_AREA))
