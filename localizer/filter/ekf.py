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

Slip: while the vehicle reports contact (``add_odometry(..., in_contact=True)``), the odometry
noise grows with the wheel motion since the contact began (:class:`~localizer.filter.motion.ContactSlip`).

Status (:data:`STATUSES`): ``tracking``; ``lost`` (no live re-localization hypothesis) or
``relocalizing`` (hypotheses alive, none confirmed yet).

Wide is not lost: when odometry alone spreads the estimate past ``lost_position_sigma`` (largest
eigenvalue of P_xy) or ``lost_heading_sigma``, the filter keeps the same belief as a Gaussian
mixture (:class:`~localizer.filter.wide.WideBelief`, ``FilterConfig.wide``, opt-in) and goes on
tracking: the state and covariance it reports are the mixture's moments, honest however wide,
and the first target seen reweighs the components, until the moments are narrow again and one
Gaussian takes over. The wide belief is given up (lost) when its own tests say so
(:meth:`~localizer.filter.wide.WideBelief.lost_reason`); the one Gaussian when the tests of
:mod:`localizer.filter.lost` say so (misfits that line up, frames refused, poor fits, an
estimate outside free space), or when told so: :meth:`PoseEKF.declare_lost` (an unknown start
pose). The reason is kept (:attr:`PoseEKF.lost_reason`).

