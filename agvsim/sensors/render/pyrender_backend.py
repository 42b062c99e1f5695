"""The pyrender backend: reflectance and depth by OpenGL (EGL/llvmpipe headless), lit here.

The reference renderer and the general 3-D path (:class:`PyrenderBackend`); the compiled
raycaster (:mod:`agvsim.sensors.render.raycast`) is the fast one. Per frame:

1. OpenGL (pyrender, ``FLAT``): surface reflectance and depth at ``supersample``
   times the camera's resolution, with an ``IntrinsicsCamera`` whose principal
   point is shifted by half a pixel (OpenGL's pixel centres are at ``j + 0.5``,
   :class:`localizer.Camera`'s at ``j``); pyrender's readback already flips rows
   so row 0 is the top. Box-downsampled to the camera's resolution.
2. Deferred lighting (:mod:`agvsim.sensors.render.lighting`): ambient + ceiling lamps,
   times the map's lighting zone level (or the override) at each pixel's
   surface point, found from the depth buffer.

The GL context is opened at the first frame (:class:`agvsim.sensors.render.gl.GLContext`,
which several renderers in one process should share).
"""
from __future__ import annotations

import dataclasses
from types import MappingProxyType

import numpy as np

from agvsim.sensors.render.gl import GLContext
from agvsim.sensors.render.lighting import Illumination
from agvsim.sensors.render.mount import CameraPose
from agvsim.sensors.render.scene import SceneDescription
from localizer.model.camera import Camera

__all__ = ["SHADING_STRIDE", "ZFAR", "ZNEAR", "PyrenderBackend"]

ZNEAR = 0.05  # m
ZFAR = 200.0  # m
SHADING_STRIDE = 2  # px, irradiance is computed on every 2nd pixel and interpolated


