r"""Observation sources for the closed loop: what the camera reports at a frame.

Every source has ``observe(true_pose, rng) -> list`` of observations with
``distance`` (m), ``beta``, ``alpha`` (rad, thesis conventions), ``covariance``
(3 x 3 over (d, β, α)) and ``polarity``, like :class:`localizer.TargetObservation`.
Sources see the *true* pose (the camera is where the vehicle really is); the
filter never does.

* :class:`RenderedSource` (``"rendered"``): the issue-4 renderer
  (:mod:`agvsim.render`) draws the frame at the true pose and
  :func:`localizer.detect_targets` finds the targets. The real thing.
* :class:`SyntheticFrameSource` (``"synthetic"``): the frame is drawn by
  :mod:`localizer.synthetic` (exact perspective warp of each visible target on a
  plain background, the map's lighting level, blur and sensor noise) and
  :func:`localizer.detect_targets` finds the targets. Real detector, no scene.
* :class:`GeometricSource` (``"geometric"``): the true (d, β, α) of each visible
  target plus Gaussian noise from a covariance model fitted to the localizer's
  reported covariance (16 mm lens), optional missed and false detections.
  Fast; for tests and quick studies.

Visibility (geometric and synthetic sources): the whole printed target inside
the image with bars at least 5 px wide and 16 rows tall
(:func:`localizer.synthetic.in_envelope`), range and incidence limits, and no
wall or obstacle crossing the 2-D line of sight (:meth:`Solids.blocker`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from localizer.camera import Camera
from localizer.filter import CameraMount2D, TargetMap, ViewLimits, predict_all
from localizer.geometry import TargetPose

__all__ = [
    "DEFAULT_MOUNT", "GeometricNoise", "GeometricSource", "RenderedSource", "SOURCES", "SimObservation",
    "SyntheticFrameSource", "VisionConfig", "drop_targets", "make_source", "mount_2d", "targets_from_map",
    "visible_targets",
]

SOURCES: tuple[str, ...] = ("rendered", "synthetic", "geometric")


def _default_mount():
    from agvsim.render.mount import CameraMount

    # right-forward looking (45° right of the heading): plant_floor's targets hang on the right of the
    # direction of travel. Chosen by a visibility scan along its default route over yaw -20..-70°:
    # a target in view on 34 % of the route, the fewest and shortest gaps (longest 14.8 m).
    return CameraMount(forward=0.4, lateral=0.0, height=1.2, yaw=-math.radians(45.0))


DEFAULT_MOUNT = _default_mount()


def mount_2d(mount) -> CameraMount2D:
    """The renderer's :class:`~agvsim.render.mount.CameraMount` as the filter's plain 2-D mount."""
    return CameraMount2D(float(mount.forward), float(mount.lateral), float(mount.yaw))


def targets_from_map(world_map) -> TargetMap:
    """The map's targets as the filter's plain data (ids, face centres, facing yaws, polarities)."""
    ts = world_map.targets
    return TargetMap(tuple(t.id for t in ts), np.array([t.position for t in ts]).reshape(-1, 2),
                     np.array([t.yaw for t in ts]), tuple(t.polarity for t in ts))


def drop_targets(world_map, every: int, offset: int = 0):
    """A copy of the map without every ``every``-th target (indices ``offset, offset + every, ...``)."""
    if every < 2:
        raise ValueError(f"drop_targets: every must be >= 2, got {every!r}")
    keep = tuple(t for i, t in enumerate(world_map.targets) if (i - offset) % every != 0)
    return replace(world_map, targets=keep)


@dataclass(frozen=True)
class VisionConfig:
    """The camera on the vehicle.

    Attributes:
        mount: the renderer's ``CameraMount`` (lens offset, height, yaw).
        focal_mm: lens focal length (mm) of the thesis camera (16 or 50).
        max_range: farthest target the localizer is trusted with (m).
        max_incidence: largest |γ| = |α - β| at which targets are reported (rad).
        detector: ``localizer.detect_targets`` method.
    """

    mount: object = DEFAULT_MOUNT
    focal_mm: float = 16.0  # mm
    max_range: float = 10.0  # m
    max_incidence: float = math.radians(70.0)  # rad
    detector: str = "exact"

    @property
    def camera(self) -> Camera:
        return Camera.thesis(self.focal_mm)

    @property
    def mount2d(self) -> CameraMount2D:
        return mount_2d(self.mount)

    def view_limits(self) -> ViewLimits:
        """The filter's prediction of which targets are in view (horizontal FOV of the lens)."""
        cam = self.camera
        half = math.atan(0.5 * cam.width / cam.fx)
        return ViewLimits(half_fov=half, min_range=0.3, max_range=self.max_range + 1.0,
                          max_incidence=min(self.max_incidence + math.radians(5.0), math.pi / 2))