Then :class:`~localizer.filter.relocalize.Relocalizer` takes the frames until a hypothesis is
confirmed (never while a contact's wheel slip is still counting: the odometry the hypotheses
ride on is not to be trusted then; global re-localization from nothing: the main state plays
no part in it); the frames since the last fit are replayed into it first
(:mod:`localizer.filter.replay`, at most ``relocalize.replay_frames``). Inputs are checked at the boundary (:mod:`localizer.filter.limits`).
"""
from __future__ import annotations

import math
from collections import deque
from typing import Sequence

import numpy as np

from localizer.filter.association import ACCEPTED, associate
from localizer.filter.config import FilterConfig
from localizer.filter.limits import (LOST, MAX_HEADING_SIGMA, MAX_ODOMETRY_STEP, MAX_ODOMETRY_TURN,
                                     MAX_POSITION_SIGMA, RELOCALIZING, STATUSES, TIME_SLACK, TRACKING, UNINFORMATIVE,
                                     FrameResult, Refused, check_frame_time, check_odometry, check_state,
                                     with_refused, within_bounds)
from localizer.filter.lost import Evidence, becomes_wide, lost_reason
from localizer.filter.measurement import Measurement, TargetMap, informative
from localizer.filter.misfits import MisfitWatch
from localizer.model.mount import CameraMount
from localizer.filter.motion import ContactSlip, OdometryAccumulator, compose_jacobians
from localizer.filter.relocalize import Hypothesis, Relocalizer
from localizer.filter.replay import RecentFrames
from localizer.filter.wide import WideBelief
from localizer.filter.update import PoseKF, nis, position_sigma, predict_pose, update_pose
from localizer.numeric import check_number, wrap_angle

__all__ = ["FilterConfig", "FrameResult", "LOST", "MAX_HEADING_SIGMA", "MAX_ODOMETRY_STEP", "MAX_ODOMETRY_TURN",
           "MAX_POSITION_SIGMA", "PoseEKF", "RELOCALIZING", "STATUSES", "TRACKING", "UNINFORMATIVE"]

class PoseEKF:
    """Odometry + target-observation pose filter (module docstring).

    Args:
        x0: (3,) initial pose (m, m, rad).
        P0: (3, 3) its covariance.
        targets: the map's targets (plain data).
        mount: the camera mount.
        config: settings.
        t0: time of the initial pose (s).
        free_space: optional ``(x m, y m) -> bool``, whether the vehicle's reference point can be
            there (inside the map, not inside a wall or an obstacle): an estimate outside it
            means lost, and no re-localization hypothesis is kept outside it.
    """

    def __init__(self, x0, P0, targets: TargetMap, mount: CameraMount,
                 config: FilterConfig = FilterConfig(), t0: float = 0.0, free_space=None) -> None:
        x0, P0 = check_state("PoseEKF", x0, P0, ("x0", "P0"))
        self.targets = targets
        self.mount = mount
        self.config = config
        self.kf = PoseKF(x0, P0)
        self.time = check_number("PoseEKF t0", t0, unit="s")  # s, time of the filter state
        self._pending: deque = deque()  # (t, ds, dθ) after self.time
        self._now = OdometryAccumulator(config.noise)
        self._slip = ContactSlip(config.contact_slip, config.noise.track_width)
        self.free_space = free_space
        self.relocalizer = Relocalizer(targets, mount, config.gate, config.relocalize, free_space=free_space)
        self.lost = False
        self.lost_reason: str | None = None  # why the filter is lost (None while tracking)
        self.wide: WideBelief | None = None  # the mixture while the estimate is wide (module docstring)
        self.wide_events = 0  # times the estimate became wide
        self.last_tracking = float(t0)  # s: the filter time it was last tracking
        self.rejected_frames = 0  # consecutive frames with a target predicted in view, none accepted
        # grossly misfitting detections since the last accepted one, placed in the map
        self.misfits = MisfitWatch(targets, config.misfit_d2, config.misfit_radius, config.misfit_yaw)
        self.rejections = 0  # observations not accepted, total
        self._refusals: dict[str, int] = {}  # inputs refused at the boundary, by reason (diagnostics)
        self.relocalizations = 0
        self.lost_events = 0
        self.last_fix = float(t0)  # s: the last accepted update (or confirmed re-localization)
        self._nis = deque(maxlen=config.nis_window)  # the latest accepted updates' NIS
        # while tracking: [u (3,), Q (3, 3), measurements] per flush / frame, for the replay
        self._history = RecentFrames(config.relocalize.replay_frames)
        self._nis_limit = config.nis_limit
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

    @property
    def status(self) -> str:
        """``tracking``, ``lost`` or ``relocalizing`` (:data:`STATUSES`)."""
        if not self.lost:
            return TRACKING
        return RELOCALIZING if self.relocalizer.hypotheses else LOST

    @property
    def hypotheses(self) -> int:
        """How many poses the belief holds: 1 while tracking with one Gaussian, the wide belief's
        components, or the live re-localization hypotheses while lost."""
        if self.lost:
            return len(self.relocalizer.hypotheses)
        return 1 if self.wide is None else len(self.wide)

    def since_tracking(self, t: float) -> float:
        """Seconds from the last filter time the status was ``tracking`` to ``t`` (0 while tracking)."""
        return 0.0 if not self.lost else max(float(t) - self.last_tracking, 0.0)

    def since_fix(self, t: float) -> float:
        """Seconds from the last accepted update (or confirmed re-localization) to ``t`` (s)."""
        return max(float(t) - self.last_fix, 0.0)

    def position_sigma(self) -> float:
        """The largest standard deviation of the position (m): √ of the larger eigenvalue of
        the current covariance's P_xy."""
        return position_sigma(self.covariance())

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
    def add_odometry(self, t: float, ds: float, dtheta: float, in_contact: bool = False) -> None:
        """Queue the odometry increment (Δs m, Δθ rad) that ended at time ``t`` (s);
        ``in_contact``: the vehicle touched a wall or obstacle during it (its wheels may have
        slipped: :attr:`FilterConfig.contact_slip`).

        Raises ``ValueError`` (nothing queued, counted in :meth:`diagnostics`) for a time stamp
        that is not finite or is before the last one (or the filter time), a Δs or Δθ that is not
        finite or beyond :data:`MAX_ODOMETRY_STEP` / :data:`MAX_ODOMETRY_TURN`, an ``in_contact``
        that is not a bool."""
        last = self._pending[-1][0] if self._pending else self.time
        try:
            t, ds, dtheta = check_odometry(t, ds, dtheta, in_contact, last, slack=0.0 if self._pending else TIME_SLACK)
        except Refused as exc:
            self._refuse(exc.reason)
            raise
        # validated: from here on nothing raises, so nothing is half-applied
        slip = self._slip.extra(ds, dtheta, bool(in_contact), t)
        self._now.add(ds, dtheta, slip)
        self._pending.append((t, ds, dtheta, slip))

    def _check_time(self, where: str, t) -> float:
        """``t`` (s) finite and not before the filter time, or a ``ValueError`` (counted)."""
        try:
            return check_frame_time(where, t, self.time)
        except Refused as exc:
            self._refuse(exc.reason)
            raise

    def flush(self, t: float) -> None:
        """Predict the filter state to time ``t`` (s) with the queued increments up to ``t``."""
        t = self._check_time("PoseEKF.flush t", t)
        self._flush(t)

    def _flush(self, t: float) -> None:
        acc = OdometryAccumulator(self.config.noise)
        self._history.no_motion()
        while self._pending and self._pending[0][0] <= t + 1e-9:
            _, ds, dth, slip = self._pending.popleft()
            acc.add(ds, dth, slip)
        if acc.steps:
            self._predict(acc.u, acc.Q)
            self._refresh_now()
            if not self.lost:
                self._history.motion(acc.u, acc.Q)
        self.time = float(t)
        self._check_lost()

    def _predict(self, u: np.ndarray, Q: np.ndarray) -> None:
        if self.wide is not None:
            self.wide.predict(u, Q)
            self._from_wide()
        else:
            predict_pose(self.kf, u, Q)
        self.kf.x[2, 0] = wrap_angle(float(self.kf.x[2, 0]))
        if self.lost:
            self.relocalizer.predict(u, Q)
        self._bound_covariance()

    def _bound_covariance(self) -> None:
        """Lost is a state, not an ever-growing matrix: a covariance that is not finite, or whose
        position σ exceeds :data:`MAX_POSITION_SIGMA` (heading σ :data:`MAX_HEADING_SIGMA`),
        makes the filter lost and is set back to ``lost_sigma`` (counted: ``covariance_bound``)."""
        if within_bounds(self.kf.x, self.kf.P):
            return
        self._refuse("covariance_bound")
        if not np.isfinite(self.kf.x).all():
            self.kf.x = np.zeros((3, 1))
        self.declare_lost(f"covariance beyond the representable bound (position sigma > {MAX_POSITION_SIGMA:g} m, "
                          f"heading sigma > {MAX_HEADING_SIGMA:g} rad, or not finite)")
        self.kf.P = np.diag(np.asarray(self.config.lost_sigma, dtype=float) ** 2)

    def _from_wide(self) -> None:
        """The state and covariance from the wide belief's moments."""
        x, P = self.wide.moments()
        self.kf.x = x.reshape(3, 1)
        self.kf.P = P

    def _check_lost(self) -> None:
        if self.lost:
            return
        self.last_tracking = self.time
        if self.wide is not None:
            reason = self.wide.lost_reason()
            if reason is not None:
                self.declare_lost(reason)
            elif self.wide.narrow():
                self._from_wide()
                self.wide = None
            return
        if becomes_wide(self.kf.P, self.config):
            cfg = self.config
            self.wide = WideBelief(self.kf.x, self.kf.P, self.targets, self.mount, cfg.gate, cfg.wide, self.free_space)
            self.wide_events += 1
            return
        evidence = Evidence(self.rejected_frames, self.misfits.frames, self._nis, self._nis_limit)
        reason = lost_reason(self.kf.x.reshape(-1), self.kf.P, self.config, evidence, self.free_space)
        if reason is not None:
            self.declare_lost(reason)

    def declare_lost(self, reason: str) -> None:
        """Mark the filter lost (``reason``: why, for :attr:`lost_reason`); re-localization starts
        from nothing with the next frame's detections. A no-op if already lost."""
        if self.lost:
            return
        self.lost = True
        self.lost_reason = str(reason)
        self.lost_events += 1
        self.wide = None
        self.kf.P = np.diag(np.asarray(self.config.lost_sigma, dtype=float) ** 2)
        reloc = self.relocalizer
        reloc.reset()
        self._history.replay(reloc)  # the recent frames first (module docstring)

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
        t_capture = self._check_time("PoseEKF.process_frame t_capture", t_capture)
        fused = []  # every observation validated before the state changes (nothing half-applied)
        for k, o in enumerate(observations):
            try:
                fused.append(self.measurement(o))
            except ValueError as err:
                self._refuse("measurement_invalid")
                raise ValueError(f"PoseEKF.process_frame observations[{k}]: {err}") from None
        # beyond the sane bounds an observation fits anything: refused (counted), the rest fused
        keep = [k for k, m in enumerate(fused) if informative(m.R)]
        refused = len(fused) - len(keep)
        ms = fused if not refused else [fused[k] for k in keep]
        for _ in range(refused):
            self._refuse("measurement_uninformative")
            self.rejections += 1
        self._flush(t_capture)
        if self.lost:
            result = self._relocalize(t_capture, ms)
            return with_refused(result, keep, len(fused)) if refused else result
        if ms:  # the frame's measurements join the motion this flush predicted (if any)
            self._history.measured(ms)
        if self.wide is not None:
            return self._wide_frame(t_capture, ms, keep, len(fused))
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
        # a frame counts against the filter when a target was predicted in view and none fitted;
        # gross misfits not explained by the map are watched for a line-up (localizer.filter.lost)
        if accepted:
            self.rejected_frames = 0
            self.misfits.clear()
            self._history.clear()  # the replay starts after the last frame that fitted
            self.last_fix = float(t_capture)
            self._nis.extend(nis)
            self._slip.restart()
        elif any(a.candidates > 0 for a in assoc):
            self.rejected_frames += 1
        if not accepted:
            self.misfits.observe(ms, assoc, self.mount.camera_pose(self.kf.x.reshape(-1)))
        # no _refresh_now here: flush left _now the accumulation of exactly the queued increments
        self._check_lost()
        relocalized = False
        if self.lost and not self._slip.slipping:  # the replay may already have found the vehicle
            confirmed = self.relocalizer.confirmed()
            if confirmed is not None:
                self._adopt(confirmed, t_capture)
                relocalized = True
        result = FrameResult(t_capture, tuple(assoc), np.asarray(nis), accepted, self.lost, relocalized,
                             len(self.relocalizer.hypotheses), self.status)
        return with_refused(result, keep, len(fused)) if refused else result

    def _wide_frame(self, t: float, ms: list[Measurement], keep: list[int], n: int) -> FrameResult:
        """A frame while the estimate is wide: the mixture reweighed by it (module docstring)."""
        informative = [self.relocalizer.is_evidence(m) for m in ms]
        explained, assoc, nis = self.wide.update(ms, informative)
        self.rejections += len(ms) - len(nis)
        if explained:
            self.last_fix = float(t)
            self._history.clear()
            self._slip.restart()
        if self.wide.components:
            self._from_wide()
        self._check_lost()
        result = FrameResult(t, tuple(assoc), np.asarray(nis), len(nis), self.lost, False, self.hypotheses,
                             self.status)
        return with_refused(result, keep, n) if len(keep) != n else result

    def _refuse(self, reason: str) -> None:
        self._refusals[reason] = self._refusals.get(reason, 0) + 1

    def diagnostics(self) -> dict:
        """The filter's state for whoever watches it: ``status``, ``lost_reason``,
        ``position_sigma`` (m) and ``heading_sigma`` (rad) of filterpy's ``P``, ``nis`` of
        filterpy's last update (``y``, ``S``; nan before any), ``hypotheses`` (:attr:`hypotheses`),
        the counters ``rejections``, ``relocalizations``, ``lost_events``, ``wide_events`` (times
        the estimate became a wide belief), and ``refusals``: inputs refused, by reason
        (:data:`~localizer.filter.limits.REFUSAL_REASONS`)."""
        P = self.kf.P
        refusals = dict(self._refusals)
        for reason, n in self.relocalizer.refusals.items():
            refusals[reason] = refusals.get(reason, 0) + n
        try:
            last_nis = nis(self.kf) if np.any(self.kf.S) else math.nan
        except np.linalg.LinAlgError:
            last_nis = math.nan
        return {"status": self.status, "lost_reason": self.lost_reason, "time": self.time,
                "position_sigma": position_sigma(P), "heading_sigma": math.sqrt(max(P.item(2, 2), 0.0)),
                "nis": last_nis, "rejections": self.rejections, "relocalizations": self.relocalizations,
                "lost_events": self.lost_events, "hypotheses": self.hypotheses, "wide_events": self.wide_events,
                "refusals": refusals}

    def _refresh_now(self) -> None:
        self._now.reset()
        for _, ds, dth, slip in self._pending:
            self._now.add(ds, dth, slip)

    def _relocalize(self, t: float, ms: list[Measurement]) -> FrameResult:
        reloc = self.relocalizer
        confirmed = reloc.process(ms, evidence=not self._slip.slipping) if ms else None
        self.rejections += len(ms)
        # not while the wheels may be slipping: the hypotheses' odometry is not to be trusted
        if confirmed is not None and not self._slip.slipping:
            self._adopt(confirmed, t)
        else:
            confirmed = None
        return FrameResult(t, tuple(), np.zeros(0), 0, self.lost, confirmed is not None,
                           len(reloc.hypotheses), self.status)

    def _adopt(self, confirmed: Hypothesis, t: float) -> None:
        """Take the confirmed hypothesis as the state (at the filter time ``t``)."""
        self.kf.x = confirmed.x.reshape(3, 1).copy()
        self.kf.x[2, 0] = wrap_angle(float(self.kf.x[2, 0]))
        self.kf.P = confirmed.P.copy()
        self._recovered(t)
        self.relocalizations += 1
        self._refresh_now()

    def _recovered(self, t: float) -> None:
        self.lost = False
        self.lost_reason = None
        self.wide = None
        self.rejected_frames = 0
        self.misfits.clear()
        self._nis.clear()
        self._history.clear()
        self._slip.restart()
        self.last_fix = float(t)
        self.relocalizer.reset()

    def reset(self, x, P) -> None:
        """Set the filter state to ``x`` (3,), ``P`` (3, 3) at the current filter time; not lost."""
        x, P = check_state("PoseEKF.reset", x, P)
        self.kf.x = x.reshape(3, 1).copy()
        self.kf.P = P
        self._recovered(self.time)

