"""When the one-Gaussian estimate is to be given up: the pose filter's loss tests
(:class:`~localizer.filter.ekf.PoseEKF`).

The filter is lost, with the reason :func:`lost_reason` gives, when any of these holds:

* position σ (largest eigenvalue of P_xy) or heading σ beyond ``lost_position_sigma`` /
  ``lost_heading_sigma`` with no wide belief to take over (``FilterConfig.wide=None``, or a
  position σ past its ``max_position_sigma``; otherwise the estimate becomes wide, not lost:
  :func:`becomes_wide`);
* ``lost_rejected_frames`` frames in a row with a target predicted in view whose
  observations were all refused;
* consistent detections that the estimate cannot explain: refused detections that misfit
  grossly (no target of their polarity predicted in view, or the nearest candidate's D² above
  ``misfit_d2``), placed in the map from the estimate, that fall within ``misfit_radius`` of
  one another, facing the same way within ``misfit_yaw``, over ``lost_misfit_frames`` such
  frames in a row (:class:`~localizer.filter.misfits.MisfitWatch`: one real target seen from a
  wrong estimate stays put, as odometry moves the estimate with the vehicle; false detections
  do not line up; a detection that lands on a map target of its polarity facing its way is
  explained, not a misfit, even where the view limits predicted none). It works far from the
  truth, and fast;
* the estimate outside the map's free space (inside a wall or an obstacle, or outside the
  map), when the filter was given ``free_space``;
* the mean NIS of the last ``nis_window`` accepted updates above the χ²(3 ``nis_window``)
  quantile of ``nis_probability`` divided by ``nis_window`` (consistently poor fits).
"""
from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

from localizer.filter.config import FilterConfig
from localizer.filter.update import position_sigma

__all__ = ["Evidence", "becomes_wide", "lost_reason"]


class Evidence(NamedTuple):
    """What the filter has seen since its last good fit.

    Attributes:
        rejected_frames: consecutive frames with a target predicted in view, none accepted.
        misfit_frames: the longest line-up of misfitting detections (frames).
        nis: the latest accepted updates' NIS (at most ``nis_window``).
        nis_limit: the mean NIS above which the fits are consistently poor.
    """

    rejected_frames: int
    misfit_frames: int
    nis: Sequence[float]
    nis_limit: float


def _sigmas(P: np.ndarray) -> tuple[float, float]:
    return position_sigma(P), math.sqrt(max(P.item(2, 2), 0.0))


def becomes_wide(P: np.ndarray, config: FilterConfig) -> bool:
    """Whether the covariance ``P`` (3, 3) is past the one-Gaussian limits and a wide belief
    (``config.wide``) can hold it."""
    pos, heading = _sigmas(P)
    return ((pos > config.lost_position_sigma or heading > config.lost_heading_sigma)
            and config.wide is not None and pos <= config.wide.max_position_sigma)


def lost_reason(x: np.ndarray, P: np.ndarray, config: FilterConfig, evidence: Evidence,
                free_space=None) -> str | None:
    """Why the estimate ``x`` (3,), ``P`` (3, 3) is lost (module docstring), or None.

    ``free_space``: optional ``(x m, y m) -> bool``, where the vehicle can be."""
    cfg = config
    pos_sigma, heading_sigma = _sigmas(P)
    nis = evidence.nis
    if pos_sigma > cfg.lost_position_sigma:
        return f"position sigma {pos_sigma:.2f} m > {cfg.lost_position_sigma:g} m"
    if heading_sigma > cfg.lost_heading_sigma:
        return f"heading sigma {math.degrees(heading_sigma):.1f} deg > {math.degrees(cfg.lost_heading_sigma):g} deg"
    if evidence.rejected_frames >= cfg.lost_rejected_frames:
        return (f"{evidence.rejected_frames} frames in a row with a target predicted in view "
                "and every detection refused")
    if evidence.misfit_frames >= cfg.lost_misfit_frames:
        return (f"detections in {evidence.misfit_frames} frames line up where the estimate "
                "predicts no target that fits them")
    if len(nis) == cfg.nis_window and sum(nis) / cfg.nis_window > evidence.nis_limit:
        return (f"mean NIS {sum(nis) / cfg.nis_window:.1f} over the last {cfg.nis_window} "
                f"updates > {evidence.nis_limit:.1f}")
    if free_space is not None:
        px, py = float(x[0]), float(x[1])
        if not free_space(px, py):
            return f"estimate ({px:.2f}, {py:.2f}) m is not in free space (in a wall or obstacle, or off the map)"
    return None
