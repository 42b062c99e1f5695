"""``CameraRenderer``: camera frames of a map, with ground truth, from one of two backends.

    >>> from agvsim.world import load_map
    >>> from agvsim.sensors.render import CameraRenderer, RenderConditions
    >>> r = CameraRenderer(load_map("plant_floor"))          # no GL context yet
    >>> image, truth = r.render((30.0, 4.0, -1.5708), RenderConditions(), np.random.default_rng(0))
    >>> [t.id for t in truth.visible]

One renderer per world, reused for every frame. Backends (:data:`agvsim.sensors.backends.BACKENDS`):

* ``raycast`` (default): the compiled column raycaster (:mod:`agvsim.sensors.render.raycast`),
  exact for the level camera, no OpenGL;
* ``pyrender``: OpenGL (:mod:`agvsim.sensors.render.pyrender_backend`), the reference; the GL
  context is opened at the first frame.

Pipeline per frame: the backend's radiance and depth (surface reflectance x the lighting
of :mod:`agvsim.sensors.render.lighting`) -> the sensor (:mod:`agvsim.sensors.render.sensor`;
compiled for the raycaster: :mod:`agvsim.sensors.render._motion_blur_kernels`,
:mod:`agvsim.sensors.render._sensor_kernels`): motion blur, defocus, distortion, exposure,
noise, saturation, 8 bits -> truth
(:mod:`agvsim.sensors.render.truth`): d, α, β, corners, bbox, visibility by depth test.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from localizer.interrupts import deferred_interrupt
from localizer.numeric import check_number

from localizer.model.camera import Camera
from agvsim.sensors.render import sensor as sn
from agvsim.sensors.backends import DEFAULT_BACKEND, check_backend
from agvsim.sensors.render.gl import GLContext
from agvsim.sensors.render.lighting import Illumination, lighting_level
from agvsim.sensors.render.mount import CameraMount, CameraPose, check_pose
from agvsim.sensors.render.ray_records import BlurScratch, MotionBlurParams, SensorParams
from agvsim.sensors.render.scene import SceneDescription, build_scene
from agvsim.sensors.render.truth import FrameTruth, TruthGeometry, frame_truth

_NO_SENSOR = SensorParams(1.0, 0.0, 1.0, 0.0, 0.0, 0)  # (motion blur's sensor when the blurred radiance is stored)
_NO_IMAGE = np.zeros((0, 0), np.uint8)


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
        supersample: pyrender only: render at this many times the resolution per axis and
            box-filter down (1..4; 2 keeps edges within about 0.1 px). The raycaster
            integrates each pixel's area instead.
        context: pyrender only: a shared :class:`GLContext` (default: a new one, opened at
            the first frame).
        backend: ``"raycast"`` or ``"pyrender"`` (:data:`~agvsim.sensors.backends.BACKENDS`).
    """

    def __init__(self, world_map, camera: Camera | None = None, mount: CameraMount | None = None,
                 sensor: sn.SensorModel | None = None, supersample: int = 2, context: GLContext | None = None,
                 backend: str = DEFAULT_BACKEND):
        self.map = world_map
        self.backend = check_backend(backend)
        self.camera = camera if camera is not None else Camera.thesis(16.0)
        if not isinstance(self.camera, Camera):
            raise ValueError(f"camera must be a localizer.Camera, got {type(self.camera).__name__}")
        self.mount = mount if mount is not None else CameraMount()
        self.sensor = sensor if sensor is not None else sn.SensorModel()
        if isinstance(supersample, bool) or not isinstance(supersample, (int, np.integer)) or not 1 <= supersample <= 4:
            raise ValueError(f"supersample must be an integer 1..4, got {supersample!r}")
        if context is not None and self.backend != "pyrender":
            raise ValueError(f"context= is a GL context for backend='pyrender'; backend={self.backend!r} opens none")
        scene: SceneDescription = build_scene(world_map)
        self.illumination = Illumination.from_map(world_map)
        self._truth_geometry = TruthGeometry.of(world_map)
        self._distortion_maps = None
        self._row_buffers = None  # raycast: row-major copies of the frame, for the optics
        self._frame_buffers = None  # raycast: the frame's radiance and depth, drawn into every frame
        self._columns_u8 = None  # raycast: a block of the 8-bit frame's columns, before they are stored
        self._blur_buffers = None  # raycast: motion blur's work arrays and blurred radiance
        if self.backend == "pyrender":
            from agvsim.sensors.render.pyrender_backend import PyrenderBackend

            self.engine = PyrenderBackend(world_map, self.camera, scene, self.illumination, int(supersample), context)
            self.context = self.engine.context
            self.supersample = self.engine.supersample
        else:
            from agvsim.sensors.render.raycast import RaycastBackend

            self.engine = RaycastBackend(scene, self.illumination, world_map.lighting_default)
            self.context = None
            self.supersample = 1

    @property
    def gl_open(self) -> bool:
        """Whether this renderer's GL scene exists (pyrender, after the first frame)."""
        return self.backend == "pyrender" and self.engine.gl_scene is not None

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
        noisy = conditions.noise and conditions.noise_scale > 0
        needs_rng = noisy or (conditions.jitter and (self.mount.pitch_sigma > 0 or self.mount.roll_sigma > 0))
        if needs_rng and not isinstance(rng, np.random.Generator):
            raise ValueError("render() with noise or jitter needs rng, a numpy.random.Generator "
                             "(or use RenderConditions(noise=False, jitter=False))")
        with deferred_interrupt():  # (a KeyboardInterrupt inside a compiled call crashes Python)
            return self._render(pose, conditions, rng, noisy)

    def _render(self, pose: tuple, conditions: RenderConditions, rng, noisy: bool) -> tuple[np.ndarray, FrameTruth]:
        """:meth:`render` of a checked pose and conditions."""
        cam_pose = self.camera_pose(pose, conditions, rng)
        if self.backend == "raycast":
            image, depth_full = self._raycast_frame(pose, cam_pose, conditions, rng if noisy else None)
        else:
            image, depth_full = self._pyrender_frame(pose, cam_pose, conditions, rng)
        if conditions.rgb:
            image = np.repeat(image[..., None], 3, axis=2)
        distorted = bool(conditions.distortion and self.camera.dist)
        truth = frame_truth(self.map, self.camera, cam_pose, pose, depth_full, self.supersample, distorted,
                            conditions.level, geometry=self._truth_geometry)
        return image, truth

    def _optics(self, radiance: np.ndarray, depth: np.ndarray, conditions: RenderConditions) -> np.ndarray:
        """Defocus and lens distortion of an ``(H, W)`` radiance image (as light goes)."""
        if conditions.focus_distance is not None and conditions.aperture > 0:
            radiance = sn.defocus_depth(radiance, depth, self.camera.fx, conditions.aperture,
                                        conditions.focus_distance, conditions.defocus_px)
        else:
            radiance = sn.defocus(radiance, conditions.defocus_px)
        if conditions.distortion and self.camera.dist:
            if self._distortion_maps is None:
                self._distortion_maps = sn.distortion_maps(self.camera)
            radiance = sn.apply_distortion(radiance, self._distortion_maps)
        return radiance

    def _pyrender_frame(self, pose, cam_pose, conditions, rng):
        radiance, depth, depth_full = self.engine.draw(cam_pose, conditions.level)
        v, w = conditions.velocity
        if (v != 0.0 or w != 0.0) and conditions.exposure_time > 0:
            radiance = sn.motion_blur(radiance, depth, self.camera, self._camera_twist(pose, v, w, cam_pose),
                                      conditions.exposure_time)
        radiance = self._optics(radiance, depth, conditions)
        image = sn.expose(radiance, self.sensor, conditions.exposure, conditions.noise, rng, conditions.noise_scale)
        return image, depth_full

    def _raycast_frame(self, pose, cam_pose, conditions, rng):
        from agvsim.sensors.render._motion_blur_kernels import transpose_into
        from agvsim.sensors.render._sensor_kernels import expose, expose_columns, expose_scratch, nearest_depth

        c = self.camera
        if self._frame_buffers is None:  # the backend draws into them (nothing render() returns refers to them)
            from agvsim.sensors.render.raycast import frame_buffers

            self._frame_buffers = frame_buffers(c.width, c.height)
        v, w = conditions.velocity
        moving = (v != 0.0 or w != 0.0) and conditions.exposure_time > 0
        optics = self._optics_apply(conditions)
        if not moving and not optics and cam_pose.pitch == 0.0 and cam_pose.roll == 0.0:
            # a still, level frame with nothing between the scene and the sensor: exposed as it
            # is drawn (the same frame bit for bit as below, without storing the radiance)
            image = np.empty((c.height, c.width), np.uint8)  # a new array: callers keep their frames
            depth = self._frame_buffers[1]
            self.engine.draw_exposed(self.engine.view(c, cam_pose, conditions.level), self._sensor_params(conditions, rng),
                                     image, depth)
            return image, depth
        # (H, W) column-major (the raycaster draws a column at a time): motion blur reads it as it
        # is (and, with no optics after it, exposes it as it blurs it); the sensor exposes it column
        # by column into the row-major 8-bit frame; OpenCV's optics read row-major copies (and the
        # depth returned for the truth is then the row-major one)
        radiance, depth = self.engine.draw(c, cam_pose, conditions.level, self._frame_buffers)
        motion = None
        if moving:
            motion = sn.exposure_motion(c, radiance, depth, self._camera_twist(pose, v, w, cam_pose),
                                        conditions.exposure_time, z_min=nearest_depth(depth.T))
        if motion is not None:
            blur = MotionBlurParams(c.fx, c.fy, c.cx, c.cy, *motion[:4])
            if not optics:
                return self._blurred(radiance, depth, blur, self._sensor_params(conditions, rng)), depth
            radiance = self._blurred(radiance, depth, blur, None)
        if optics:
            if self._row_buffers is None:  # row-major copies of the radiance and the depth
                self._row_buffers = tuple(np.empty((c.height, c.width), np.float32) for _ in range(2))
            rad_rows, dep_rows = self._row_buffers
            transpose_into(radiance.T, rad_rows)
            transpose_into(depth.T, dep_rows)
            radiance, depth = self._optics(rad_rows, dep_rows, conditions), dep_rows
        params = self._sensor_params(conditions, rng)
        image = np.empty((c.height, c.width), np.uint8)  # a new array: callers keep their frames
        if radiance.flags.c_contiguous:
            expose(radiance, params, image)  # the kernel reads it flat
        else:  # column-major: exposed a block of columns at a time, stored row by row
            if self._columns_u8 is None:
                self._columns_u8 = expose_scratch(c.height)
            expose_columns(radiance.T, params, image, self._columns_u8)
        return image, depth

    def _blurred(self, radiance: np.ndarray, depth: np.ndarray, blur: MotionBlurParams,
                 params: SensorParams | None) -> np.ndarray:
        """The column-major ``radiance`` and ``depth`` (``(H, W)`` float32, Fortran order) blurred by
        ``blur`` (:func:`~agvsim.sensors.render._motion_blur_kernels.blur_columns`): exposed with
        ``params`` as it is blurred, a new ``(H, W)`` uint8 frame; or, ``params`` None, the blurred
        radiance, ``(H, W)`` float32 in Fortran order (the renderer's buffer, overwritten by the
        next such frame)."""
        from agvsim.sensors.render._motion_blur_kernels import blur_columns

        c = self.camera
        if self._blur_buffers is None:  # the blur's work arrays, the blurred radiance (column-major)
            self._blur_buffers = (BlurScratch.of(c.height, c.width), np.empty((c.width, c.height), np.float32))
        scratch, blurred_t = self._blur_buffers
        if params is None:
            blur_columns(radiance.T, depth.T, blur, blurred_t, scratch, _NO_SENSOR, _NO_IMAGE)
            return blurred_t.T
        image = np.empty((c.height, c.width), np.uint8)  # a new array: callers keep their frames
        blur_columns(radiance.T, depth.T, blur, blurred_t, scratch, params, image)
        return image

    def _sensor_params(self, conditions: RenderConditions, rng: np.random.Generator | None) -> SensorParams:
        """The sensor's constants for one frame: its noise seed drawn from ``rng`` (None: no noise)."""
        s = self.sensor
        seed = int(rng.integers(0, 2 ** 63)) if rng is not None else 0
        return SensorParams(float(s.gain * conditions.exposure), float(s.flare), float(s.full_well / 255.0),
                            float(s.read_noise), float(conditions.noise_scale if rng is not None else 0.0), seed)

    def _optics_apply(self, conditions: RenderConditions) -> bool:
        """Whether :meth:`_optics` changes the radiance under ``conditions``."""
        return ((conditions.focus_distance is not None and conditions.aperture > 0) or conditions.defocus_px > 0
                or bool(conditions.distortion and self.camera.dist))

    def _camera_twist(self, pose, v: float, w: float, cam_pose: CameraPose):
        """Camera linear (m/s) and angular (rad/s) velocity in the camera frame."""
        x, y, th = pose
        vel = np.array([v * math.cos(th), v * math.sin(th), 0.0])
        arm = cam_pose.position - np.array([x, y, cam_pose.position[2]])
        vel = vel + np.cross([0.0, 0.0, w], arm)
        omega = np.array([0.0, 0.0, w])
        return cam_pose.rotation.T @ vel, cam_pose.rotation.T @ omega

    def close(self) -> None:
        """pyrender: drop this renderer's camera from the shared GL scene (the context stays open)."""
        if self.backend == "pyrender":
            self.engine.close()

    def __repr__(self) -> str:
        c = self.camera
        gl = "" if self.backend != "pyrender" else \
            f", supersample={self.supersample}, gl={'open' if self.context.is_open else 'not opened'}"
        return (f"CameraRenderer(map={self.map.name!r}, backend={self.backend!r}, {c.width}x{c.height} "
                f"fx={c.fx:.1f} fy={c.fy:.1f}{gl})")
