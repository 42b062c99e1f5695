"""The filter's position uncertainty along a route, predicted without rendering a frame.

The route is driven once without a camera (the follower on the true pose: the path the
vehicle really takes, corners cut) and sampled at the camera's frames (:class:`RouteModel`);
the odometry between frames accumulated as the filter does
(:class:`localizer.filter.motion.OdometryAccumulator`, the noise model of
:func:`agvsim.loop.closed_loop.odometry_noise_for`), and at each frame an EKF update for
every target the camera sees there (the same visibility test as the ``geometric`` source:
:func:`agvsim.sensors.vision.visible_targets`), with the measurement Jacobian of the filter
(:func:`localizer.filter.measurement.measurement_jacobian`) and the localizer's covariance
model (:class:`agvsim.sensors.geometric.GeometricNoise`, plus the filter's
``measurement_floor`` and the loop's inflation of frames taken while turning,
``LoopConfig.turn_blur_noise``). The covariance does not depend on what is measured, only on where:
so it can be predicted for thousands of placements at once (:func:`propagate`: a batch of
covariances, one per placement tried, in the Joseph form of filterpy's update).

Shapes: ``N`` frames along one lap, ``C`` placements tried at once; covariances ``(..., 3, 3)``
over (x m, y m, θ rad).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from agvsim.loop.closed_loop import LoopConfig, filter_config_for, odometry_noise_for
from agvsim.loop.pure_pursuit import RoutePath
from agvsim.sensors.geometric import GeometricNoise
from agvsim.sensors.vision import VisionConfig, targets_from_map, visible_targets
from agvsim.vehicle.simulation import SimConfig
from localizer.filter.measurement import measurement_jacobian
from localizer.filter.motion import OdometryAccumulator, compose_jacobians
from localizer.numeric import wrap_angle

__all__ = ["RouteModel", "Sightings", "joseph", "position_sigmas", "propagate", "steady_start"]

#: odometry increments per frame interval (the filter accumulates one per control step)
SUBSTEPS = 8


@dataclass(frozen=True)
class Sightings:
    """Which targets the camera sees at each frame of the lap, and what each sighting tells.

    Attributes:
        frame: ``(K,)`` frame index of each sighting, ascending.
        target: ``(K,)`` index of the target seen (into the list given to :meth:`RouteModel.sightings`).
        H: ``(K, 3, 3)`` measurement Jacobians. R: ``(K, 3, 3)`` measurement covariances.
        distance: ``(K,)`` m.
    """

    frame: np.ndarray
    target: np.ndarray
    H: np.ndarray
    R: np.ndarray
    distance: np.ndarray

    def of(self, targets) -> "Sightings":
        """The sightings of the targets with these indices only."""
        keep = np.isin(self.target, np.asarray(list(targets), dtype=int))
        return Sightings(self.frame[keep], self.target[keep], self.H[keep], self.R[keep], self.distance[keep])


class RouteModel:
    """One lap of ``route`` on paper (module docstring).

    Args:
        world_map: the map (walls and obstacles occlude). route: route name.
        odometry: odometry preset. vision: the camera (its mount: the map's if None).
        camera_rate: frames per second (Hz).
    """

    def __init__(self, world_map, route: str = "default", odometry: str = "typical",
                 vision: VisionConfig | None = None, camera_rate: float = 4.0) -> None:
        self.map = world_map
        self.route = route
        self.vision = (vision or VisionConfig()).for_map(world_map)
        self.path = RoutePath.from_route(world_map, route)
        self.poses, self.s = _driven_lap(world_map, route, camera_rate)  # (N, 3), (N,)
        n = len(self.poses)
        self.step = float(self.s[-1] + np.hypot(*(self.poses[0, :2] - self.poses[-1, :2]))) / n  # m per frame, mean
        sim = SimConfig(odometry=odometry)
        self.filter_config = filter_config_for(sim, self.vision)
        noise = odometry_noise_for(sim)
        self.noise_model = GeometricNoise()
        floor = np.asarray(self.filter_config.measurement_floor)
        self._floor = np.diag(floor ** 2)
        F = np.empty((n, 3, 3))
        GQG = np.empty((n, 3, 3))
        acc = OdometryAccumulator(noise)
        nxt = np.roll(self.poses, -1, axis=0)
        if not self.path.loop:
            nxt[-1] = self.poses[-1]
        for i in range(n):  # the motion from frame i-1 to frame i, predicted at frame i-1's pose
            a, b = self.poses[i - 1], self.poses[i]
            ds = float(np.hypot(*(b[:2] - a[:2]))) if (i > 0 or self.path.loop) else 0.0
            dth = float(wrap_angle(b[2] - a[2])) if (i > 0 or self.path.loop) else 0.0
            acc.reset()
            for _ in range(SUBSTEPS):
                acc.add(ds / SUBSTEPS, dth / SUBSTEPS)
            Fi, Gi = compose_jacobians(a, acc.u)
            F[i], GQG[i] = Fi, Gi @ acc.Q @ Gi.T
        self.F, self.GQG = F, GQG
        self.turn_blur_noise = LoopConfig().turn_blur_noise
        # yaw rate at each frame (rad/s), central differences of the driven lap's headings
        ahead, behind = np.roll(self.poses[:, 2], -1), np.roll(self.poses[:, 2], 1)
        self.yaw_rate = wrap_angle(ahead - behind) * (0.5 * camera_rate)

    @property
    def frames(self) -> int:
        return len(self.poses)

    def sightings(self, targets) -> Sightings:
        """Every (frame, target) where the camera sees one of ``targets`` (``MapTarget`` list)."""
        from dataclasses import replace

        m = replace(self.map, targets=tuple(targets))
        tm = targets_from_map(m)
        mount = self.vision.mount
        k_d, k_b, k_a = self.turn_blur_noise
        rows = []
        for i, pose in enumerate(self.poses):
            w = abs(float(self.yaw_rate[i]))
            for k, tp in visible_targets(m, self.vision, pose, tm):
                t = targets[k]
                H = measurement_jacobian(pose, t.position, t.yaw, mount)
                # the localizer's covariance, the filter's floor and the loop's inflation of a
                # frame taken while turning (LoopConfig.turn_blur_noise: with_turn_blur)
                blur = np.array([k_d * w * tp.distance, k_b * w, k_a * w])
                R = self.noise_model.covariance(tp.distance) + self._floor + np.diag(blur ** 2)
                rows.append((i, k, H, R, tp.distance))
        if not rows:
            e = np.zeros((0, 3, 3))
            return Sightings(np.zeros(0, int), np.zeros(0, int), e, e, np.zeros(0))
        i, k, H, R, d = zip(*rows)
        return Sightings(np.array(i), np.array(k), np.array(H), np.array(R), np.array(d))


def _driven_lap(world_map, route: str, camera_rate: float) -> tuple[np.ndarray, np.ndarray]:
    """The vehicle's poses at the camera's frames over one lap of ``route`` (the follower on the
    true pose, ideal odometry, no camera: the path it really drives, corners cut and slowed in
    curves), and the distance driven to each (m)."""
    from agvsim.loop.mission import MissionConfig, run_mission

    config = MissionConfig(route=route, laps=1.0, vision=False, steer_on="truth", sim=SimConfig(odometry="ideal"))
    log = run_mission(world_map, None, np.random.default_rng(0), config)
    t = np.arange(0.0, float(log.time[-1]), 1.0 / camera_rate)
    heading = np.unwrap(log.true_pose[:, 2])
    poses = np.column_stack([np.interp(t, log.time, log.true_pose[:, 0]), np.interp(t, log.time, log.true_pose[:, 1]),
                             wrap_angle(np.interp(t, log.time, heading))])
    return poses, np.interp(t, log.time, log.distance)


def joseph(P: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The EKF covariance update in Joseph form (filterpy's), batched:
    ``K = P Hᵀ S⁻¹``, ``S = H P Hᵀ + R``, ``P ← (I - K H) P (I - K H)ᵀ + K R Kᵀ``.
    ``P`` ``(..., 3, 3)``; ``H``, ``R`` ``(3, 3)`` or ``(..., 3, 3)``."""
    Ht = np.swapaxes(H, -1, -2)
    PHt = P @ Ht
    S = H @ PHt + R
    K = np.swapaxes(np.linalg.solve(S, np.swapaxes(PHt, -1, -2)), -1, -2)  # P Hᵀ S⁻¹ (S symmetric)
    A = np.eye(3) - K @ H
    return A @ P @ np.swapaxes(A, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)


def position_sigmas(P: np.ndarray) -> np.ndarray:
    """The largest position standard deviation (m) of each covariance ``(..., 3, 3)``."""
    a, b, d = P[..., 0, 0], P[..., 1, 0], P[..., 1, 1]
    return np.sqrt(np.maximum(0.5 * (a + d) + np.hypot(0.5 * (a - d), b), 0.0))


def propagate(model: RouteModel, P0: np.ndarray, common: Sightings, each: Sightings | None = None,
              batch_of: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One lap of covariances, a batch at once.

    Args:
        model: the lap. P0: ``(C, 3, 3)`` covariances at the lap's start.
        common: sightings fused into every member of the batch (the targets already placed).
        each: sightings fused into one member only: ``batch_of[each.target]`` is its member
            (a candidate placement tried on top of the common ones).
    Returns:
        ``(P_end (C, 3, 3), sigma (C, N))``: the covariances after the lap and the largest
        position standard deviation (m) after each frame's update.
    """
    P = np.array(P0, dtype=float)
    C, N = P.shape[0], model.frames
    sigma = np.empty((C, N))
    c_starts = np.searchsorted(common.frame, np.arange(N + 1))
    e_starts = np.searchsorted(each.frame, np.arange(N + 1)) if each is not None else None
    for i in range(N):
        P = model.F[i] @ P @ model.F[i].T + model.GQG[i]
        for k in range(c_starts[i], c_starts[i + 1]):
            P = joseph(P, common.H[k], common.R[k])
        if e_starts is not None and e_starts[i + 1] > e_starts[i]:
            sl = slice(e_starts[i], e_starts[i + 1])
            members = batch_of[each.target[sl]]
            # a member seen twice in one frame (two of its targets) takes one sighting per pass:
            # pass r updates every member's r-th sighting of the frame
            order = np.argsort(members, kind="stable")
            members, Hs, Rs = members[order], each.H[sl][order], each.R[sl][order]
            starts = np.r_[0, np.flatnonzero(members[1:] != members[:-1]) + 1]
            rank = np.arange(len(members)) - np.repeat(starts, np.diff(np.r_[starts, len(members)]))
            for r in range(int(rank.max()) + 1):
                pick = rank == r
                P[members[pick]] = joseph(P[members[pick]], Hs[pick], Rs[pick])
        sigma[:, i] = position_sigmas(P)
    return P, sigma


def steady_start(model: RouteModel, common: Sightings, laps: int = 3) -> np.ndarray:
    """``(3, 3)``: the covariance at the lap's start once laps repeat (a loop route), else the
    filter's initial covariance."""
    P = np.diag(np.asarray(LoopConfig().initial_sigma, dtype=float) ** 2)[None]
    if not model.path.loop:
        return P[0]
    for _ in range(laps):
        P, _ = propagate(model, P, common)
    return P[0]
