"""The pose filter's limits and records: what it accepts at its boundary, how much uncertainty it
represents, its states and what fusing a frame did (:mod:`localizer.filter.ekf` uses them)."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from localizer.filter.association import Association
from localizer.filter.update import position_sigma
from localizer.numeric import check_number

__all__ = ["FrameResult", "LOST", "MAX_HEADING_SIGMA", "MAX_ODOMETRY_STEP", "MAX_ODOMETRY_TURN", "MAX_POSITION_SIGMA",
           "RELOCALIZING", "STATUSES", "TIME_SLACK", "TRACKING", "UNINFORMATIVE", "Refused", "check_frame_time",
           "check_odometry", "check_state", "with_refused",
           "within_bounds", "REFUSAL_REASONS"]

#: largest |Δs| (m) of one odometry increment: a control step moves centimetres
MAX_ODOMETRY_STEP = 10.0  # m
#: largest |Δθ| (rad) of one odometry increment
MAX_ODOMETRY_TURN = 2.0 * math.pi  # rad
#: the covariance the filter represents is bounded: position σ beyond this (or a covariance not
#: finite) is lost, and the covariance is set back to ``FilterConfig.lost_sigma``
MAX_POSITION_SIGMA = 1.0e4  # m
#: the same for the heading σ
MAX_HEADING_SIGMA = 2.0 * math.pi  # rad
#: the association status of an observation refused at the filter's boundary: its covariance
#: (floor included) is not positive definite or a σ exceeds ``MAX_MEASUREMENT_SIGMA``
UNINFORMATIVE = "uninformative"
#: slack (s) on time stamps (the filter's frame times are rounded sums of control steps)
TIME_SLACK = 1e-9  # s

#: the reasons :meth:`localizer.filter.ekf.PoseEKF.diagnostics` counts refused inputs under: the
#: filter's, then the re-localizer's (:class:`localizer.filter.relocalize.Relocalizer`)
REFUSAL_REASONS = ("odometry_time", "odometry_increment", "odometry_contact", "frame_time", "measurement_invalid",
                   "measurement_uninformative", "covariance_bound", "uninformative_match", "unsound_seed",
                   "imprecise_confirmation")

TRACKING = "tracking"  # the estimate and its covariance are to be trusted
LOST = "lost"  # the filter does not know where the vehicle is, and has no candidate pose
RELOCALIZING = "relocalizing"  # lost, with candidate poses (hypotheses) being tested
#: the filter's states, in the order of their codes (the env's ``status`` observation)
STATUSES = (TRACKING, LOST, RELOCALIZING)


@dataclass(frozen=True)
class FrameResult:
    """What fusing one frame did.

    Attributes:
        time: capture time (s).
        associations: one per observation; while lost, only the observations refused at the
            boundary have one (:data:`UNINFORMATIVE`): the rest went to re-localization.
        nis: (k,) normalised innovation squared of each accepted update (χ²(3) when consistent).
        accepted: number of accepted observations.
        lost: whether the filter is lost after the frame.
        relocalized: whether this frame confirmed a re-localization.
        hypotheses: live re-localization hypotheses after the frame.
        status: the filter's status after the frame (:data:`STATUSES`).
    """

    time: float
    associations: tuple[Association, ...]
    nis: np.ndarray
    accepted: int
    lost: bool
    relocalized: bool
    hypotheses: int
    status: str = TRACKING


def check_state(where: str, x, P, names: tuple[str, str] = ("x", "P")) -> tuple[np.ndarray, np.ndarray]:
    """``x`` (3,) finite and ``P`` (3, 3) finite positive semi-definite with position σ within
    :data:`MAX_POSITION_SIGMA` (P symmetrised), or one ``ValueError``."""
    x = np.asarray(x, dtype=float).reshape(-1)
    P = np.asarray(P, dtype=float)
    if x.shape != (3,) or not np.isfinite(x).all():
        raise ValueError(f"{where}: {names[0]} must be a finite (3,) pose (m, m, rad), got {x!r}")
    if (P.shape != (3, 3) or not np.isfinite(P).all() or np.any(np.linalg.eigvalsh(0.5 * (P + P.T)) < 0)
            or position_sigma(P) > MAX_POSITION_SIGMA or P.item(2, 2) > MAX_HEADING_SIGMA ** 2):
        raise ValueError(f"{where}: {names[1]} must be a finite positive semi-definite (3, 3) matrix with position "
                         f"sigma <= {MAX_POSITION_SIGMA:g} m and heading sigma <= {MAX_HEADING_SIGMA:g} rad, "
                         f"got {P!r}")
    return x, 0.5 * (P + P.T)


class Refused(ValueError):
    """An input refused at the filter's boundary; ``reason`` names the count it adds to
    (:meth:`localizer.filter.ekf.PoseEKF.diagnostics`)."""

    def __init__(self, reason: str, message: str):
        super().__init__(message)
        self.reason = reason


def check_odometry(t, ds, dtheta, in_contact, last: float, slack: float) -> tuple[float, float, float]:
    """``(t, ds, dtheta)`` of an odometry increment, or :class:`Refused`: ``t`` (s) finite and not
    before ``last - slack``; ``ds`` (m), ``dtheta`` (rad) finite within :data:`MAX_ODOMETRY_STEP`
    and :data:`MAX_ODOMETRY_TURN`; ``in_contact`` a bool."""
    try:
        t = check_number("PoseEKF.add_odometry t", t, unit="s")
    except ValueError as exc:
        raise Refused("odometry_time", str(exc)) from None
    if t < last - slack:
        raise Refused("odometry_time", f"PoseEKF.add_odometry t must not decrease: got {t!r} after {last!r} (s)")
    try:
        ds = check_number("PoseEKF.add_odometry ds", ds, low=-MAX_ODOMETRY_STEP, high=MAX_ODOMETRY_STEP, unit="m")
        dtheta = check_number("PoseEKF.add_odometry dtheta", dtheta, low=-MAX_ODOMETRY_TURN, high=MAX_ODOMETRY_TURN,
                              unit="rad")
    except ValueError as exc:
        raise Refused("odometry_increment", str(exc)) from None
    if not isinstance(in_contact, (bool, np.bool_)):
        raise Refused("odometry_contact", f"PoseEKF.add_odometry in_contact must be a bool, got {in_contact!r}")
    return t, ds, dtheta


def check_frame_time(where: str, t, now: float) -> float:
    """``t`` (s) finite and not before the filter time ``now`` (less :data:`TIME_SLACK`), or
    :class:`Refused`."""
    try:
        t = check_number(where, t, unit="s")
    except ValueError as exc:
        raise Refused("frame_time", str(exc)) from None
    if t < now - TIME_SLACK:
        raise Refused("frame_time", f"{where} must be >= the filter time {now!r} s (frames out of order?), got {t!r}")
    return t


def with_refused(result: FrameResult, keep: list[int], n: int) -> FrameResult:
    """``result`` of the ``n`` observations' kept ones (``keep``: their indices) with its
    associations indexed by all ``n``, one :data:`UNINFORMATIVE` for each refused one added (a
    kept one without an association, as while lost, stays without one)."""
    assoc = {keep[a.observation]: replace(a, observation=keep[a.observation]) for a in result.associations}
    kept = set(keep)
    for k in range(n):
        if k not in kept:
            assoc[k] = Association(k, UNINFORMATIVE, -1, "", math.inf, math.inf, 0)
    return replace(result, associations=tuple(assoc[k] for k in sorted(assoc)))


def within_bounds(x: np.ndarray, P: np.ndarray) -> bool:
    """Whether the state ``x`` and covariance ``P`` are finite, with position σ within
    :data:`MAX_POSITION_SIGMA` and heading σ within :data:`MAX_HEADING_SIGMA`."""
    return bool(np.isfinite(P).all() and np.isfinite(x).all() and position_sigma(P) <= MAX_POSITION_SIGMA
                and P.item(2, 2) <= MAX_HEADING_SIGMA ** 2)
