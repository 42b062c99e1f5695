"""The closed loop, one control step at a time: simulation, camera, filter.

:class:`ClosedLoop` advances the simulation by one control step with a
(v, ω) command, queues the odometry increment in the filter, captures a
camera frame at the vehicle's *true* pose when one is due (``camera_rate``),
and fuses each frame's observations ``latency`` seconds later (rounded up to
the next control step) at their capture time. The mission runner
(:func:`agvsim.mission.run_mission`) puts a path follower on top; the
Gymnasium environments put an agent on top. Nothing here steers.
"""
from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from agvsim.simulation import SimConfig, Simulation, StepResult
from localizer.filter import FrameResult, Measurement, PoseEKF

_EPS = 1e-9


@dataclass(frozen=True)
class FusedFrame:
    """A frame whose observations were fused in this step.

    Attributes:
        capture_time, fuse_time: s.
        step: control step index at capture.
        observations: what the source reported (objects with distance, beta,
            alpha, covariance, polarity; simulated ones also ``truth_id``).
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
        sim: the simulation's :class:`~agvsim.simulation.StepResult`.
        captured: a camera frame was captured in this step.
        fused: frames fused in this step.
    """

    sim: StepResult
    captured: bool
    fused: tuple[FusedFrame, ...]

    @property
    def accepted(self) -> int:
        return sum(f.result.accepted for f in self.fused)

    @property
    def rejected(self) -> int:
        return sum(len(f.observations) - f.result.accepted for f in self.fused)


def with_turn_blur(obs, yaw_rate: float, k: tuple[float, float, float]) -> Measurement:
    """The observation as a filter :class:`~localizer.filter.Measurement` with
    its covariance inflated for motion blur while turning at ``yaw_rate``
    (rad/s): σ_d = k_d |ω| d, σ_β = k_β |ω|, σ_α = k_α |ω| added in quadrature
    (see :attr:`agvsim.mission.MissionConfig.turn_blur_noise`)."""
    m = Measurement.from_observation(obs)
    w = abs(yaw_rate)
    if w > 0 and any(k):
        extra = np.array([k[0] * w * m.z[0], k[1] * w, k[2] * w])
        m = Measurement(m.z, m.R + np.diag(extra ** 2), m.polarity)
    return m


class ClosedLoop:
    """Simulation + camera + filter, stepped at the control rate.

    Args:
        sim: the simulation (owns the true pose and dead reckoning).
        ekf: the pose filter (already initialised at the start pose).
        source: observation source with ``observe(true_pose, rng)``, or None
            for no vision (the filter then only predicts, at frame times).
        camera_rng: generator for the camera's noise.
        camera_rate: frames per second (Hz).
        latency: capture-to-fusion delay (s).
        turn_blur_noise: covariance inflation while turning (see :func:`with_turn_blur`).
    """

    def __init__(self, sim: Simulation, ekf: PoseEKF, source, camera_rng: np.random.Generator,
                 camera_rate: float = 4.0, latency: float = 0.25,
                 turn_blur_noise: tuple[float, float, float] = (0.01, 0.0, 0.03)) -> None:
        if not (math.isfinite(camera_rate) and camera_rate > 0):
            raise ValueError(f"camera_rate must be > 0 Hz, got {camera_rate!r}")
        if not (math.isfinite(latency) and latency >= 0):
            raise ValueError(f"latency must be >= 0 s, got {latency!r}")
        self.sim = sim
        self.ekf = ekf
        self.source = source
        self.camera_rng = camera_rng
        self.period = 1.0 / camera_rate  # s
        self.latency = latency
        self.turn_blur_noise = turn_blur_noise
        self.next_frame = self.period  # s
        self.steps = 0
        self._in_flight: deque = deque()  # (ready, capture time, step, observations, observe_ms, yaw rate)
        self.timings = {"sim": 0.0, "observe": 0.0, "filter": 0.0}  # wall seconds

    @property
    def config(self) -> SimConfig:
        return self.sim.config

    def step(self, v: float, omega: float) -> LoopStep:
        """Drive with (v m/s, ω rad/s) for one control step; capture and fuse as due."""
        t0 = time.perf_counter()
        result = self.sim.step(v, omega)
        self.timings["sim"] += time.perf_counter() - t0
        now = self.sim.time
        inc = result.odometry
        self.ekf.add_odometry(now, inc.ds, inc.dtheta)
        fused = []
        while self._in_flight and self._in_flight[0][0] <= now + _EPS:
            fused.append(self._fuse(self._in_flight.popleft(), now))
        captured = False
        if now >= self.next_frame - _EPS:
            while self.next_frame <= now + _EPS:
                self.next_frame += self.period
            if self.source is not None:
                captured = True
                t0 = time.perf_counter()
                if hasattr(self.source, "velocity"):
                    self.source.velocity = self.config.vehicle.clip_command(v, omega)  # motion blur
                obs = self.source.observe(self.sim.true_pose, self.camera_rng)
                obs_ms = (time.perf_counter() - t0) * 1e3
                self.timings["observe"] += obs_ms / 1e3
                item = (now + self.latency, now, self.steps, tuple(obs), obs_ms,
                        inc.dtheta / self.config.control_dt)
                if self.latency <= _EPS:
                    fused.append(self._fuse(item, now))
                else:
                    self._in_flight.append(item)
            elif not self._in_flight:
                t0 = time.perf_counter()
                self.ekf.flush(now)
                self.timings["filter"] += time.perf_counter() - t0
        self.steps += 1
        return LoopStep(result, captured, tuple(fused))

    def _fuse(self, item, now: float) -> FusedFrame:
        _, t_cap, step, obs, obs_ms, yaw_rate = item
        t0 = time.perf_counter()
        res = self.ekf.process_frame(t_cap, [with_turn_blur(o, yaw_rate, self.turn_blur_noise) for o in obs])
        ms = (time.perf_counter() - t0) * 1e3
        self.timings["filter"] += ms / 1e3
        return FusedFrame(t_cap, now, step, obs, res, obs_ms, ms)
