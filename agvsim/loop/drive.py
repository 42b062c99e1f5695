"""One seed of a drift evaluation: the settings of a drive and the drive itself.

:class:`DriveSettings` says everything that makes two drives the same drive (map, route,
distance, odometry, camera, observation source, what is changed in the map); :func:`drive_seed`
drives it for one seed in closed loop (pure pursuit on the EKF's estimate, the camera at its
own rate, each frame rendered, localized and fused) and returns the run's log. ``agvsim drift``
runs it for each seed, ``agvsim sweep`` for each point and seed of a study: the same code.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from localizer.numeric import check_choice, check_number

__all__ = ["DriveSettings", "drive_seed"]

#: the largest lighting scale a drive accepts (16x the map's levels: far into saturation)
MAX_LIGHTING_SCALE = 16.0


@dataclass(frozen=True)
class DriveSettings:
    """A drive of a drift evaluation, all but the seed.

    Attributes:
        map: map name or YAML path.
        route: route name.
        distance: metres of route to drive (m).
        odometry: odometry error preset (:data:`agvsim.vehicle.encoders.PRESETS`).
        camera_rate: camera frames per second (Hz).
        latency: capture-to-fusion delay (s).
        vision: False: dead reckoning through the filter only (the contrast run).
        observations: observation source (:data:`agvsim.sensors.registry.SOURCES`).
        backend: renderer of rendered frames (``raycast`` or ``pyrender``).
        drop_targets: remove every N-th target of the map (0: none).
        targets_removed: share of the map's targets removed, spread evenly over its list
            (``0 <= share < 1``; :meth:`world`), applied after ``drop_targets``.
        false_rate: geometric source only: mean false detections per frame.
        camera_mount: a :class:`localizer.model.mount.CameraMount`; None: the map's.
        lens: the thesis camera's focal length (mm; one of :data:`agvsim.sensors.vision.LENSES_MM`).
        lighting: scale of the map's illumination levels (1: the map's own; 0.5: half as bright).
    """

    map: str = "plant_floor"
    route: str = "default"
    distance: float = 1000.0  # m
    odometry: str = "typical"
    camera_rate: float = 4.0  # Hz
    latency: float = 0.25  # s
    vision: bool = True
    observations: str = "rendered"
    backend: str = "raycast"
    drop_targets: int = 0
    targets_removed: float = 0.0  # share, 0 <= s < 1
    false_rate: float = 0.0  # per frame
    camera_mount: object = None  # CameraMount | None
    lens: float = 16.0  # mm
    lighting: float = 1.0  # scale

    def __post_init__(self) -> None:
        from agvsim.sensors.registry import SOURCES
        from agvsim.sensors.vision import LENSES_MM
        from agvsim.vehicle.encoders import PRESETS

        check_number("distance", self.distance, low=0.0, low_open=True, unit="m")
        check_choice("odometry", self.odometry, PRESETS)
        check_number("camera_rate", self.camera_rate, low=0.0, low_open=True, unit="Hz")
        check_number("latency", self.latency, low=0.0, unit="s")
        check_choice("observations", self.observations, SOURCES)
        if self.drop_targets == 1 or self.drop_targets < 0:
            raise ValueError(f"drop_targets must be 0 (none) or >= 2, got {self.drop_targets}")
        check_number("targets_removed", self.targets_removed, low=0.0, high=1.0, high_open=True)
        check_number("false_rate", self.false_rate, low=0.0)
        if self.false_rate and self.observations != "geometric":
            raise ValueError("false_rate applies to the geometric observation source only")
        if check_number("lens", self.lens, unit="mm") not in LENSES_MM:
            raise ValueError(f"lens must be one of {', '.join(f'{v:g}' for v in LENSES_MM)} (mm), got {self.lens!r}")
        check_number("lighting", self.lighting, low=0.0, high=MAX_LIGHTING_SCALE, low_open=True)

    def world(self):
        """The map as this drive sees it: loaded, ``drop_targets`` and ``targets_removed``
        applied (``round(share x n)`` targets removed, the ``k``-th at index
        ``floor((k + 1/2) n / m)``: spread evenly, the same ones every time), lighting scaled."""
        from agvsim.world import load_map

        world_map = load_map(self.map)
        if self.drop_targets:
            world_map = world_map.without_targets(self.drop_targets)
        n = len(world_map.targets)
        m = int(round(self.targets_removed * n))
        if m:
            gone = {math.floor((k + 0.5) * n / m) for k in range(m)}
            world_map = replace(world_map, targets=tuple(t for i, t in enumerate(world_map.targets) if i not in gone))
        if self.lighting != 1.0:
            world_map = world_map.with_lighting_scaled(self.lighting)
        return world_map


def drive_seed(settings: DriveSettings, seed: int, progress: Callable[[float], None] | None = None,
               world_map=None, observer: Callable | None = None):
    """Drive ``settings`` with ``seed`` (every random draw from ``numpy.random.default_rng(seed)``).

    Args:
        settings: the drive.
        seed: the run's seed.
        progress: called with the metres driven so far, now and then (None: not called).
        world_map: ``settings.world()`` when the caller has built it already.
        observer: passed to :func:`~agvsim.loop.mission.run_mission` (called after each step).
    Returns:
        The run's :class:`~agvsim.loop.log.MissionLog`.
    """
    from agvsim.loop.mission import MissionConfig, run_mission
    from agvsim.sensors import GeometricNoise, VisionConfig, make_source
    from agvsim.vehicle.simulation import SimConfig

    world_map = settings.world() if world_map is None else world_map
    config = MissionConfig(route=settings.route, distance=settings.distance, camera_rate=settings.camera_rate,
                           latency=settings.latency, vision=settings.vision,
                           sim=SimConfig(odometry=settings.odometry),
                           vision_config=VisionConfig(mount=settings.camera_mount,
                                                      focal_mm=float(settings.lens)).for_map(world_map))
    source = None
    if config.vision:
        kw = {}
        if settings.observations == "geometric":
            kw["noise"] = GeometricNoise(false_rate=settings.false_rate)
        if settings.observations == "rendered":
            kw["backend"] = settings.backend
        source = make_source(settings.observations, world_map, config.vision_config, **kw)
    return run_mission(world_map, source, np.random.default_rng(seed), config, progress, observer)
