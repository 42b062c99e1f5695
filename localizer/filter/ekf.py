r"""The pose filter: a filterpy ``ExtendedKalmanFilter`` over (x, y, θ) in the map frame.

Predict: odometry increments (Δs, Δθ) are queued with their time stamps and
accumulated (:mod:`localizer.filter.motion`); the EKF predicts once per
camera frame, ``x ← x ⊕ u`` and ``P ← F P Fᵀ + G Q_u Gᵀ`` (filterpy's
``predict`` with ``F`` and ``Q = G Q_u Gᵀ`` set, ``predict_x`` overridden
by the composition).

Latency: a frame captured at ``t_c`` is fused when its result is ready. The
filter's own state lags: :meth:`PoseEKF.process_frame` first predicts with
the queued increments up to ``t_c``, then updates; the pose for the
controller (:meth:`PoseEKF.pose`) is the filter state composed with the
increments still queued after it. No roll-back is needed as long as frames are
fused in capture order.

Update: each accepted observation (:mod:`localizer.filter.association`) is a
filterpy ``update(z, HJacobian, Hx, R, residual)`` with angle-wrapping
residual; filterpy 2.0's EKF update is in Joseph form,
``P = (I - K H) P (I - K H)ᵀ + K R Kᵀ``. Predict and update go through
:mod:`localizer.filter.update`, the path the re-localization hypotheses take
too; the NIS of each update is read from filterpy's innovation ``y`` and its
covariance ``S`` (:func:`~localizer.filter.update.nis`).

Lost: position σ (largest eigenvalue of P_xy) above ``lost_position_sigma``,
heading σ above ``lost_heading_sigma``, or ``lost_rejected_frames`` frames in a
row with a target predicted in view whose observations were all refused. Then :class:`~localizer.filter.relocalize.Relocalizer`
takes the frames until a hypothesis is confirmed.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from localizer.filter.association import ACCEPTED, Association, GateConfig, associate
from localizer.filter.measurement import Measurement, TargetMap
from localizer.mount import CameraMount
from localizer.filter.motion import OdometryAccumulator, OdometryNoise, compose_jacobians
from localizer.filter.relocalize import Hypothesis, RelocalizeConfig, Relocalizer
from localizer.filter.update import PoseKF, predict_pose, update_pose
from localizer.numeric import check_number, check_numbers, wrap_angle

__all__ = ["FilterConfig", "FrameResult", "PoseEKF"]


@dataclass(frozen=True)
class FilterConfig:
    """Settings of :class:`PoseEKF`.

    Attributes:
        noise: odometry motion-noise model.
        gate: association settings.
        relocalize: re-localization settings.
        measurement_floor: (σ_d m, σ_β rad, σ_α rad) added in quadrature to every
            observation's covariance (camera mount and map survey errors).
        lost_position_sigma: position σ (m) above which the filter is lost.
        lost_heading_sigma: heading σ (rad) above which the filter is lost.
        lost_rejected_frames: frames in a row with observations and a target predicted in view,
            none accepted, before lost.
    """

    noise: OdometryNoise = OdometryNoise()
    gate: GateConfig = GateConfig()
    relocalize: RelocalizeConfig = RelocalizeConfig()
    measurement_floor: tuple[float, float, float] = (0.002, 0.0003, 0.002)  # m, rad, rad
    lost_position_sigma: float = 1.0  # m
    lost_heading_sigma: float = math.radians(20.0)  # rad
    lost_rejected_frames: int = 12

    def __post_init__(self) -> None:
        check_numbers("FilterConfig.measurement_floor", self.measurement_floor, 3, low=0.0)
        for name, unit in (("lost_position_sigma", "m"), ("lost_heading_sigma", "rad")):
            check_number(f"FilterConfig.{name}", getattr(self, name), low=0.0, low_open=True, unit=unit)
        check_number("FilterConfig.lost_rejected_frames", self.lost_rejected_frames, low=1, integer=True)


@dataclass(frozen=True)
class FrameResult:
    """What fusing one frame did.

    Attributes:
        time: capture time (s).
        associations: one per observation.
        nis: (k,) normalised innovation squared of each accepted update (χ²(3) when consistent).
        accepted: number of accepted observations.
        lost: whether the filter is lost after the frame.
        relocalized: whether this frame confirmed a re-localization.
        hypotheses: live re-localization hypotheses after the frame.
    """

    time: float
    associations: tuple[Association, ...]
    nis: np.ndarray
    accepted: int
    lost: bool
    relocalized: bool
    hypotheses: int


class PoseEKF:
    """Odometry + target-observation pose filter (module docstring).

    Args:
        x0: (3,) initial pose (m, m, rad).
        P0: (3, 3) its covariance.
        targets: the map's targets (plain data).
        mount: the camera mount.
        config: settings.
        t0: time of the initial pose (s).
    """

    def __init__(self, x0, P0, targets: TargetMap, mount: CameraMount,
                 config: FilterConfig = FilterConfig(), t0: float = 0.0) -> None:
        x0 = np.asarray(x0, dtype=float).reshape(-1)
        P0 = np.asarray(P0, dtype=float)
        if x0.shape != (3,) or not np.isfinite(x0).all():
            raise ValueError(f"PoseEKF: x0 must be a finite (3,) pose, got {x0!r}")
        if P0.shape != (3, 3) or not np.isfinite(P0).all() or np.any(np.linalg.eigvalsh(0.5 * (P0 + P0.T)) < 0):
            raise ValueError(f"PoseEKF: P0 must be a finite positive semi-definite (3, 3) matrix, got {P0!r}")
        self.targets = targets
        self.mount = mount
        self.config = config
        self.kf = PoseKF(x0, 0.5 * (P0 + P0.T))
        self.time = float(t0)  # s, time of the filter state
        self._pending: deque = deque()  # (t, ds, dθ) after self.time
        self._now = OdometryAccumulator(config.noise)
        self.relocalizer = Relocalizer(targets, mount, config.gate, config.relocalize)
        self.lost = False
        self.rejected_frames = 0  # consecutive frames with observations, none accepted
        self.rejections = 0  # observations not accepted, total
        self.relocalizations = 0
        self.lost_events = 0
        self._floor = np.diag(np.asarray(config.measurement_floor, dtype=float) ** 2)

    # ------------------------------------------------------------ state
    @property
    def x(self) -> np.ndarray:
        """(3,) filter state at :attr:`time`."""
        return self.kf.x.reshape(-1).copy()

    @property
    def P(self) -> np.ndarray:
        """(3, 3) filter covariance at :attr:`time`."""
        return self.kf.P.copy()

    def pose(self) -> np.ndarray:
        """(3,) current pose estimate: the state composed with the queued odometry (θ wrapped)."""
        x, y, th = self.kf.x.ravel().tolist()
        now = self._now
        if now.steps:  # compose(x, now.u), on floats
            c, s = math.cos(th), math.sin(th)
            ux, uy = now.ux, now.uy
            x, y, th = x + c * ux - s * uy, y + s * ux + c * uy, th + now.uphi
        return np.array([x, y, wrap_angle(th)])

    def covariance(self) -> np.ndarray:
        """(3, 3) covariance of :meth:`pose`."""
        now = self._now
        if not now.steps:
            return self.kf.P.copy()
        F, G = compose_jacobians(self.kf.x, (now.ux, now.uy, now.uphi))
        return F @ self.kf.P @ F.T + G @ now.Q @ G.T

    # ------------------------------------------------------------ predict
    def add_odometry(self, t: float, ds: float, dtheta: float) -> None:
        """Queue the odometry increment (Δs m, Δθ rad) that ended at time ``t`` (s)."""
        if self._pending and t < self._pending[-1][0]:
            raise ValueError(f"odometry time stamps must not decrease: {t!r} after {self._pending[-1][0]!r}")
        self._pending.append((float(t), float(ds), float(dtheta)))
        self._now.add(ds, dtheta)

    def flush(self, t: float) -> None:
        """Predict the filter state to time ``t`` (s) with the queued increments up to ``t``."""
        if t < self.time - 1e-9:
            raise ValueError(f"cannot predict back in time: {t!r} < {self.time!r} (frames out of order?)")
        acc = OdometryAccumulator(self.config.noise)
        while self._pending and self._pending[0][0] <= t + 1e-9:
            _, ds, dth = self._pending.popleft()
            acc.add(ds, dth)
        if acc.steps:
            self._predict(acc.u, acc.Q)
            self._now.reset()
            for _, ds, dth in self._pending:
                self._now.add(ds, dth)
        self.time = float(t)
        self._check_lost()

    def _predict(self, u: np.ndarray, Q: np.ndarray) -> None:
        predict_pose(self.kf, u, Q)
        self.kf.x[2, 0] = wrap_angle(float(self.kf.x[2, 0]))
        if self.lost:
            self.relocalizer.predict(u, Q)

    def _check_lost(self) -> None:
        if self.lost:
            return
        P = self.kf.P
        # the larger eigenvalue of P_xy (its lower triangle, as numpy's eigvalsh reads it), closed form
        a, b, d = P.item(0, 0), P.item(1, 0), P.item(1, 1)
        pos_var = 0.5 * (a + d) + math.hypot(0.5 * (a - d), b)
        pos_sigma = math.sqrt(max(pos_var, 0.0))
        if (pos_sigma > self.config.lost_position_sigma
                or math.sqrt(max(P.item(2, 2), 0.0)) > self.config.lost_heading_sigma
                or self.rejected_frames >= self.config.lost_rejected_frames):
            self.lost = True
            self.lost_events += 1
            self.relocalizer.reset()

    # ------------------------------------------------------------ update
    def measurement(self, obs) -> Measurement:
        """A :class:`Measurement` from a ``TargetObservation`` (or a Measurement), with the floor added."""
        m = obs if isinstance(obs, Measurement) else Measurement.from_observation(obs)
        return m.plus_noise(self._floor)

    def process_frame(self, t_capture: float, observations: Sequence) -> FrameResult:
        """Fuse the observations of a frame captured at ``t_capture`` (s).

        ``observations``: ``TargetObservation``\\ s or :class:`Measurement`\\ s (the
        measurement floor is added to their covariance here).
        """
        self.flush(t_capture)
        ms = [self.measurement(o) for o in observations]
        if self.lost:
            return self._relocalize(t_capture, ms)
        assoc = associate(self.kf.x, self.kf.P, ms, self.targets, self.mount, self.config.gate)
        nis = []
        for a in assoc:
            if a.status != ACCEPTED:
                self.rejections += 1
                continue
            m = ms[a.observation]
            pos, yaw = self.targets.positions[a.target], self.targets.yaws[a.target]
            nis.append(update_pose(self.kf, m, pos, yaw, self.mount))  # NIS from filterpy's y and S
            self.kf.x[2, 0] = wrap_angle(float(self.kf.x[2, 0]))
        accepted = len(nis)
        # a frame counts against the filter when a target was predicted in view and none of the
        # observations fitted; observations with no candidate at all (false detections away from
        # every target) say nothing about the pose
        if accepted:
            self.rejected_frames = 0
        elif any(a.candidates > 0 for a in assoc):
            self.rejected_frames += 1
        # no _refresh_now here: flush left _now the accumulation of exactly the queued increments
        self._check_lost()
        return FrameResult(t_capture, tuple(assoc), np.asarray(nis), accepted, self.lost, False,
                           len(self.relocalizer.hypotheses))

    def _refresh_now(self) -> None:
        self._now.reset()
        for _, ds, dth in self._pending:
            self._now.add(ds, dth)

    def _relocalize(self, t: float, ms: list[Measurement]) -> FrameResult:
        reloc = self.relocalizer
        confirmed = None
        if ms:
            if not reloc.hypotheses:
                prior = Hypothesis(self.x, self.P)
                reloc.seed(ms, prior)
            else:
                confirmed = reloc.update(ms)
        self.rejections += len(ms)
        if confirmed is not None:
            self.kf.x = confirmed.x.reshape(3, 1).copy()
            self.kf.P = confirmed.P.copy()
            self.lost = False
            self.rejected_frames = 0
            self.relocalizations += 1
            reloc.reset()
            self._refresh_now()
        return FrameResult(t, tuple(), np.zeros(0), 0, self.lost, confirmed is not None,
                           len(reloc.hypotheses))

    def reset(self, x, P) -> None:
        """Set the filter state to ``x`` (3,), ``P`` (3, 3) at the current filter time; not lost."""
        self.kf.x = np.asarray(x, dtype=float).reshape(3, 1).copy()
        self.kf.P = np.asarray(P, dtype=float).copy()
        self.lost = False
        self.rejected_frames = 0
        self.relocalizer.reset()
