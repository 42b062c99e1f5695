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

Slip (:class:`~localizer.filter.motion.ContactSlip`): while the vehicle reports contact
(``add_odometry(..., in_contact=True)``: its bumper), the odometry noise grows with the wheel
motion counted since the contact began (``contact_slip``: 1 = all of it may be slip), so the
covariance stays honest while the wheels spin against a wall.

Status (:data:`STATUSES`): ``tracking``; ``lost`` (no live re-localization hypothesis) or
``relocalizing`` (hypotheses alive, none confirmed yet). The filter declares itself lost,
with the reason (:attr:`PoseEKF.lost_reason`), when any of these holds:

* position σ (largest eigenvalue of P_xy) above ``lost_position_sigma``, or heading σ above
  ``lost_heading_sigma``;
* ``lost_rejected_frames`` frames in a row with a target predicted in view whose
  observations were all refused;
* consistent detections that the estimate cannot explain: refused detections that misfit
  grossly (no target of their polarity predicted in view, or the nearest candidate's D² above
  ``misfit_d2``), placed in the map from the estimate, that fall within ``misfit_radius`` of
  one another, facing the same way within ``misfit_yaw``, over ``lost_misfit_frames`` such
  frames in a row (one real target seen from a wrong estimate stays put, as odometry moves the
  estimate with the vehicle; false detections do not line up). It works far from the truth, and fast;
* the estimate outside the map's free space (inside a wall or an obstacle, or outside the
  map), when the filter was given ``free_space``;
* the mean NIS of the last ``nis_window`` accepted updates above the χ²(3 ``nis_window``)
  quantile of ``nis_probability`` divided by ``nis_window`` (consistently poor fits);
* told so: :meth:`PoseEKF.declare_lost` (an unknown start pose).

