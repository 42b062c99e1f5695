"""Scenes of the physically based frame set (``agvsim bench pbr``): a printed sheet on a wall,
lit by a lamp and the room, seen through a thin lens, rendered by Mitsuba 3.

Nothing here comes from the localizer's model of a frame or from the simulator's camera: the
target is the page ``agvsim target print`` lays out (:func:`agvsim.deploy.printing.plan_pages`,
rasterised by matplotlib as a printer would), the wall is a procedural texture of paint,
stains, a dark dado band and posters, the light is a point lamp and an area panel in front of
the wall plus the room's ambient light (so the paper is shaded across), and the optics are
Mitsuba's thin lens (depth of field from the aperture and the focus distance). The path tracer
computes the radiance; :mod:`agvsim.bench.pbr_sensor` turns it into a camera's frame.

Frames: the localizer's camera frame (x right, y down, z forward, m), which is also the
scene's world frame: the camera sits at the origin looking down +z. A target's pose is a
:class:`localizer.TargetPose` (distance d, bearing beta > 0 right of the axis, alpha > 0 when
its right edge is nearer, height = camera-frame y of its centre).
"""
from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass

import numpy as np

from localizer.model.camera import Camera
from localizer.model.geometry import TargetPose
from localizer.model.target import POLARITIES, TargetSpec

#: the lenses (mm) of the thesis camera the set uses, and the distances (m) each is sampled over
LENSES: dict[float, tuple[float, float]] = {16.0: (1.2, 9.0), 50.0: (3.5, 24.0)}
#: alpha is sampled within this (rad): steep views, as the localizer's specification allows
ALPHA_MAX = math.radians(70.0)
#: the defocus disc's diameter is sampled up to this (px at 512 wide, scaled): a blur sd of 3 px
MAX_DISC_PX = 13.0
#: the page is rasterised at this many pixels per mm (a 600 dpi print is ~24)
PAGE_PX_PER_MM = 4.0
#: the paper sits this far (m) in front of the wall (no z-fighting; it is flat on the wall)
PAPER_LIFT = 0.0005
#: the wall's extent (m) around the target: wide and tall enough to fill every view
WALL_HALF = (14.0, 6.0)
#: wall texture resolution, pixels per m
WALL_PX_PER_M = 120.0
#: frames keep the whole target face this many pixels inside the image (at 512 px wide, scaled)
FRAME_MARGIN_PX = 6.0


@dataclass(frozen=True)
class PbrScene:
    """Everything that makes one frame's scene (SI units; JSON-ready through :func:`asdict`)."""

    width: int  # px, the frame's size
    height: int  # px
    focal_mm: float  # the thesis camera's lens (16 or 50 mm at 512 x 480; the same view at other sizes)
    has_target: bool
    distance: float  # m, the target pose (:class:`localizer.TargetPose`); the wall's pose without a target
    beta: float  # rad
    alpha: float  # rad
    target_height: float  # m, camera-frame y of the target centre (down positive)
    polarity: str  # "positive" or "negative"
    cut: bool  # the face cut out on its crop marks (else the whole sheet hangs, text and all)
    f_number: float  # the lens aperture
    focus: float  # m, the distance the lens is focused at
    lamp: tuple[float, float, float]  # m, the point lamp's position (camera frame)
    lamp_power: float  # W/sr, its intensity
    panel: tuple[float, float, float]  # m, the centre of the 1 x 0.5 m ceiling panel facing down
    panel_radiance: float  # W/(m^2 sr), its radiance
    ambient: float  # W/(m^2 sr), the room's uniform radiance
    paint: tuple[float, float, float]  # the wall paint's RGB reflectance
    band: tuple[float, float, float]  # m, the dark band's top and bottom (wall v, down positive) and reflectance
    wall_seed: int  # the wall texture's generator seed

    @property
    def pose(self) -> TargetPose:
        return TargetPose(self.distance, self.beta, self.alpha, self.target_height)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "PbrScene":
        """The scene of a record's ``scene`` (:meth:`to_dict`; JSON lists back to tuples)."""
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})


def camera_for(width: int, height: int, focal_mm: float) -> Camera:
    """The thesis camera with a ``focal_mm`` lens at 512 x 480, else square pixels with the same
    horizontal field of view (``fx = fy = fx_thesis * width / 512``), principal point at the centre."""
    thesis = Camera.thesis(focal_mm)
    if (width, height) == (thesis.width, thesis.height):
        return thesis
    f = thesis.fx * width / thesis.width
    return Camera.from_intrinsics(f, f, width / 2.0, height / 2.0, width, height)


