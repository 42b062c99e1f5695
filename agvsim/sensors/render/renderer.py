"""``CameraRenderer``: camera frames of a map, rendered with pyrender, with ground truth.

    >>> from agvsim.world import load_map
    >>> from agvsim.sensors.render import CameraRenderer, RenderConditions
    >>> r = CameraRenderer(load_map("plant_floor"))          # no GL context yet
    >>> image, truth = r.render((30.0, 4.0, -1.5708), RenderConditions(), np.random.default_rng(0))
    >>> [t.id for t in truth.visible]

One renderer per world, reused for every frame; the GL context is opened at
the first frame (see :class:`agvsim.sensors.render.gl.GLContext`, which several
renderers in one process should share).

Pipeline per frame:

1. OpenGL (pyrender, ``FLAT``): surface reflectance and depth at ``supersample``
   times the camera's resolution, with an ``IntrinsicsCamera`` whose principal
   point is shifted by half a pixel (OpenGL's pixel centres are at ``j + 0.5``,
   :class:`localizer.Camera`'s at ``j``); pyrender's readback already flips rows
   so row 0 is the top. Box-downsampled to the camera's resolution.
2. Deferred lighting (:mod:`agvsim.sensors.render.lighting`): ambient + ceiling lamps,
   times the map's lighting zone level (or the override) at each pixel's
   surface point, found from the depth buffer.
3. Sensor (:mod:`agvsim.sensors.render.sensor`): motion blur, defocus, distortion,
   exposure, noise, saturation, 8 bits.
4. Truth (:mod:`agvsim.sensors.render.truth`): d, α, β, corners, bbox, visibility by depth test.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from localizer.numeric import check_number

from localizer.camera import Camera
from agvsim.sensors.render.gl import GLContext
from agvsim.sensors.render.lighting import Illumination, lighting_level
from agvsim.sensors.render.mount import CameraMount, CameraPose, check_pose
from agvsim.sensors.render.scene import SceneDescription, build_scene
from agvsim.sensors.render import sensor as sn
from agvsim.sensors.render.truth import FrameTruth, frame_truth

ZNEAR = 0.05  # m
ZFAR = 200.0  # m
SHADING_STRIDE = 2  # px, irradiance is computed on every 2nd pixel and interpolated


def _num(name: str, value, lo: float | None = 0.0, strict: bool = False) -> float:
    return check_number(f"RenderConditions.{name}", value, low=lo, low_open=strict)


@dataclass(frozen=True)
class RenderConditions:
    """What the camera faces in one frame besides the scene.

    Attributes:
        lighting: None to use the map's lighting zones, or an override for the whole
            frame: ``"dim"``, ``"normal"``, ``"bright"`` (:data:`~agvsim.sensors.render.lighting.LIGHTING_LEVELS`)
            or a relative level > 0.
        exposure: relative exposure x gain (1.0: a white target in normal light ~215 grey levels).
        defocus_px: Gaussian optical blur sigma (px), everywhere.
        focus_distance: if set, thin-lens defocus on top: the lens is focused at this
            distance (m) and blur grows with each surface's distance from that plane.
        aperture: aperture diameter for ``focus_distance`` (m; 8 mm = a 16 mm lens at f/2).
        noise: shot + read noise on (needs ``rng``); ``noise_scale`` multiplies its sigmas.
        velocity: ``(v m/s, ω rad/s)`` of the vehicle (forward speed, yaw rate) during the exposure.
        exposure_time: shutter time for motion blur (s).
        distortion: apply the camera's lens distortion (``Camera.dist``) if it has any.
        jitter: draw pitch/roll jitter from the mount's sigmas (needs ``rng``).
        rgb: return an ``(H, W, 3)`` uint8 image (grey replicated; the scene is monochrome)
            instead of ``(H, W)``.
    """

    lighting: str | float | None = None  # None = map zones; name or relative level
    exposure: float = 1.0  # relative
    defocus_px: float = 0.0  # px, sigma
    focus_distance: float | None = None  # m; None = no depth-dependent defocus
    aperture: float = 0.008  # m, aperture diameter
    noise: bool = True
    noise_scale: float = 1.0  # multiplies shot and read noise sigmas
    velocity: tuple[float, float] = (0.0, 0.0)  # (m/s, rad/s)
    exposure_time: float = 0.01  # s
    distortion: bool = True
    jitter: bool = True
    rgb: bool = False
    level: float | None = field(init=False, default=None, repr=False)  # resolved lighting override

    def __post_init__(self) -> None:
        object.__setattr__(self, "level", lighting_level(self.lighting))
        _num("exposure", self.exposure, 0.0, strict=True)
        _num("defocus_px", self.defocus_px)
        _num("aperture", self.aperture)
        if self.focus_distance is not None:
            _num("focus_distance", self.focus_distance, 0.0, strict=True)
        _num("noise_scale", self.noise_scale)
        _num("exposure_time", self.exposure_time)
        vel = tuple(self.velocity)
        if len(vel) != 2:
            raise ValueError(f"RenderConditions.velocity must be (v m/s, omega rad/s), got {self.velocity!r}")
        object.__setattr__(self, "velocity", (_num("velocity[0]", vel[0], None), _num("velocity[1]", vel[1], None)))

    @classmethod
    def ideal(cls, **kw) -> "RenderConditions":
        """No noise, no blur, no jitter, no distortion (for geometry checks)."""
        base = dict(noise=False, defocus_px=0.0, velocity=(0.0, 0.0), distortion=False, jitter=False)
        base.update(kw)
        return cls(**base)


class CameraRenderer:
    """Renders camera frames of one map; create once per world and reuse.

    Args:
        world_map: an :class:`agvsim.world.map.Map`.
        camera: intrinsics (default ``Camera.thesis(16.0)``).
        mount: where the camera sits on the vehicle (default forward-looking, 1.2 m high).
        sensor: sensor constants.
        supersample: render at this many times the resolution per axis and box-filter
            down (1..4; 2 keeps edges within about 0.1 px).
        context: a shared :class:`GLContext` (default: a new one, opened at the first frame).
    """

    def __init__(self, world_map, camera: Camera | None = None, mount: CameraMount | None = None,
                 sensor: sn.SensorModel | None = None, supersample: int = 2, context: GLContext | None = None):
        self.map = world_map
        self.camera = camera if camera is not None else Camera.thesis(16.0)
        if not isinstance(self.camera, Camera):
            raise ValueError(f"camera must be a localizer.Camera, got {type(self.camera).__name__}")
        self.mount = mount if mount is not None else CameraMount()
        self.sensor = sensor if sensor is not None else sn.SensorModel()
        if isinstance(supersample, bool) or not isinstance(supersample, (int, np.integer)) or not 1 <= supersample <= 4:
            raise ValueError(f"supersample must be an integer 1..4, got {supersample!r}")
        self.supersample = int(supersample)
        self.context = context if context is not None else GLContext()
        self.scene: SceneDescription = build_scene(world_map)
        self.illumination = Illumination.from_map(world_map)
        self._gl = None  # (pyrender scene, camera node), built at the first frame
        self._distortion_maps = None
        self._pixel_rays = None

    # ------------------------------------------------------------------ GL
    @property
    def gl_open(self) -> bool:
        """Whether this renderer's GL scene exists (a frame has been rendered)."""
        return self._gl is not None

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

    def _render_gl(self, cam_pose: CameraPose) -> tuple[np.ndarray, np.ndarray]:
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
        _release_texture_sources(scene)
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

    # ------------------------------------------------------------- public
    def camera_pose(self, vehicle_pose, conditions: RenderConditions | None = None,
                    rng: np.random.Generator | None = None) -> CameraPose:
        """The camera's pose for ``vehicle_pose`` (jitter drawn from ``rng`` if enabled)."""
        conditions = conditions or RenderConditions()
        pitch, roll = (self.mount.draw_jitter(rng) if conditions.jitter else (0.0, 0.0))
        return CameraPose.from_vehicle(self.mount, vehicle_pose, pitch, roll)

    def render(self, vehicle_pose, conditions: RenderConditions | None = None,
               rng: np.random.Generator | None = None) -> tuple[np.ndarray, FrameTruth]:
        """Render one frame.

        Args:
            vehicle_pose: ``(x m, y m, θ rad)`` in the map frame.
            conditions: lighting, exposure, blur, noise, motion (default :class:`RenderConditions`).
            rng: the only source of randomness (noise, jitter); required when they are on.
        Returns:
            ``(image, truth)``: ``(H, W)`` uint8 grey (or ``(H, W, 3)`` if ``conditions.rgb``) and
            the :class:`~agvsim.sensors.render.truth.FrameTruth`.
        Raises:
            ValueError: non-finite pose, bad conditions, noise/jitter without ``rng``.
        """
        pose = check_pose(vehicle_pose)
        conditions = conditions if conditions is not None else RenderConditions()
        if not isinstance(conditions, RenderConditions):
            raise ValueError(f"conditions must be RenderConditions, got {type(conditions).__name__}")
        needs_rng = (conditions.noise and conditions.noise_scale > 0) or (
            conditions.jitter and (self.mount.pitch_sigma > 0 or self.mount.roll_sigma > 0))
        if needs_rng and not isinstance(rng, np.random.Generator):
            raise ValueError("render() with noise or jitter needs rng, a numpy.random.Generator "
                             "(or use RenderConditions(noise=False, jitter=False))")
        cam_pose = self.camera_pose(pose, conditions, rng)
        albedo, depth_full = self._render_gl(cam_pose)
        radiance, depth = self._shade(albedo, depth_full, cam_pose, conditions.level)
        v, w = conditions.velocity
        if (v != 0.0 or w != 0.0) and conditions.exposure_time > 0:
            radiance = sn.motion_blur(radiance, depth, self.camera, self._camera_twist(pose, v, w, cam_pose),
                                      conditions.exposure_time)
        if conditions.focus_distance is not None and conditions.aperture > 0:
            radiance = sn.defocus_depth(radiance, depth, self.camera.fx, conditions.aperture,
                                        conditions.focus_distance, conditions.defocus_px)
        else:
            radiance = sn.defocus(radiance, conditions.defocus_px)
        distorted = bool(conditions.distortion and self.camera.dist)
        if distorted:
            if self._distortion_maps is None:
                self._distortion_maps = sn.distortion_maps(self.camera)
            radiance = sn.apply_distortion(radiance, self._distortion_maps)
        image = sn.expose(radiance, self.sensor, conditions.exposure, conditions.noise, rng, conditions.noise_scale)
        if conditions.rgb:
            image = np.repeat(image[..., None], 3, axis=2)
        truth = frame_truth(self.map, self.camera, cam_pose, pose, depth_full, self.supersample, distorted,
                            conditions.level)
        return image, truth

    def _camera_twist(self, pose, v: float, w: float, cam_pose: CameraPose):
        """Camera linear (m/s) and angular (rad/s) velocity in the camera frame."""
        x, y, th = pose
        vel = np.array([v * math.cos(th), v * math.sin(th), 0.0])
        arm = cam_pose.position - np.array([x, y, cam_pose.position[2]])
        vel = vel + np.cross([0.0, 0.0, w], arm)
        omega = np.array([0.0, 0.0, w])
        return cam_pose.rotation.T @ vel, cam_pose.rotation.T @ omega

    def close(self) -> None:
        """Drop this renderer's camera from the shared GL scene (the context stays open)."""
        if self._gl is not None:
            _, scene, node = self._gl
            if scene.has_node(node):
                scene.remove_node(node)
        self._gl = None

    def __repr__(self) -> str:
        c = self.camera
        return (f"CameraRenderer(map={self.map.name!r}, {c.width}x{c.height} fx={c.fx:.1f} fy={c.fy:.1f}, "
                f"supersample={self.supersample}, gl={'open' if self.context.is_open else 'not opened'})")


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


def _release_texture_sources(scene) -> None:
    """Drop the CPU copies of textures already uploaded to the GL context.

    pyrender keeps each texture's source array after upload; the GL
    context (one per process, never recreated) holds its own copy, so the
    source is dead weight (about 25 MB for ``plant_floor``). Textures not yet
    uploaded (no GL texture id) keep theirs.
    """
    for mesh in scene.meshes:
        for prim in mesh.primitives:
            tex = getattr(prim.material, "baseColorTexture", None)
            if tex is not None and tex.source is not None and getattr(tex, "_texid", None) is not None:
                tex.source = None

