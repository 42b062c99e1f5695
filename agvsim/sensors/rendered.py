"""The ``rendered`` source: frames of the scene from the renderer, targets from the localizer.

The renderer backend is the compiled raycaster by default, pyrender on request.

The real thing: :class:`agvsim.sensors.render.CameraRenderer` draws the frame at
the true pose (lighting zones, sensor noise, motion blur) and
:func:`localizer.detect_targets` finds the targets.
"""
from __future__ import annotations

import math
import time
from typing import ClassVar

import numpy as np

from agvsim.sensors.base import SimObservation
from agvsim.sensors.backends import DEFAULT_BACKEND, check_backend
from agvsim.sensors.vision import VisionConfig, match_truth
from localizer.model.geometry import TargetPose
from localizer.numeric import check_number

__all__ = ["RenderedSource"]


class RenderedSource:
    """Frames from the camera renderer (:class:`agvsim.sensors.render.CameraRenderer`), targets from
    :func:`localizer.detect_targets`.

    The renderer (one GL context per process) is created lazily at the first
    frame, so the source can be built before a fork/spawn. Each frame uses the
    map's lighting zones, sensor noise, and motion blur from the vehicle's
    current command (the ``command`` given to :meth:`observe`).

    Args:
        world_map, vision: as for :class:`GeometricSource`.
        conditions: keyword overrides of :class:`agvsim.sensors.render.RenderConditions`
            (e.g. ``{"defocus_px": 0.5}``); ``velocity`` is filled in per frame.
        backend: the renderer backend (:data:`agvsim.sensors.backends.BACKENDS`):
            ``"raycast"`` (default, compiled, no OpenGL) or ``"pyrender"`` (the reference).
    """

    name: ClassVar[str] = "rendered"
    draws_frames: ClassVar[bool] = True
    has_exposure: ClassVar[bool] = True

    def __init__(self, world_map, vision: VisionConfig | None = None, conditions: dict | None = None,
                 backend: str = DEFAULT_BACKEND) -> None:
        self.map = world_map
        self.backend = check_backend(backend)
        self.vision = (vision or VisionConfig()).for_map(world_map)
        self.conditions = dict(conditions or {})
        if "velocity" in self.conditions:
            raise ValueError("RenderedSource conditions: 'velocity' is set per frame from the command; "
                             "do not pass it")
        self.camera = self.vision.camera
        self._renderer = None
        self.last_frame: np.ndarray | None = None
        self.last_truth = None
        #: what the localizer found in :attr:`last_frame` (:class:`localizer.TargetObservation`)
        self.last_detections: tuple = ()
        self.timing = {"render": 0.0, "localize": 0.0}  # wall seconds in renderer.render, detect_targets

    @staticmethod
    def available() -> bool:
        """Whether :mod:`agvsim.sensors.render` provides ``CameraRenderer`` (no GL context is opened)."""
        try:
            from agvsim.sensors.render import CameraRenderer  # noqa: F401
        except (ImportError, AttributeError):
            return False
        return True

    def _get_renderer(self):
        if self._renderer is None:
            try:
                from agvsim.sensors.render import CameraRenderer
            except (ImportError, AttributeError) as exc:
                raise ValueError("the 'rendered' observation source needs the camera renderer "
                                 "(agvsim.sensors.render.CameraRenderer), which is not available here "
                                 f"({exc}); use --observations synthetic or geometric") from None
            self._renderer = CameraRenderer(self.map, camera=self.camera, mount=self.vision.mount,
                                            backend=self.backend)
        return self._renderer

    def set_exposure(self, factor: float) -> None:
        """Render the following frames with ``exposure=factor`` (> 0)."""
        self.conditions = {**self.conditions, "exposure": check_number("exposure", factor, low=0.0, low_open=True)}

    def observe(self, true_pose, rng: np.random.Generator,
                command: tuple[float, float] = (0.0, 0.0)) -> list[SimObservation]:
        from agvsim.sensors.render import RenderConditions
        from localizer import detect_targets
        from localizer.model.target import TargetSpec

        renderer = self._get_renderer()
        cond = RenderConditions(**{**self.conditions, "velocity": (float(command[0]), float(command[1]))})
        t0 = time.perf_counter()
        image, truth = renderer.render(tuple(float(v) for v in true_pose), cond, rng)
        self.timing["render"] += time.perf_counter() - t0
        self.last_frame = image
        self.last_truth = truth
        # candidates for labelling detections with the target really seen (evaluation only): the
        # renderer's visible targets, plus facing, unoccluded ones whose printed margin is cut by
        # the image border (the localizer still finds their bars there)
        half = self.vision.view_limits().half_fov + 0.05
        facing, occ, dist, beta = (truth.column(k) for k in ("facing", "occluded", "d", "beta"))
        candidates = truth.column("visible") | (facing & (occ < 0.5) & np.isfinite(dist) & (dist > 0)
                                                 & (np.abs(beta) <= half))
        alpha, height = truth.column("alpha"), truth.column("height")
        visible = [(i, TargetPose(float(dist[i]), float(beta[i]), float(alpha[i]),
                                  float(height[i]) if math.isfinite(height[i]) else 0.0))
                   for i in candidates.nonzero()[0].tolist()]
        spec = self.map.targets[0].spec if self.map.targets else TargetSpec()
        out = []
        t0 = time.perf_counter()
        detections = detect_targets(image, self.camera, spec, method=self.vision.detector)
        self.timing["localize"] += time.perf_counter() - t0
        self.last_detections = tuple(detections)
        for o in detections:
            out.append(SimObservation(o.distance, o.beta, o.alpha, np.asarray(o.covariance), o.polarity,
                                      match_truth(o, visible, self.map)))
        return out
