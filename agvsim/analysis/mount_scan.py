"""Which camera mount sees the map's targets best along a route: a visibility scan.

For each candidate :class:`~localizer.model.mount.CameraMount` the route is sampled
every ``step`` metres at the path's heading, and at each sample the targets the
camera can see are counted with the same visibility test the ``geometric`` and
``synthetic`` sources use (:func:`agvsim.sensors.vision.visible_targets`: whole
target in the image, bars wide and tall enough, range and incidence limits, no
wall or obstacle in the line of sight). What matters to the filter is how long
it drives blind, so mounts are ranked by the longest stretch of route without
a target in view, then by the share of the route with one.

This is how each shipped map's recommended ``camera_mount`` was chosen
(``agvsim map mounts MAP``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Iterable

import numpy as np

from agvsim.loop.pure_pursuit import RoutePath
from agvsim.sensors.vision import VisionConfig, targets_from_map, visible_targets
from localizer.model.mount import CameraMount
from localizer.numeric import check_number

__all__ = ["MountCoverage", "candidate_mounts", "scan_mounts"]


@dataclass(frozen=True)
class MountCoverage:
    """How one mount sees the targets along a route.

    Attributes:
        mount: the mount scanned.
        coverage: share of the route samples with at least one target in view (0..1).
        longest_gap: longest stretch of route with no target in view (m).
        gaps: stretches of route with no target in view, at least ``2 * step`` long.
        mean_in_view: mean number of targets in view per sample.
        targets_seen: distinct targets seen anywhere along the route.
    """

    mount: CameraMount
    coverage: float
    longest_gap: float  # m
    gaps: int
    mean_in_view: float
    targets_seen: int

    def to_dict(self) -> dict:
        m = self.mount
        return {"mount": {"forward": m.forward, "lateral": m.lateral, "height": m.height, "yaw": m.yaw},
                "coverage": self.coverage, "longest_gap_m": self.longest_gap, "gaps": self.gaps,
                "mean_in_view": self.mean_in_view, "targets_seen": self.targets_seen}


def candidate_mounts(yaws: Iterable[float], laterals: Iterable[float] = (0.0,), forward: float = 0.4,
                     height: float = 1.2) -> list[CameraMount]:
    """Every combination of ``yaws`` (rad) and ``laterals`` (m) at one forward offset and height (m)."""
    return [CameraMount(forward=forward, lateral=float(lat), height=height, yaw=float(yaw))
            for lat in laterals for yaw in yaws]


def _samples(path: RoutePath, step: float) -> list[tuple[float, float, float]]:
    n = max(int(path.length / step), 1)
    out = []
    for k in range(n):
        s = k * step
        p0, p1 = path.point_at(s), path.point_at(min(s + 0.1, path.length))
        if s + 0.1 > path.length:  # heading of the last piece
            p0, p1 = path.point_at(max(s - 0.1, 0.0)), path.point_at(s)
        out.append((float(p0[0]), float(p0[1]), math.atan2(float(p1[1] - p0[1]), float(p1[0] - p0[0]))))
    return out


def scan_mounts(world_map, mounts: Iterable[CameraMount], route: str = "default", step: float = 0.25,
                vision: VisionConfig = VisionConfig()) -> list[MountCoverage]:
    """The coverage of each mount along ``route``, best first (shortest longest gap, then most coverage).

    Args:
        world_map: the map.
        mounts: the candidates.
        route: route name.
        step: sample spacing along the route (m).
        vision: lens and trusted range (its ``mount`` is replaced by each candidate).
    """
    step = check_number("scan_mounts step", step, low=0.0, low_open=True, unit="m")
    poses = _samples(RoutePath.from_route(world_map, route), step)
    targets = targets_from_map(world_map)
    results = []
    for mount in mounts:
        v = replace(vision, mount=mount)
        counts, seen = [], set()
        for pose in poses:
            vis = visible_targets(world_map, v, pose, targets)
            counts.append(len(vis))
            seen.update(i for i, _ in vis)
        blind = np.asarray(counts) == 0
        runs, run = [], 0
        for b in blind:
            if b:
                run += 1
            elif run:
                runs.append(run)
                run = 0
        if run:
            runs.append(run)
        results.append(MountCoverage(mount, float(1.0 - blind.mean()), max(runs, default=0) * step,
                                     sum(r >= 2 for r in runs), float(np.mean(counts)), len(seen)))
    results.sort(key=lambda r: (r.longest_gap, -r.coverage))
    return results
