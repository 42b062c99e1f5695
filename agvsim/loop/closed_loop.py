"""The closed loop, one control step at a time: simulation, camera, filter.

:class:`ClosedLoop` is the one place a run is put together: it builds the
simulation, the pose filter and the camera schedule from a :class:`LoopConfig`
and splits the run's generator into its streams (``rng.spawn(2)``: odometry,
camera). Each :meth:`ClosedLoop.step` advances the simulation by one control
step with a (v, ω) command, queues the odometry increment in the filter,
captures a camera frame at the vehicle's *true* pose when one is due
(``camera_rate``), and fuses each frame's observations ``latency`` seconds later
(rounded up to the next control step) at their capture time.

Who steers: the mission (:func:`agvsim.loop.mission.run_mission`) puts a path
follower on top, the Gymnasium environments (:mod:`envs`) an agent. Nothing
here steers, rewards or knows about spaces.

Localization modes (:data:`~agvsim.loop.modes.LOCALIZATION_MODES`), the pose
:attr:`ClosedLoop.believed_pose` reports:
    ``ekf``       dead reckoning corrected by camera observations of the wall targets;
    ``odometry``  dead reckoning, with its covariance from the filter's odometry motion
                  model (:class:`localizer.filter.OdometryAccumulator`);
    ``truth``     the true pose (covariance zero).
"""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from agvsim.loop.modes import LOCALIZATION_MODES
from agvsim.sensors.vision import VisionConfig, targets_from_map
from agvsim.vehicle.simulation import SimConfig, Simulation, StepResult
from localizer.filter import (TRACKING, ContactSlip, FilterConfig, FrameResult, GateConfig, Measurement,
                              OdometryAccumulator, OdometryNoise, PoseEKF, compose_jacobians, position_sigma)
from localizer.numeric import check_choice, check_number, check_numbers, wrap_angle

__all__ = ["ClosedLoop", "FusedFrame", "LoopConfig", "LoopStep", "filter_config_for", "odometry_noise_for",
           "with_turn_blur"]

_EPS = 1e-9


def odometry_noise_for(config: SimConfig, correlation: float = 15.0, inflation: float = 1.0) -> OdometryNoise:
    """The filter's motion-noise model matching the simulation's odometry error model.

    Random part: the per-wheel noise as is. Systematic part (unknown to the filter):
    |E_d - 1| and |E_b - 1| folded in as noise accumulating over ``correlation`` m
    (about the distance between target sightings on the shipped maps). Quantization
    error does not accumulate (the counts are cumulative) and is left out.
    """
    e = config.odometry
    return OdometryNoise(wheel_noise=e.wheel_noise, track_width=config.vehicle.track_width,
                         diameter_bias=abs(e.ed - 1.0), wheelbase_bias=abs(e.eb - 1.0), scale_bias=0.0,
                         correlation=correlation, inflation=inflation)


def filter_config_for(config: SimConfig, vision: VisionConfig, noise: OdometryNoise | None = None,
                      **kw) -> FilterConfig:
    """A :class:`FilterConfig` for this odometry and camera (``kw`` overrides fields).

    ``noise``: the motion-noise model if already made (default :func:`odometry_noise_for`).
    """
    base = dict(noise=noise if noise is not None else odometry_noise_for(config),
                gate=GateConfig(view=vision.view_limits()))
    base.update(kw)
    return FilterConfig(**base)


@dataclass(frozen=True)
class LoopConfig:
    """How a closed loop is put together (the mission's and the environments' shared part).

    Attributes:
        sim: rates, vehicle, odometry error model.
        vision_config: the camera; its mount None: the map's recommended mount.
        camera_rate: frames per second (Hz).
        latency: capture-to-fusion delay (s).
        filter: filter settings; None: :func:`filter_config_for`.
        initial_sigma: (σ_x m, σ_y m, σ_θ rad) of the start pose given to the filter.
        initial_error: (3,) error added to the start pose given to the filter (m, m, rad).
        turn_blur_noise: (k_d 1/(rad/s), k_β s, k_α s): extra standard deviations
            ``σ_d = k_d |ω| d``, ``σ_β = k_β |ω|``, ``σ_α = k_α |ω|`` added in quadrature to each
            observation of a frame captured while the vehicle turns at yaw rate ω (rad/s, from
            the odometry). Motion blur while turning biases the localizer's d and α beyond its
            reported covariance: in rendered frames (10 ms exposure, 16 mm lens, d ≈ 3 m,
            ω ≈ 0.55 rad/s) α was off by 10-18 mrad (3-9 reported σ) and d by 5-20 mm, while the
            same frames without blur were within 1 σ.
    """

    sim: SimConfig = field(default_factory=SimConfig)
    vision_config: VisionConfig = field(default_factory=VisionConfig)
    camera_rate: float = 4.0  # Hz
    latency: float = 0.25  # s
    filter: FilterConfig | None = None
    initial_sigma: tuple[float, float, float] = (0.01, 0.01, 0.002)  # m, m, rad
    initial_error: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m, m, rad
    turn_blur_noise: tuple[float, float, float] = (0.01, 0.0, 0.03)  # 1/(rad/s), s, s

    def __post_init__(self) -> None:
        name = type(self).__name__
        check_number(f"{name}.camera_rate", self.camera_rate, low=0.0, low_open=True, unit="Hz")
        check_number(f"{name}.latency", self.latency, low=0.0, unit="s")
        check_numbers(f"{name}.turn_blur_noise", self.turn_blur_noise, 3, low=0.0)
        check_numbers(f"{name}.initial_sigma", self.initial_sigma, 3, low=0.0, low_open=True)
        check_numbers(f"{name}.initial_error", self.initial_error, 3)