def face_in_view(pose: TargetPose, camera: Camera, target: TargetSpec, margin: float) -> bool:
    """Whether the target's face (margin included) lies ``margin`` px inside the frame."""
    u = 0.5 * target.outer_width * np.array([-1.0, 1.0, 1.0, -1.0])
    v = 0.5 * target.outer_height * np.array([-1.0, -1.0, 1.0, 1.0])
    p = pose.points(u, v)
    if np.any(p[:, 2] < 0.2):
        return False
    xy = camera.project(p)
    return bool(np.all((xy[:, 0] >= margin) & (xy[:, 0] <= camera.width - 1 - margin)
                       & (xy[:, 1] >= margin) & (xy[:, 1] <= camera.height - 1 - margin)))


def _pose(rng: np.random.Generator, camera: Camera, focal_mm: float, target: TargetSpec) -> TargetPose:
    near, far = LENSES[focal_mm]
    margin = FRAME_MARGIN_PX * camera.width / 512.0
    for _ in range(400):
        d = math.exp(rng.uniform(math.log(near), math.log(far)))
        half = math.atan(0.5 * camera.width / camera.fx)
        vhalf = math.atan(0.5 * camera.height / camera.fy)
        pose = TargetPose(d, rng.uniform(-half, half), rng.uniform(-ALPHA_MAX, ALPHA_MAX),
                          d * math.tan(rng.uniform(-vhalf, vhalf)))
        if face_in_view(pose, camera, target, margin):
            return pose
    raise ValueError(f"no pose shows the target whole in a {camera.width}x{camera.height} frame")


def focus_for_disc(d: float, disc: float, aperture_px: float, nearer: bool) -> float:
    """The focus distance (m) that blurs a point at ``d`` (m) into a disc of ``disc`` px, for an
    aperture of ``aperture_px`` (its diameter times fx): ``disc = aperture_px |1/s - 1/d|``, on
    the near side of ``d`` or beyond it (where beyond would be past infinity, the near side)."""
    step = disc / aperture_px
    if not nearer and 1.0 / d - step > 1e-3:
        return 1.0 / (1.0 / d - step)
    return 1.0 / (1.0 / d + step)


def sample_scene(rng: np.random.Generator, width: int, height: int, focal_mm: float, has_target: bool,
                 target: TargetSpec = TargetSpec()) -> PbrScene:
    """One scene from ``rng``: the pose (distance log-uniform over the lens's range, alpha uniform
    within +-70 deg, bearing and height uniform over the view, the whole face inside the frame),
    the lens (f/1.4-f/8, focused on the target or, in 70 % of
    scenes, off it by a defocus disc of up to :data:`MAX_DISC_PX`), the lights and the wall."""
    camera = camera_for(width, height, focal_mm)
    pose = _pose(rng, camera, focal_mm, target)
    d = pose.distance
    f_number = math.exp(rng.uniform(math.log(1.4), math.log(8.0)))
    focus = focus_for_disc(d, rng.uniform(0.0, MAX_DISC_PX * camera.width / 512.0) if rng.random() < 0.7 else 0.0,
                   focal_mm / 1000.0 / f_number * camera.fx, rng.random() < 0.5)
    side = rng.choice([-1.0, 1.0])
    lamp = (float(pose.centre[0] + side * rng.uniform(0.3, 3.0)), float(pose.height - rng.uniform(0.5, 2.5)),
            float(pose.centre[2] * rng.uniform(0.3, 0.9)))
    panel = (float(rng.uniform(-2.0, 2.0)), float(-rng.uniform(1.5, 3.0)), float(pose.centre[2] * rng.uniform(0.2, 0.8)))
    paint = tuple(float(x) for x in np.clip(rng.uniform(0.35, 0.85) * (1.0 + rng.normal(0.0, 0.08, 3)), 0.05, 0.95))
    band_top = float(rng.uniform(-0.15, 0.5))  # wall v of the band's top (m, down, from the target centre)
    return PbrScene(
        width=int(width), height=int(height), focal_mm=float(focal_mm), has_target=bool(has_target),
        distance=float(d), beta=float(pose.beta), alpha=float(pose.alpha), target_height=float(pose.height),
        polarity=str(rng.choice(POLARITIES)), cut=bool(rng.random() < 0.5),
        f_number=float(f_number), focus=float(focus),
        lamp=lamp, lamp_power=float(rng.uniform(2.0, 40.0)) * float(np.dot(lamp, lamp)) ** 0.5,
        panel=panel, panel_radiance=float(rng.uniform(0.0, 6.0)), ambient=float(rng.uniform(0.05, 0.6)),
        paint=paint, band=(band_top, band_top + float(rng.uniform(0.1, 0.6)), float(rng.uniform(0.03, 0.2))),
        wall_seed=int(rng.integers(2**31)))


