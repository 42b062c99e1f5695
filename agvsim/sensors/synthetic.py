"""The ``synthetic`` source: targets warped onto a plain background, found by the localizer.

The frame is drawn by :mod:`localizer.tools.synthetic` (exact perspective warp of each
visible target on a plain background, the map's lighting level, blur and sensor
noise) and :func:`localizer.detect_targets` finds the targets. Real detector, no scene.
"""
from __future__ import annotations

import time
from typing import ClassVar

import numpy as np

from agvsim.sensors.base import SimObservation
from agvsim.sensors.vision import VisionConfig, targets_from_map, match_truth, visible_targets
from localizer.numeric import check_number

__all__ = ["SyntheticFrameSource"]


class SyntheticFrameSource:
    """Frames drawn by :mod:`localizer.tools.synthetic`, targets found by :func:`localizer.detect_targets`.

    Args:
        world_map, vision: as for :class:`GeometricSource`.
        blur: optical blur σ (px).
        noise: sensor noise σ (grey levels).
        gain, flare: exposure at lighting level 1 (grey levels per reflectance, grey levels);
            scaled by the map's lighting level at the lens (dim corners, sunlit doors saturate).
    """

    name: ClassVar[str] = "synthetic"
    draws_frames: ClassVar[bool] = True
    has_exposure: ClassVar[bool] = True

    def __init__(self, world_map, vision: VisionConfig | None = None, blur: float = 0.7,
                 noise: float = 2.0, gain: float = 235.0, flare: float = 5.0) -> None:
        self.map = world_map
        self.vision = (vision or VisionConfig()).for_map(world_map)
        self._targets = targets_from_map(world_map)
        self.exposure = 1.0
        self.blur = blur
        self.noise = noise
        self.gain = gain
        self.flare = flare
        self.camera = self.vision.camera
        self.last_frame: np.ndarray | None = None
        self.timing = {"render": 0.0, "localize": 0.0}  # wall seconds in render_frame, detect_targets

    def set_exposure(self, factor: float) -> None:
        """Scale the gain and flare of the following frames by ``factor`` (> 0)."""
        self.exposure = check_number("exposure", factor, low=0.0, low_open=True)

    def observe(self, true_pose, rng: np.random.Generator,
                command: tuple[float, float] = (0.0, 0.0)) -> list[SimObservation]:
        from localizer import detect_targets
        from localizer.tools.synthetic import Lighting, render_frame

        visible = visible_targets(self.map, self.vision, true_pose, self._targets)
        lens, _ = self.vision.mount.camera_pose(true_pose)
        level = self.map.lighting_at(float(lens[0]), float(lens[1]))
        level *= self.exposure
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
        from localizer.model.target import TargetSpec

        t0 = time.perf_counter()
        frame = render_frame(self.camera, poses, spec or TargetSpec(), pols, light, self.blur, self.noise,
                             background=0.5, rng=rng)
        self.timing["render"] += time.perf_counter() - t0
        self.last_frame = frame
        out = []
        t0 = time.perf_counter()
        detections = detect_targets(frame, self.camera, spec or TargetSpec(), method=self.vision.detector)
        self.timing["localize"] += time.perf_counter() - t0
        for o in detections:
            out.append(SimObservation(o.distance, o.beta, o.alpha, np.asarray(o.covariance), o.polarity,
                                      match_truth(o, visible, self.map)))
        return out