@dataclass(frozen=True)
class SimObservation:
    """An observation from a simulated source (same fields the filter reads from a TargetObservation).

    ``truth_id``: the map target really seen (None for a false detection); for evaluation only.
    """

    distance: float  # m
    beta: float  # rad
    alpha: float  # rad
    covariance: np.ndarray  # (3, 3) m², rad²
    polarity: str
    truth_id: str | None = None


def visible_targets(world_map, vision: VisionConfig, true_pose) -> list[tuple[int, TargetPose]]:
    """(index into ``world_map.targets``, true camera-frame pose) of every target the camera can see."""
    tm = targets_from_map(world_map)
    if len(tm) == 0:
        return []
    mount = vision.mount
    cam = vision.camera
    limits = ViewLimits(half_fov=math.atan(0.5 * cam.width / cam.fx), min_range=0.3,
                        max_range=vision.max_range, max_incidence=vision.max_incidence, margin=0.0)
    Z, ok = predict_all(np.asarray(true_pose, dtype=float), tm, vision.mount2d, limits)
    if not ok.any():
        return []
    from localizer.synthetic import in_envelope

    lens, _ = mount.camera_pose(true_pose)
    out = []
    for i in np.nonzero(ok)[0]:
        t = world_map.targets[i]
        pose = TargetPose(float(Z[i, 0]), float(Z[i, 1]), float(Z[i, 2]), float(mount.height - t.height))
        if not in_envelope(cam, pose, t.spec):
            continue
        if world_map.solids.blocker(lens[:2], t.position) is not None:
            continue
        out.append((int(i), pose))
    return out


@dataclass(frozen=True)
class GeometricNoise:
    """Covariance model of (d, β, α) fitted to the localizer's reported covariance
    (``exact``, 16 mm lens, blur 0.7 px, noise 2 grey levels, 2-8 m, |γ| <= 60°)::

        σ_d = d_coef d²,  σ_β = beta_sigma,  σ_α = alpha_coef d²

    Attributes:
        d_coef: (1/m).
        beta_sigma: (rad).
        alpha_coef: (rad/m²).
        floor: (σ_d m, σ_β rad, σ_α rad) lower bounds.
        error_scale: drawn error σ over reported σ (1 = the report is exact; the
            localizer's real errors were 0.3-0.6 of its report on synthetic frames).
        detection_probability: chance a visible target is reported.
        false_rate: mean number of false detections per frame (Poisson).
    """

    d_coef: float = 2.6e-4  # 1/m
    beta_sigma: float = 2e-5  # rad
    alpha_coef: float = 3.0e-4  # rad/m²
    floor: tuple[float, float, float] = (0.0005, 1e-5, 0.0005)  # m, rad, rad
    error_scale: float = 1.0
    detection_probability: float = 1.0
    false_rate: float = 0.0  # per frame

    def __post_init__(self) -> None:
        for name in ("d_coef", "beta_sigma", "alpha_coef", "error_scale", "false_rate"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"GeometricNoise.{name} must be finite and >= 0, got {v!r}")
        if not (0.0 <= self.detection_probability <= 1.0):
            raise ValueError(f"GeometricNoise.detection_probability must be in [0, 1], got {self.detection_probability!r}")

    def covariance(self, d: float) -> np.ndarray:
        """(3, 3) diagonal covariance at distance ``d`` (m)."""
        s = np.maximum([self.d_coef * d * d, self.beta_sigma, self.alpha_coef * d * d], self.floor)
        return np.diag(s ** 2)