Then :class:`~localizer.filter.relocalize.Relocalizer` takes the frames until a hypothesis is
confirmed (never while a contact's wheel slip is still counting: the odometry the hypotheses
ride on is not to be trusted then; global re-localization from nothing: the main state plays
no part in it). While tracking, the filter keeps the frames since the last one with an accepted
observation (at most ``relocalize.replay_frames``), their measurements and the odometry between
them; on becoming lost it replays them into the re-localization first, so the detections that
were refused are the first evidence (a kidnapped vehicle has often seen two targets by the time
it knows it is lost). Inputs are checked at the boundary (:mod:`localizer.filter.limits`).
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
from localizer.filter.measurement import Measurement, TargetMap, informative
from localizer.filter.misfits import line_up
from localizer.model.mount import CameraMount
from localizer.filter.motion import ContactSlip, OdometryAccumulator, compose_jacobians
from localizer.filter.relocalize import Hypothesis, Relocalizer
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
        self.rejected_frames = 0  # consecutive frames with a target predicted in view, none accepted
        self.misfit_frames = 0  # the longest line-up of grossly misfitting detections (frames)
        # misfitting detections since the last accepted one placed in the map:
        # (x m, y m, facing rad, polarity, support frames, misfit frame number)
        self._misfits: list[tuple[float, float, float, str | None, int, int]] = []
        self._misfit_count = 0  # frames with misfitting detections so far
        self.rejections = 0  # observations not accepted, total
        self._refusals: dict[str, int] = {}  # inputs refused at the boundary, by reason (diagnostics)
        self.relocalizations = 0
        self.lost_events = 0
        self.last_fix = float(t0)  # s: the last accepted update (or confirmed re-localization)
        self._nis = deque(maxlen=config.nis_window)  # the latest accepted updates' NIS
        # while tracking: [u (3,), Q (3, 3), measurements] per flush / frame, for the replay
        self._history: deque = deque(maxlen=config.relocalize.replay_frames)
        self._flush_entry = None  # the history entry the last flush made
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
        self._flush_entry = None
        while self._pending and self._pending[0][0] <= t + 1e-9:
            _, ds, dth, slip = self._pending.popleft()
            acc.add(ds, dth, slip)
        if acc.steps:
            self._predict(acc.u, acc.Q)
            self._refresh_now()
            if not self.lost:
                self._flush_entry = [acc.u, acc.Q, ()]
                self._history.append(self._flush_entry)
        self.time = float(t)
        self._check_lost()

    def _predict(self, u: np.ndarray, Q: np.ndarray) -> None:
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

    def _check_lost(self) -> None:
        if self.lost:
            return
        cfg = self.config
        P = self.kf.P
        pos_sigma = position_sigma(P)
        heading_sigma = math.sqrt(max(P.item(2, 2), 0.0))
        reason = None
        if pos_sigma > cfg.lost_position_sigma:
            reason = f"position sigma {pos_sigma:.2f} m > {cfg.lost_position_sigma:g} m"
        elif heading_sigma > cfg.lost_heading_sigma:
            reason = (f"heading sigma {math.degrees(heading_sigma):.1f} deg > "
                      f"{math.degrees(cfg.lost_heading_sigma):g} deg")
        elif self.rejected_frames >= cfg.lost_rejected_frames:
            reason = (f"{self.rejected_frames} frames in a row with a target predicted in view "
                      "and every detection refused")
        elif self.misfit_frames >= cfg.lost_misfit_frames:
            reason = (f"detections in {self.misfit_frames} frames line up where the estimate "
                      "predicts no target that fits them")
        elif len(self._nis) == cfg.nis_window and sum(self._nis) / cfg.nis_window > self._nis_limit:
            reason = (f"mean NIS {sum(self._nis) / cfg.nis_window:.1f} over the last {cfg.nis_window} "
                      f"updates > {self._nis_limit:.1f}")
        elif self.free_space is not None:
            x, y = self.kf.x.item(0), self.kf.x.item(1)
            if not self.free_space(x, y):
                reason = f"estimate ({x:.2f}, {y:.2f}) m is not in free space (in a wall or obstacle, or off the map)"
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
        self.kf.P = np.diag(np.asarray(self.config.lost_sigma, dtype=float) ** 2)
        reloc = self.relocalizer
        reloc.reset()
        for u, Q, ms in self._history:  # the recent frames first (module docstring)
            reloc.predict(u, Q)
            if ms:
                reloc.process(ms)
        self._history.clear()

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
            if self._flush_entry is not None and self._history and self._history[-1] is self._flush_entry:
                self._flush_entry[2] = ms
            else:
                self._history.append([np.zeros(3), np.zeros((3, 3)), ms])
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
        # observations fitted (rejected), or when there were detections and no target of their
        # polarity is predicted in view at all (unexplained: the estimate is elsewhere, or they
        # are false detections, which do not come several frames in a row)
        if accepted:
            self.rejected_frames = 0
            self.misfit_frames = 0
            self._misfits.clear()
            self._history.clear()  # the replay starts after the last frame that fitted
            self.last_fix = float(t_capture)
            self._nis.extend(nis)
            self._slip.restart()
        elif any(a.candidates > 0 for a in assoc):
            self.rejected_frames += 1
        if not accepted:
            gross = [ms[a.observation] for a in assoc if a.d2 > self.config.misfit_d2]
            if gross:
                self._line_up(gross)
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

    def _refuse(self, reason: str) -> None:
        self._refusals[reason] = self._refusals.get(reason, 0) + 1

    def diagnostics(self) -> dict:
        """The filter's state for whoever watches it: ``status``, ``lost_reason``,
        ``position_sigma`` (m) and ``heading_sigma`` (rad) of filterpy's ``P``, ``nis`` of
        filterpy's last update (``y``, ``S``; nan before any), the counters ``rejections``,
        ``relocalizations``, ``lost_events``, and ``refusals``: inputs refused, by reason
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
                "lost_events": self.lost_events, "refusals": refusals}

    def _line_up(self, ms: list[Measurement]) -> None:
        """Place a frame's grossly misfitting detections in the map from the estimate and count
        over how many such frames in a row (one skipped allowed) each lines up
        (:attr:`misfit_frames`, the longest; :func:`localizer.filter.misfits.line_up`)."""
        self._misfit_count += 1
        past = [e for e in self._misfits if e[5] >= self._misfit_count - 2]  # the two frames before this one
        now = line_up(ms, self.mount.camera_pose(self.kf.x.reshape(-1)), past, self._misfit_count,
                      self.config.misfit_radius, self.config.misfit_yaw)
        self.misfit_frames = max([self.misfit_frames] + [e[4] for e in now])
        self._misfits = now + past

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
        self.rejected_frames = 0
        self.misfit_frames = 0
        self._misfits.clear()
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