class PyrenderBackend:
    """Draws frames of one map with pyrender (one per renderer; the GL context may be shared).

    Args:
        world_map, camera: the map and the intrinsics.
        scene, illumination: the map's scene and lighting.
        supersample: render at this many times the resolution per axis and box-filter down.
        context: a shared :class:`GLContext` (default: a new one, opened at the first frame).
    """

    def __init__(self, world_map, camera: Camera, scene: SceneDescription, illumination: Illumination,
                 supersample: int = 2, context: GLContext | None = None) -> None:
        self.map = world_map
        self.camera = camera
        self.scene = scene
        self.illumination = illumination
        self.supersample = int(supersample)
        self.context = context if context is not None else GLContext()
        self._gl = None  # (pyrender, scene, camera node), built at the first frame
        self._pixel_rays = None

    @property
    def gl_open(self) -> bool:
        """Whether this renderer's GL scene exists (a frame has been rendered)."""
        return self._gl is not None

    @property
    def gl_scene(self):
        """``(pyrender module, pyrender.Scene, camera node)`` once the first frame is drawn, else None."""
        return self._gl

    def _build_gl(self):
        from agvsim.sensors.render.gl import import_pyrender

        pyrender, _ = import_pyrender()
        scene = self.context.shared_scene(self.map, lambda: self._make_scene(pyrender))
        # the reflectance textures now live in the pyrender scene (and, after the
        # first frame, only in the GL context): drop this renderer's float copies
        self.scene = dataclasses.replace(self.scene, textures=MappingProxyType({}))
        s = self.supersample
        c = self.camera
        cam = pyrender.IntrinsicsCamera(fx=c.fx * s, fy=c.fy * s, cx=(c.cx + 0.5) * s, cy=(c.cy + 0.5) * s,
                                        znear=ZNEAR, zfar=ZFAR)
        node = scene.add(cam, pose=np.eye(4))
        self._gl = (pyrender, scene, node)

    def _make_scene(self, pyrender):
        """The pyrender scene of :attr:`scene` (meshes and textures; no camera)."""
        from pyrender.constants import GLTF

        from agvsim.sensors.render.textures import to_rgba8

        bg = float(self.scene.background)
        scene = pyrender.Scene(bg_color=[bg, bg, bg, 1.0], ambient_light=[1.0, 1.0, 1.0])
        texture_cache = {}
        for part in self.scene.parts:
            wrap = GLTF.REPEAT if part.tiled else GLTF.CLAMP_TO_EDGE
            tex = texture_cache.get(part.texture)
            if tex is None:
                sampler = pyrender.Sampler(magFilter=GLTF.LINEAR, minFilter=GLTF.LINEAR_MIPMAP_LINEAR,
                                           wrapS=wrap, wrapT=wrap)
                tex = pyrender.Texture(source=to_rgba8(self.scene.textures[part.texture]), source_channels="RGBA",
                                       sampler=sampler)
                texture_cache[part.texture] = tex
            mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0], baseColorTexture=tex,
                                                     metallicFactor=0.0, roughnessFactor=1.0)
            # pyrender draws solid meshes sorted by the distance of their node's origin from the
            # camera, ties in the (per-process random) order of a set; MSAA edge pixels depend on
            # the draw order, so give every mesh its own origin (its centroid) for a fixed order
            centre = part.positions.astype(np.float64).mean(axis=0)
            prim = pyrender.Primitive(positions=(part.positions - centre).astype(np.float32), texcoord_0=part.uvs,
                                      indices=part.indices, material=mat, mode=4)
            pose = np.eye(4)
            pose[:3, 3] = centre
            scene.add(pyrender.Mesh([prim]), pose=pose)
        return scene

    def render_gl(self, cam_pose: CameraPose) -> tuple[np.ndarray, np.ndarray]:
        """``(albedo (H, W) float32, depth (H*s, W*s) float32)`` for ``cam_pose``."""
        import cv2

        s = self.supersample
        off = self.context.renderer(self.camera.width * s, self.camera.height * s)
        if self._gl is None:
            self._build_gl()
        pyrender, scene, node = self._gl
        scene.main_camera_node = node
        scene.set_pose(node, cam_pose.gl_pose())
        color, depth = off.render(scene, flags=pyrender.RenderFlags.FLAT)
        albedo = color[..., 0].astype(np.float32) * np.float32(1.0 / 255.0)
        if s > 1:
            albedo = cv2.resize(albedo, (self.camera.width, self.camera.height), interpolation=cv2.INTER_AREA)
        return albedo, depth

    # ------------------------------------------------------------- shading
    def _rays(self, stride: int) -> np.ndarray:
        """``(H/stride, W/stride, 3)`` camera-frame rays ``(x/z, y/z, 1)`` of every ``stride``-th pixel."""
        if self._pixel_rays is None or self._pixel_rays[0] != stride:
            c = self.camera
            jj, ii = np.meshgrid(np.arange(0, c.width, stride, dtype=np.float32) + (stride - 1) / 2,
                                 np.arange(0, c.height, stride, dtype=np.float32) + (stride - 1) / 2)
            rays = np.stack([(jj - c.cx) / c.fx, (ii - c.cy) / c.fy, np.ones_like(jj)], axis=-1)
            self._pixel_rays = (stride, rays.astype(np.float32))
        return self._pixel_rays[1]

    def _shade(self, albedo: np.ndarray, depth_full: np.ndarray, cam_pose: CameraPose, level: float | None):
        """Radiance ``(H, W)`` float32 and the per-pixel depth ``(H, W)`` (m, 0 = nothing).

        Irradiance varies slowly over a surface, so it is computed on every
        :data:`SHADING_STRIDE`-th pixel (from the depth buffer) and interpolated.
        """
        import cv2

        s = self.supersample
        k = SHADING_STRIDE
        h, w = self.camera.height, self.camera.width
        depth = depth_full[s // 2::s, s // 2::s] if s > 1 else depth_full
        # depth at the coarse grid: the sample nearest each coarse cell's centre
        step = s * k
        off = step // 2  # the supersampled pixel at each coarse cell's centre
        dk = depth_full[off::step, off::step][: -(-h // k), : -(-w // k)]
        rays = self._rays(k)[: dk.shape[0], : dk.shape[1]]
        pts = rays * dk[..., None] @ cam_pose.rotation.T.astype(np.float32) + cam_pose.position.astype(np.float32)
        normals = _normals_from_points(pts, dk)
        irr = self.illumination.irradiance(pts, normals)
        if level is None:
            irr = irr * self.illumination.zone_level(pts[..., :2])
        else:
            irr = irr * np.float32(level)
        bg_level = np.float32(level if level is not None else self.map.lighting_default)
        irr = np.where(dk > 0, irr, bg_level).astype(np.float32)
        if k > 1:
            irr = cv2.resize(irr, (w, h), interpolation=cv2.INTER_LINEAR)
        return (albedo * irr).astype(np.float32), depth

    def draw(self, cam_pose: CameraPose, level: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(radiance (H, W), depth (H, W), depth (H s, W s))`` float32 of one frame (depth m
        along the optical axis, 0 = nothing)."""
        albedo, depth_full = self.render_gl(cam_pose)
        radiance, depth = self._shade(albedo, depth_full, cam_pose, level)
        return radiance, depth, depth_full

    def close(self) -> None:
        """Drop this renderer's camera from the shared GL scene (the context stays open)."""
        if self._gl is not None:
            _, scene, node = self._gl
            if scene.has_node(node):
                scene.remove_node(node)
        self._gl = None


def _normals_from_points(pts: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """Unit surface normals ``(H, W, 3)`` from back-projected points, using at each pixel the
    neighbour (left/right, up/down) with the smaller depth jump so silhouettes stay sharp."""
    p = pts
    dxf = np.zeros_like(p)
    dxb = np.zeros_like(p)
    dxf[:, :-1] = p[:, 1:] - p[:, :-1]
    dxb[:, 1:] = p[:, 1:] - p[:, :-1]
    dyf = np.zeros_like(p)
    dyb = np.zeros_like(p)
    dyf[:-1] = p[1:] - p[:-1]
    dyb[1:] = p[1:] - p[:-1]
    zf = np.zeros_like(depth)
    zb = np.full_like(depth, np.inf)
    zf[:, :-1] = np.abs(depth[:, 1:] - depth[:, :-1])
    zf[:, -1] = np.inf
    zb[:, 1:] = np.abs(depth[:, 1:] - depth[:, :-1])
    dx = np.where((zf <= zb)[..., None], dxf, dxb)
    zf = np.zeros_like(depth)
    zb = np.full_like(depth, np.inf)
    zf[:-1] = np.abs(depth[1:] - depth[:-1])
    zf[-1] = np.inf
    zb[1:] = np.abs(depth[1:] - depth[:-1])
    dy = np.where((zf <= zb)[..., None], dyf, dyb)
    n = np.cross(dy, dx)  # image x right, y down -> normal towards the camera
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    n = n / np.maximum(norm, 1e-12)
    return n.astype(np.float32)