class GeometricSource:
    """True (d, β, α) of the visible targets plus noise (module docstring).

    Args:
        world_map: the map (targets, walls for occlusion).
        vision: the camera.
        noise: the covariance / error model.
    """

    name = "geometric"

    def __init__(self, world_map, vision: VisionConfig = VisionConfig(),
                 noise: GeometricNoise = GeometricNoise()) -> None:
        self.map = world_map
        self.vision = vision
        self.noise = noise

    def observe(self, true_pose, rng: np.random.Generator) -> list[SimObservation]:
        out = []
        nz = self.noise
        for i, pose in visible_targets(self.map, self.vision, true_pose):
            if nz.detection_probability < 1.0 and rng.random() >= nz.detection_probability:
                continue
            C = nz.covariance(pose.distance)
            e = rng.standard_normal(3) * np.sqrt(np.diag(C)) * nz.error_scale
            t = self.map.targets[i]
            out.append(SimObservation(pose.distance + e[0], pose.beta + e[1], pose.alpha + e[2], C,
                                      t.polarity, t.id))
        n_false = int(rng.poisson(nz.false_rate)) if nz.false_rate > 0 else 0
        half = self.vision.view_limits().half_fov
        for _ in range(n_false):
            d = float(rng.uniform(1.0, self.vision.max_range))
            beta = float(rng.uniform(-half, half))
            alpha = beta + float(rng.uniform(-1.0, 1.0))
            out.append(SimObservation(d, beta, alpha, nz.covariance(d),
                                      "positive" if rng.random() < 0.5 else "negative", None))
        return out


def _match_truth(obs, visible, world_map) -> str | None:
    """Id of the visible target nearest in bearing to ``obs`` (within 0.02 rad and 10 % in d), else None."""
    best, best_id = 0.02, None
    for i, pose in visible:
        db = abs(obs.beta - pose.beta)
        if db < best and abs(obs.distance - pose.distance) < 0.1 * pose.distance:
            best, best_id = db, world_map.targets[i].id
    return best_id


class SyntheticFrameSource:
    """Frames drawn by :mod:`localizer.synthetic`, targets found by :func:`localizer.detect_targets`.

    Args:
        world_map, vision: as for :class:`GeometricSource`.
        blur: optical blur σ (px).
        noise: sensor noise σ (grey levels).
        gain, flare: exposure at lighting level 1 (grey levels per reflectance, grey levels);
            scaled by the map's lighting level at the lens (dim corners, sunlit doors saturate).
    """

    name = "synthetic"

    def __init__(self, world_map, vision: VisionConfig = VisionConfig(), blur: float = 0.7,
                 noise: float = 2.0, gain: float = 235.0, flare: float = 5.0) -> None:
        self.map = world_map
        self.vision = vision
        self.blur = blur
        self.noise = noise
        self.gain = gain
        self.flare = flare
        self.camera = vision.camera
        self.last_frame: np.ndarray | None = None

    def observe(self, true_pose, rng: np.random.Generator) -> list[SimObservation]:
        from localizer import detect_targets
        from localizer.synthetic import Lighting, render_frame

        visible = visible_targets(self.map, self.vision, true_pose)
        lens, _ = self.vision.mount.camera_pose(true_pose)
        level = self.map.lighting_at(float(lens[0]), float(lens[1]))
        light = Lighting(gain=self.gain * level, flare=self.flare * level)
        poses = [p for _, p in visible]
        if poses:
            specs = {self.map.targets[i].spec for i, _ in visible}
            if len(specs) > 1:
                raise ValueError("SyntheticFrameSource: all targets must share one TargetSpec")
            spec = specs.pop()
            pols = [self.map.targets[i].polarity for i, _ in visible]
        else:
            spec, pols = self.map.targets[0].spec if self.map.targets else None, []
        from localizer.target import TargetSpec

        frame = render_frame(self.camera, poses, spec or TargetSpec(), pols, light, self.blur, self.noise,
                             background=0.5, rng=rng)
        self.last_frame = frame
        out = []
        for o in detect_targets(frame, self.camera, spec or TargetSpec(), method=self.vision.detector):
            out.append(SimObservation(o.distance, o.beta, o.alpha, np.asarray(o.covariance), o.polarity,
                                      _match_truth(o, visible, self.map)))
        return out