# ----------------------------------------------------------------------------- textures

@functools.lru_cache(maxsize=4)
def sheet_texture(polarity: str, cut: bool, target: TargetSpec = TargetSpec()) -> tuple[np.ndarray, tuple, tuple]:
    """The printed page as a reflectance texture: ``(rgb, size_m, centre_m)`` -- the ``(H, W, 3)``
    float32 image (row 0 at the page's top), the page's (width, height) in m and the target
    centre's (u, v) on it (m from the page's top-left corner, v down). ``cut``: only the face,
    as cut on its crop marks. Paper reflects 0.85, toner 0.04 (a laser print's black)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from agvsim.deploy.printing import PrintTarget, draw_page, plan_pages

    page = plan_pages([PrintTarget("T1", target, polarity)], "a3")[0]
    fig = draw_page(page)
    FigureCanvasAgg(fig)
    fig.set_dpi(25.4 * PAGE_PX_PER_MM)
    fig.canvas.draw()
    grey = np.asarray(fig.canvas.buffer_rgba())[..., :3].mean(axis=2) / 255.0
    w_mm, h_mm = page.size
    placement = page.placements[0]
    ow, oh = placement.piece.target.outer_mm
    cx_mm, cy_mm = placement.face_x + ow / 2, h_mm - (placement.y + oh / 2)  # from the top-left, y down
    if cut:
        px = grey.shape[1] / w_mm
        x0, x1 = int(round((cx_mm - ow / 2) * px)), int(round((cx_mm + ow / 2) * px))
        y0, y1 = int(round((cy_mm - oh / 2) * px)), int(round((cy_mm + oh / 2) * px))
        grey = grey[y0:y1, x0:x1]
        w_mm, h_mm, cx_mm, cy_mm = (x1 - x0) / px, (y1 - y0) / px, cx_mm - x0 / px, cy_mm - y0 / px
    reflect = (0.04 + 0.81 * grey).astype(np.float32)
    return np.repeat(reflect[..., None], 3, axis=2), (w_mm / 1000.0, h_mm / 1000.0), (cx_mm / 1000.0, cy_mm / 1000.0)


def wall_texture(scene: PbrScene) -> np.ndarray:
    """The wall's RGB reflectance, ``(H, W, 3)`` float32 over ``2 * WALL_HALF`` m (row 0 at the
    top, v = -WALL_HALF[1] relative to the target centre): the paint with smooth stains, a dark
    band, posters and signs (dark and light rectangles, some with stripes of text)."""
    import cv2

    rng = np.random.default_rng(scene.wall_seed)
    w, h = (int(2 * s * WALL_PX_PER_M) for s in WALL_HALF)
    base = np.ones((h, w, 3), np.float32) * np.asarray(scene.paint, np.float32)
    stains = cv2.resize(rng.normal(0.0, 1.0, (h // 40, w // 40)).astype(np.float32), (w, h),
                        interpolation=cv2.INTER_CUBIC)
    grain = rng.normal(0.0, 1.0, (h, w)).astype(np.float32)
    base *= (1.0 + 0.06 * stains + 0.02 * grain)[..., None]
    v = (np.arange(h) + 0.5) / WALL_PX_PER_M - WALL_HALF[1]
    band = (v >= scene.band[0]) & (v < scene.band[1])
    base[band] = scene.band[2] * (1.0 + 0.05 * grain[band])[..., None]
    for _ in range(int(rng.integers(6, 16))):
        cw, ch = rng.uniform(0.2, 1.2), rng.uniform(0.2, 1.0)
        u0, v0 = rng.uniform(-WALL_HALF[0], WALL_HALF[0] - cw), rng.uniform(-2.5, 2.5)
        near = abs(u0 + cw / 2) < 0.6 + cw / 2 and abs(v0 + ch / 2) < 0.4 + ch / 2
        if near and scene.has_target:
            continue  # posters hang apart from the target (the sheet would hide or overlap them)
        x0, x1 = (int((x + WALL_HALF[0]) * WALL_PX_PER_M) for x in (u0, u0 + cw))
        y0, y1 = (int((y + WALL_HALF[1]) * WALL_PX_PER_M) for y in (v0, v0 + ch))
        base[y0:y1, x0:x1] = rng.uniform(0.03, 0.9, 3).astype(np.float32)
        if rng.random() < 0.6:  # lines of text
            for yy in range(y0 + 6, y1 - 6, int(rng.integers(8, 16))):
                base[yy:yy + 4, x0 + 4:x1 - 4:3] = rng.uniform(0.03, 0.9)
    return np.clip(base, 0.01, 0.95)
