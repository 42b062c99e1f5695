"""One drive of the vehicle, step by step, with a chosen pose source.

:class:`Episode` is what the Gymnasium adapters in ``envs/`` wrap: it owns
the simulation and the localization and knows nothing of rewards or spaces.
Each :meth:`Episode.step` applies one (v, ω) command for one control step
and returns what the vehicle believes (pose and covariance), what its wheels
measured, and what happened (contacts); ground truth is kept apart.

Localization modes:
    ``truth``     the believed pose is the true pose (covariance zero);
    ``odometry``  dead reckoning, with its covariance from the filter's
                  odometry motion model (:class:`localizer.filter.OdometryAccumulator`);
    ``ekf``       dead reckoning corrected by camera observations of the
                  wall targets (the closed loop of :mod:`agvsim.mission`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from agvsim.simulation import SimConfig, Simulation

LOCALIZATION_MODES: tuple[str, ...] = ("ekf", "odometry", "truth")


@dataclass(frozen=True)
class EpisodeStep:
    """What one control step produced.

    Attributes:
        believed_pose: (3,) pose the vehicle believes (x m, y m, θ rad), θ wrapped.
        covariance: (3, 3) covariance of ``believed_pose`` (m², m·rad, rad²).
        wheel_speeds: (2,) measured (left, right) rim speeds over the step (m/s).
        collided: a contact began during the step.
        in_contact: touching a wall or obstacle at the end of the step.
        accepted: target observations fused during the step.
        rejected: target observations refused during the step.
        frame: the camera frame taken during the step, if any ((H, W) uint8).
    """

    believed_pose: np.ndarray
    covariance: np.ndarray
    wheel_speeds: np.ndarray
    collided: bool
    in_contact: bool
    accepted: int = 0
    rejected: int = 0
    frame: np.ndarray | None = None


def wrap_angle(a: float) -> float:
    """Angle wrapped to (-π, π] (rad)."""
    return math.atan2(math.sin(a), math.cos(a))


class Episode:
    """A vehicle on a map, stepped at the control rate.

    Args:
        world_map: the map.
        start_pose: true start pose (x m, y m, θ rad); dead reckoning and the
            filter start from it too (the AGV is told where it starts).
        config: rates, vehicle, odometry error model.
        rng: the episode's generator (odometry noise, camera noise).
        localization: one of :data:`LOCALIZATION_MODES`.
        vision: the camera (:class:`agvsim.observe.VisionConfig`); default mount and 16 mm lens.
        observations: observation source for ``ekf``: ``rendered`` (the
            renderer + localizer), ``synthetic`` or ``geometric`` (see
            :mod:`agvsim.observe`), or a source object to reuse (keep one
            rendered source per process: it owns the GL context).
        camera_rate: frames per second (Hz).
        latency: capture-to-fusion delay (s).
        conditions: keyword overrides of :class:`agvsim.render.RenderConditions`
            for rendered frames (e.g. ``{"exposure": 0.5}``).
        capture_frames: render camera frames even when not localizing with
            them (``observe_image`` with ``truth``/``odometry``).
    """

    def __init__(self, world_map, start_pose, config: SimConfig, rng: np.random.Generator,
                 localization: str = "odometry", vision=None, observations: str = "rendered",
                 camera_rate: float = 4.0, latency: float = 0.25, conditions: dict | None = None,
                 capture_frames: bool = False) -> None:
        if localization not in LOCALIZATION_MODES:
            raise ValueError(f"localization must be one of {LOCALIZATION_MODES}, got {localization!r}")
        from agvsim.mission import filter_config_for, odometry_noise_for
        from localizer.filter import OdometryAccumulator
        from agvsim.observe import VisionConfig, make_source, targets_from_map
        from localizer.filter import PoseEKF

        self.map = world_map
        self.config = config
        self.localization = localization
        sim_rng, cam_rng = rng.spawn(2)
        self.sim = Simulation(world_map, start_pose, config, sim_rng)
        # dead reckoning's covariance: the filter's motion model accumulated from the (known) start
        self._start = np.asarray(start_pose, dtype=float)
        self._odometry_motion = OdometryAccumulator(odometry_noise_for(config))
        vision = vision if vision is not None else VisionConfig()
        self.vision = vision
        source = None
        if localization == "ekf" or capture_frames:
            if isinstance(observations, str):
                kw = {"conditions": conditions} if observations == "rendered" and conditions else {}
                source = make_source(observations, world_map, vision, **kw)
            else:
                source = observations
        self.source = source
        x0 = np.asarray(start_pose, dtype=float)
        P0 = np.diag(np.array([0.01, 0.01, 0.002]) ** 2)
        ekf = PoseEKF(x0, P0, targets_from_map(world_map), vision.mount2d,
                      filter_config_for(config, vision), t0=0.0)
        from agvsim.closed_loop import ClosedLoop

        self.loop = ClosedLoop(self.sim, ekf, source, cam_rng, camera_rate=camera_rate, latency=latency)
        self.accepted_total = 0
        self.rejected_total = 0

    @property
    def true_pose(self) -> np.ndarray:
        """(3,) ground truth, θ wrapped; for rewards, rendering and evaluation."""
        x, y, th = self.sim.true_pose
        return np.array([x, y, wrap_angle(th)])

    @property
    def odometry_pose(self) -> np.ndarray:
        x, y, th = self.sim.odometry_pose
        return np.array([x, y, wrap_angle(th)])

    @property
    def estimated_pose(self) -> np.ndarray:
        """(3,) the filter's estimate (dead reckoning corrected by the camera)."""
        return self.loop.ekf.pose()

    @property
    def believed_pose(self) -> np.ndarray:
        if self.localization == "truth":
            return self.true_pose
        if self.localization == "odometry":
            return self.odometry_pose
        return self.estimated_pose

    @property
    def covariance(self) -> np.ndarray:
        if self.localization == "truth":
            return np.zeros((3, 3))
        if self.localization == "odometry":
            from localizer.filter import compose_jacobians

            acc = self._odometry_motion
            _, G = compose_jacobians(self._start, acc.u)
            return G @ acc.Q @ G.T
        return self.loop.ekf.covariance()

    @property
    def last_frame(self) -> np.ndarray | None:
        """The latest camera frame ((H, W) uint8), if the source renders frames."""
        return getattr(self.source, "last_frame", None)

    def step(self, v: float, omega: float) -> EpisodeStep:
        """Apply (v m/s, ω rad/s) for one control step."""
        loop_step = self.loop.step(v, omega)
        inc = loop_step.sim.odometry
        self._odometry_motion.add(inc.ds, inc.dtheta)
        dt = self.config.control_dt
        half = 0.5 * self.config.vehicle.track_width
        wheels = np.array([(inc.ds - inc.dtheta * half) / dt, (inc.ds + inc.dtheta * half) / dt])
        accepted, rejected = loop_step.accepted, loop_step.rejected
        self.accepted_total += accepted
        self.rejected_total += rejected
        frame = self.last_frame if loop_step.captured else None
        return EpisodeStep(believed_pose=self.believed_pose, covariance=self.covariance,
                           wheel_speeds=wheels, collided=loop_step.sim.collided,
                           in_contact=self.sim.contacts.in_contact, accepted=accepted,
                           rejected=rejected, frame=frame)