class RenderedSource:
    """Frames from the issue-4 renderer (:class:`agvsim.render.CameraRenderer`), targets from
    :func:`localizer.detect_targets`.

    The renderer (one GL context per process) is created lazily at the first
    frame, so the source can be built before a fork/spawn. Each frame uses the
    map's lighting zones, sensor noise, and motion blur from the vehicle's
    current command (set :attr:`velocity` before :meth:`observe`).

    Args:
        world_map, vision: as for :class:`GeometricSource`.
        conditions: keyword overrides of :class:`agvsim.render.RenderConditions`
            (e.g. ``{"defocus_px": 0.5}``); ``velocity`` is filled in per frame.
    """

    name = "rendered"

    def __init__(self, world_map, vision: VisionConfig = VisionConfig(), conditions: dict | None = None) -> None:
        self.map = world_map
        self.vision = vision
        self.conditions = dict(conditions or {})
        self.camera = vision.camera
        self.velocity = (0.0, 0.0)  # (m/s, rad/s) during the exposure, set by the mission loop
        self._renderer = None
        self.last_frame: np.ndarray | None = None
        self.last_truth = None

    @staticmethod
    def available() -> bool:
        """Whether :mod:`agvsim.render` provides ``CameraRenderer`` (no GL context is opened)."""
        try:
            from agvsim.render import CameraRenderer  # noqa: F401
        except (ImportError, AttributeError):
            return False
        return True

    def _get_renderer(self):
        if self._renderer is None:
            try:
                from agvsim.render import CameraRenderer
            except (ImportError, AttributeError) as exc:
                raise ValueError("the 'rendered' observation source needs the camera renderer "
                                 "(agvsim.render.CameraRenderer, issue 4), which is not available here "
                                 f"({exc}); use --observations synthetic or geometric") from None
            self._renderer = CameraRenderer(self.map, camera=self.camera, mount=self.vision.mount)
        return self._renderer

    def observe(self, true_pose, rng: np.random.Generator) -> list[SimObservation]:
        from agvsim.render import RenderConditions
        from localizer import detect_targets
        from localizer.target import TargetSpec

        renderer = self._get_renderer()
        cond = RenderConditions(**{**self.conditions, "velocity": tuple(self.velocity)})
        image, truth = renderer.render(tuple(float(v) for v in true_pose), cond, rng)
        self.last_frame = image
        self.last_truth = truth
        # candidates for labelling detections with the target really seen (evaluation only): the
        # renderer's visible targets, plus facing, unoccluded ones whose printed margin is cut by
        # the image border (the localizer still finds their bars there)
        half = self.vision.view_limits().half_fov + 0.05
        visible = []
        for i, t in enumerate(truth.targets):
            partly = (t.facing and t.occluded_fraction < 0.5 and math.isfinite(t.distance) and t.distance > 0
                      and abs(t.beta) <= half)
            if t.visible or partly:
                visible.append((i, TargetPose(t.distance, t.beta, t.alpha, t.height if math.isfinite(t.height) else 0.0)))
        spec = self.map.targets[0].spec if self.map.targets else TargetSpec()
        out = []
        for o in detect_targets(image, self.camera, spec, method=self.vision.detector):
            out.append(SimObservation(o.distance, o.beta, o.alpha, np.asarray(o.covariance), o.polarity,
                                      _match_truth(o, visible, self.map)))
        return out


def make_source(name: str, world_map, vision: VisionConfig = VisionConfig(), **kw):
    """The observation source called ``name`` (one of :data:`SOURCES`)."""
    if name == "geometric":
        return GeometricSource(world_map, vision, **kw)
    if name == "synthetic":
        return SyntheticFrameSource(world_map, vision, **kw)
    if name == "rendered":
        return RenderedSource(world_map, vision, **kw)
    raise ValueError(f"unknown observation source {name!r}; expected one of {', '.join(SOURCES)}")