def with_turn_blur(obs, yaw_rate: float, k: tuple[float, float, float]) -> Measurement:
    """The observation as a filter :class:`~localizer.filter.Measurement` with
    its covariance inflated for motion blur while turning at ``yaw_rate``
    (rad/s): σ_d = k_d |ω| d, σ_β = k_β |ω|, σ_α = k_α |ω| added in quadrature
    (see :attr:`LoopConfig.turn_blur_noise`)."""
    m = Measurement.from_observation(obs)
    w = abs(yaw_rate)
    if w > 0 and any(k):
        extra = np.array([k[0] * w * m.z[0], k[1] * w, k[2] * w])
        m = m.plus_noise(np.diag(extra ** 2))
    return m


@dataclass(frozen=True)
class FusedFrame:
    """A frame whose observations were fused in this step.

    Attributes:
        capture_time, fuse_time: s.
        step: control step index at capture.
        observations: what the source reported (:class:`~agvsim.sensors.base.SimObservation`).
        result: the filter's :class:`~localizer.filter.FrameResult`.
        observe_ms: render + detect wall time (ms).
        filter_ms: fusion wall time (ms).
    """

    capture_time: float
    fuse_time: float
    step: int
    observations: tuple
    result: FrameResult
    observe_ms: float
    filter_ms: float


@dataclass(frozen=True)
class LoopStep:
    """What one control step of the closed loop produced.

    Attributes:
        sim: the vehicle's :class:`~agvsim.vehicle.simulation.StepResult` (odometry
            increment, applied command, contacts).
        captured: a camera frame was captured in this step.
        fused: frames fused in this step.
        wheel_speeds: measured (left, right) rim speeds over the step (m/s).
    """

    sim: StepResult
    captured: bool
    fused: tuple[FusedFrame, ...]
    wheel_speeds: tuple[float, float]

    @property
    def accepted(self) -> int:
        """Observations fused in this step."""
        return sum(f.result.accepted for f in self.fused)

    @property
    def rejected(self) -> int:
        """Observations refused in this step."""
        return sum(len(f.observations) - f.result.accepted for f in self.fused)


