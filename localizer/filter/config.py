"""Settings of the pose filter (:class:`~localizer.filter.ekf.PoseEKF`), in one frozen dataclass."""
from __future__ import annotations

import math
from dataclasses import dataclass

from localizer.filter.association import GateConfig, gate_threshold
from localizer.filter.motion import OdometryNoise
from localizer.filter.relocalize import RelocalizeConfig
from localizer.filter.wide import WideConfig
from localizer.numeric import check_number, check_numbers

__all__ = ["FilterConfig"]


@dataclass(frozen=True)
class FilterConfig:
    """Settings of :class:`PoseEKF`.

    Attributes:
        noise: odometry motion-noise model.
        gate: association settings.
        relocalize: re-localization settings.
        wide: the wide belief (:mod:`localizer.filter.wide`) the filter keeps, still tracking, when
            odometry alone has spread its estimate past ``lost_position_sigma`` or
            ``lost_heading_sigma``; None (the default): it declares itself lost there instead.
            Opt-in: under uniform random driving it keeps tracking about 90 % of steps instead
            of 30-75 %, but its mixture can collapse onto a look-alike target's component, a
            confident wrong pose the one Gaussian does not produce (BENCHMARKS.md, availability
            under an agent's driving: ``agvsim bench availability --wide``).
        measurement_floor: (σ_d m, σ_β rad, σ_α rad) added in quadrature to every
            observation's covariance (camera mount and map survey errors).
        lost_position_sigma: position σ (m) above which one Gaussian is given up (for the wide
            belief; lost without one).
        lost_heading_sigma: heading σ (rad) above which one Gaussian is given up (the same).
        lost_rejected_frames: frames in a row with observations and a target predicted in view,
            none accepted, before lost.
        lost_misfit_frames: frames whose grossly misfitting detections line up (module
            docstring) before lost.
        misfit_d2: D² (dimensionless) above which a refused detection misfits grossly.
        misfit_yaw: how alike (rad) the facing of two frames' misfitting detections must be to
            line up.
        misfit_radius: how close (m) two frames' misfitting detections, placed in the map from
            the estimate, must be to line up.
        nis_window: accepted updates whose mean NIS is watched.
        nis_probability: lost when that mean exceeds the χ²(3 ``nis_window``) quantile of this
            probability over ``nis_window``.
        lost_sigma: (σ_x m, σ_y m, σ_θ rad) the covariance is set to when the filter finds
            itself lost: the state is then a guess, and says so to whoever reads only the
            covariance.
        contact_slip: share of the wheel motion counted while in contact that may be slip
            (:class:`~localizer.filter.motion.ContactSlip`; 0 turns it off). Twice the motion:
            besides the wheels' slip, the contact's impulses shove and turn the chassis, which
            no encoder counts. Under uniform random actions (``agvsim bench availability``,
            12 seeds x 2,000 steps) 1 left 2.6 % (PlantFloor-v2) and 1.75 % (Corridor-v2) of the
            steps outside 3 sigma while tracking (on PlantFloor mostly after a contact); 2 leaves 0.06 % and
            0.9 %, and tracks 3 % of the steps less (the wider estimate is more often lost).
    """

    noise: OdometryNoise = OdometryNoise()
    gate: GateConfig = GateConfig()
    relocalize: RelocalizeConfig = RelocalizeConfig()
    wide: WideConfig | None = None
    measurement_floor: tuple[float, float, float] = (0.002, 0.0003, 0.002)  # m, rad, rad
    lost_position_sigma: float = 1.0  # m
    lost_heading_sigma: float = math.radians(20.0)  # rad
    lost_rejected_frames: int = 12
    lost_misfit_frames: int = 3
    misfit_yaw: float = math.radians(10.0)  # rad
    misfit_d2: float = 100.0  # D², dimensionless
    misfit_radius: float = 0.3  # m
    nis_window: int = 10
    nis_probability: float = 0.9999  # dimensionless
    lost_sigma: tuple[float, float, float] = (100.0, 100.0, math.pi)  # m, m, rad
    contact_slip: float = 2.0  # dimensionless

    def __post_init__(self) -> None:
        check_numbers("FilterConfig.measurement_floor", self.measurement_floor, 3, low=0.0)
        for name, unit in (("lost_position_sigma", "m"), ("lost_heading_sigma", "rad")):
            check_number(f"FilterConfig.{name}", getattr(self, name), low=0.0, low_open=True, unit=unit)
        check_number("FilterConfig.misfit_d2", self.misfit_d2, low=0.0, low_open=True, unit="D²")
        for name in ("lost_rejected_frames", "lost_misfit_frames", "nis_window"):
            check_number(f"FilterConfig.{name}", getattr(self, name), low=1, integer=True)
        check_number("FilterConfig.nis_probability", self.nis_probability, low=0.0, high=1.0, low_open=True,
                     high_open=True)
        check_number("FilterConfig.contact_slip", self.contact_slip, low=0.0)
        check_numbers("FilterConfig.lost_sigma", self.lost_sigma, 3, low=0.0, low_open=True)
        check_number("FilterConfig.misfit_radius", self.misfit_radius, low=0.0, low_open=True, unit="m")
        check_number("FilterConfig.misfit_yaw", self.misfit_yaw, low=0.0, low_open=True, unit="rad")

    @property
    def nis_limit(self) -> float:
        """The mean NIS over :attr:`nis_window` updates above which the filter is lost."""
        return gate_threshold(self.nis_probability, 3 * self.nis_window) / self.nis_window