class ClosedLoop:
    """Simulation + camera + filter on a map, stepped at the control rate.

    Args:
        world_map: the map (the world, the filter's target list and its free space).
        start_pose: true start pose (x m, y m, θ rad); dead reckoning starts there.
        believed_pose: what the filter is told: None (the start pose plus
            ``config.initial_error``, with ``config.initial_sigma``), a pose (x m, y m, θ rad)
            with ``config.initial_sigma``, or ``"unknown"``: the filter starts lost
            (``status`` ``lost``) and localizes from the targets it sees.
        rng: the run's generator, split into odometry and camera streams (``rng.spawn(2)``).
        config: how the loop is put together.
        source: observation source (:class:`~agvsim.sensors.base.ObservationSource`), or None
            for no camera (the filter then only predicts, at frame times).
        localization: what :attr:`believed_pose` reports, one of
            :data:`~agvsim.loop.modes.LOCALIZATION_MODES`.
    """

    def __init__(self, world_map, start_pose, rng: np.random.Generator, config: LoopConfig = LoopConfig(),
                 source=None, localization: str = "ekf", believed_pose=None) -> None:
        check_choice("localization", localization, LOCALIZATION_MODES)
        self.map = world_map
        self.config = config
        self.localization = localization
        self.vision = config.vision_config.for_map(world_map)
        sim_rng, self.camera_rng = rng.spawn(2)
        start = tuple(float(v) for v in start_pose)
        self.sim = Simulation(world_map, start, config.sim, sim_rng)
        noise = odometry_noise_for(config.sim)
        fcfg = config.filter or filter_config_for(config.sim, self.vision, noise)
        unknown = isinstance(believed_pose, str)
        if unknown and believed_pose != "unknown":
            raise ValueError(f"believed_pose must be None, a pose (x, y, theta) or 'unknown', got {believed_pose!r}")
        P0 = np.diag(np.asarray(config.initial_sigma, dtype=float) ** 2)
        if unknown:  # the map's centre, nothing believed: the filter starts lost
            xmin, ymin, xmax, ymax = world_map.bounds
            x0 = np.array([0.5 * (xmin + xmax), 0.5 * (ymin + ymax), 0.0])
        elif believed_pose is not None:
            x0 = np.array(check_numbers("believed_pose", believed_pose, 3), dtype=float)
        else:
            x0 = np.asarray(start) + np.asarray(config.initial_error, dtype=float)
        self.ekf = PoseEKF(x0, P0, targets_from_map(world_map), self.vision.mount, fcfg, t0=0.0,
                           free_space=world_map.is_free)
        if unknown:
            self.ekf.declare_lost("start pose unknown")
        self.source = source
        # dead reckoning's covariance: the filter's motion model accumulated from the (known) start
        self._start = np.asarray(start, dtype=float)
        self._odometry_motion = OdometryAccumulator(noise) if localization == "odometry" else None
        self._odometry_slip = ContactSlip(fcfg.contact_slip, noise.track_width)
        self.kidnaps = 0  # times the vehicle was carried off (kidnap)
        self.period = 1.0 / config.camera_rate  # s
        self.latency = config.latency
        self.next_frame = self.period  # s
        self.steps = 0
        self._in_flight: deque = deque()  # (ready, capture time, step, observations, observe_ms, yaw rate)
        self._dt = config.sim.control_dt  # s
        self._half_track = 0.5 * config.sim.vehicle.track_width  # m
        #: wall seconds: "sim" (Simulation.step: physics, encoders, dead reckoning), "observe" (the
        #: source's observe) = "render" (drawing frames, from the source's own ``timing`` when it
        #: keeps one) + "localize" (the rest of observe: finding the targets), "filter" (odometry
        #: into the filter, predict, associate, update)
        self.timings = {"sim": 0.0, "observe": 0.0, "render": 0.0, "localize": 0.0, "filter": 0.0}

    # -- poses -----------------------------------------------------------------
    @property
    def true_pose(self) -> np.ndarray:
        """(3,) ground truth, θ wrapped to [-π, π); for rewards, rendering and evaluation only."""
        x, y, th = self.sim.true_pose
        return np.array([x, y, wrap_angle(th)])

    @property
    def odometry_pose(self) -> np.ndarray:
        """(3,) dead reckoning, θ wrapped to [-π, π)."""
        x, y, th = self.sim.odometry_pose
        return np.array([x, y, wrap_angle(th)])

    @property
    def estimated_pose(self) -> np.ndarray:
        """(3,) the filter's estimate (dead reckoning corrected by the camera)."""
        return self.ekf.pose()

    @property
    def believed_pose(self) -> np.ndarray:
        """(3,) the pose of :attr:`localization`."""
        if self.localization == "truth":
            return self.true_pose
        if self.localization == "odometry":
            return self.odometry_pose
        return self.estimated_pose

    @property
    def covariance(self) -> np.ndarray:
        """(3, 3) covariance of :attr:`believed_pose` (m², m·rad, rad²)."""
        if self.localization == "truth":
            return np.zeros((3, 3))
        if self.localization == "odometry":
            acc = self._odometry_motion
            _, G = compose_jacobians(self._start, (acc.ux, acc.uy, acc.uphi))
            return G @ acc.Q @ G.T
        return self.ekf.covariance()

    def localization_info(self, covariance: np.ndarray | None = None) -> dict:
        """The localization's state for the agent (``info["localization"]``): ``status``
        (``tracking``, ``lost`` or ``relocalizing``), ``position_sigma`` (m, the largest
        standard deviation of the believed position), ``since_fix`` (s since the last
        accepted target observation, or re-localization), ``since_tracking`` (s since the status
        was last ``tracking``; 0 while it is), ``hypotheses`` (poses the belief holds: 1 for one
        Gaussian, the components of a wide belief, the live re-localization hypotheses while
        lost), ``reason`` (why lost; None while tracking), ``lost_events`` and
        ``relocalizations`` (counts this episode).

        ``covariance``: :attr:`covariance` if the caller has it already (it is not made
        twice). For ``localization="odometry"`` the status is always ``tracking`` and
        ``since_fix`` the time since the start; for ``"truth"`` σ and ``since_fix`` are 0."""
        now = self.sim.time
        if self.localization == "truth":
            return {"status": TRACKING, "position_sigma": 0.0, "since_fix": 0.0, "since_tracking": 0.0,
                    "hypotheses": 1, "reason": None, "lost_events": 0, "relocalizations": 0}
        sigma = position_sigma(self.covariance if covariance is None else covariance)
        if self.localization == "odometry":
            return {"status": TRACKING, "position_sigma": sigma, "since_fix": now, "since_tracking": 0.0,
                    "hypotheses": 1, "reason": None, "lost_events": 0, "relocalizations": 0}
        ekf = self.ekf
        return {"status": ekf.status, "position_sigma": sigma, "since_fix": ekf.since_fix(now),
                "since_tracking": ekf.since_tracking(now), "hypotheses": ekf.hypotheses, "reason": ekf.lost_reason,
                "lost_events": ekf.lost_events, "relocalizations": ekf.relocalizations}

    def kidnap(self, pose) -> None:
        """Carry the vehicle to ``pose`` (x m, y m, θ rad) without telling the filter (the
        kidnapped robot): the wheels do not turn, dead reckoning and the filter carry on from
        where they were. Raises ``ValueError`` if the chassis would overlap a wall or obstacle."""
        self.sim.place_vehicle(tuple(check_numbers("kidnap pose", pose, 3)))
        self.kidnaps += 1

    @property
    def last_frame(self) -> np.ndarray | None:
        """The latest camera frame ((H, W) uint8), if the source draws frames."""
        return self.source.last_frame if self.source is not None else None

    # -- stepping --------------------------------------------------------------
    def step(self, v: float, omega: float) -> LoopStep:
        """Drive with (v m/s, ω rad/s) for one control step; capture and fuse as due."""
        perf = time.perf_counter
        timings = self.timings
        t0 = perf()
        result = self.sim.step(v, omega)
        t1 = perf()
        now = self.sim.time
        dt = self._dt
        touched = result.in_contact or bool(result.contacts)  # the bumper, during the step
        self.ekf.add_odometry(now, result.ds, result.dtheta, touched)
        if self._odometry_motion is not None:
            self._odometry_motion.add(result.ds, result.dtheta,
                                      self._odometry_slip.extra(result.ds, result.dtheta, touched, now))
        timings["sim"] += t1 - t0
        timings["filter"] += perf() - t1
        fused = []
        while self._in_flight and self._in_flight[0][0] <= now + _EPS:
            fused.append(self._fuse(self._in_flight.popleft(), now))
        captured = False
        if now >= self.next_frame - _EPS:
            while self.next_frame <= now + _EPS:
                self.next_frame += self.period
            if self.source is not None:
                captured = True
                source_timing = getattr(self.source, "timing", None)  # {"render": s, ...} if it keeps one
                rendered = source_timing["render"] if source_timing else 0.0
                t0 = perf()
                obs = self.source.observe(self.sim.true_pose, self.camera_rng, result.command)
                elapsed = perf() - t0
                rendered = source_timing["render"] - rendered if source_timing else 0.0
                timings["observe"] += elapsed
                timings["render"] += rendered
                timings["localize"] += elapsed - rendered
                obs_ms = elapsed * 1e3
                item = (now + self.latency, now, self.steps, tuple(obs), obs_ms, result.dtheta / dt)
                if self.latency <= _EPS:
                    fused.append(self._fuse(item, now))
                else:
                    self._in_flight.append(item)
            elif not self._in_flight:
                t0 = perf()
                self.ekf.flush(now)
                timings["filter"] += perf() - t0
        self.steps += 1
        half = self._half_track
        wheels = ((result.ds - result.dtheta * half) / dt, (result.ds + result.dtheta * half) / dt)
        return LoopStep(result, captured, tuple(fused), wheels)

    def _fuse(self, item, now: float) -> FusedFrame:
        _, t_cap, step, obs, obs_ms, yaw_rate = item
        t0 = time.perf_counter()
        k = self.config.turn_blur_noise
        res = self.ekf.process_frame(t_cap, [with_turn_blur(o, yaw_rate, k) for o in obs])
        ms = (time.perf_counter() - t0) * 1e3
        self.timings["filter"] += ms / 1e3
        return FusedFrame(t_cap, now, step, obs, res, obs_ms, ms)
