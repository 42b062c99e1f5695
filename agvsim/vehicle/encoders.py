"""Wheel encoders and their error model.

The encoders read the *true* wheel motion. The true vehicle differs from its
nominal parameters (Borenstein's UMBmark systematic errors), its wheels slip
a little at random, and they spin against obstacles; the counts are
quantized. Dead reckoning (:mod:`agvsim.vehicle.odometry`) then integrates
the counts with the *nominal* parameters, so it drifts.

Systematic errors (UMBmark, Borenstein & Feng 1996):
    E_d = D_R / D_L   ratio of the true right and left wheel diameters, whose
                      mean equals the nominal diameter, so
                      D_R = 2 E_d / (E_d + 1) D,  D_L = 2 / (E_d + 1) D;
    E_b = b_true / b_nominal   true over nominal wheelbase (track width).

Random error: each wheel's arc length s over a physics step gets zero-mean
Gaussian noise of variance ``wheel_noise**2 * |s|`` (m²), so the variance
grows linearly with the distance the wheel rolls (a random walk).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from localizer.numeric import TWO_PI, check_choice, check_number

_NOISE_BLOCK = 4096  # normals drawn from the generator at a time


@dataclass(frozen=True)
class OdometryErrorModel:
    """What makes dead reckoning drift; each part switchable.

    Attributes:
        wheel_noise: per-wheel random arc error, σ = wheel_noise * sqrt(|s|)
            with s the wheel's arc length (m^(1/2)); 0 disables it.
        ed: UMBmark E_d = D_R / D_L (dimensionless); 1 disables it.
        eb: UMBmark E_b = b_true / b_nominal (dimensionless); 1 disables it.
        ticks_per_rev: encoder counts per wheel revolution; 0 disables
            quantization (the counts are then real numbers).
        slip_in_contact: share (0..1) of the commanded wheel motion that the
            wheels spin through while the chassis is in contact with an
            obstacle (pushing against a wall); 0 disables it.
    """

    wheel_noise: float = 0.0  # m^(1/2)
    ed: float = 1.0  # dimensionless
    eb: float = 1.0  # dimensionless
    ticks_per_rev: int = 0  # counts / rev
    slip_in_contact: float = 0.0  # share of commanded wheel motion

    def __post_init__(self) -> None:
        check_number("OdometryErrorModel.wheel_noise", self.wheel_noise, low=0.0, unit="m^(1/2)")
        check_number("OdometryErrorModel.ed", self.ed, low=0.0, low_open=True)
        check_number("OdometryErrorModel.eb", self.eb, low=0.0, low_open=True)
        check_number("OdometryErrorModel.slip_in_contact", self.slip_in_contact, low=0.0, high=1.0)
        check_number("OdometryErrorModel.ticks_per_rev", self.ticks_per_rev, low=0.0, integer=True)

    @classmethod
    def preset(cls, name: str) -> "OdometryErrorModel":
        """The model called ``name``, one of :data:`PRESETS` (``ideal``: no error; ``typical``:
        a well-kept AGV, about 1 % of distance; ``worn``: uneven tyres, worn encoders, several %)."""
        check_choice("odometry preset", name, PRESETS)
        return cls(**_PRESET_FIELDS[name])

    def without(self, *parts: str) -> "OdometryErrorModel":
        """A copy with the named parts switched off (``noise``, ``systematic``,
        ``quantization``, ``slip``)."""
        off = {"noise": {"wheel_noise": 0.0}, "systematic": {"ed": 1.0, "eb": 1.0},
               "quantization": {"ticks_per_rev": 0}, "slip": {"slip_in_contact": 0.0}}
        changes: dict[str, float] = {}
        for part in parts:
            if part not in off:
                raise ValueError(f"unknown odometry error part {part!r}; expected one of {sorted(off)}")
            changes.update(off[part])
        return replace(self, **changes)


#: preset name -> its fields; the one list of presets (CLI choices, env validation, docs).
_PRESET_FIELDS: dict[str, dict[str, float]] = {
    "ideal": {},
    # measured on plant_floor's default route (4 seeds): ~1.2 % of distance at 100 m
    "typical": {"wheel_noise": 0.001, "ed": 1.0002, "eb": 1.001, "ticks_per_rev": 4096, "slip_in_contact": 1.0},
    # same route: ~5 % of distance at 100 m
    "worn": {"wheel_noise": 0.002, "ed": 1.001, "eb": 1.004, "ticks_per_rev": 1024, "slip_in_contact": 1.0},
}

#: The odometry error presets by name.
PRESETS: tuple[str, ...] = tuple(_PRESET_FIELDS)


@dataclass(frozen=True)
class WheelTicks:
    """Cumulative encoder counts (left, right); real numbers when unquantized."""

    left: float
    right: float


class EncoderModel:
    """Turns the chassis's true motion into wheel encoder counts.

    Args:
        wheel_radius: nominal wheel radius r (m).
        track_width: nominal wheelbase b (m).
        errors: the error model.
        rng: the run's generator; noise is drawn from it in blocks.
    """

    def __init__(self, wheel_radius: float, track_width: float,
                 errors: OdometryErrorModel, rng: np.random.Generator) -> None:
        self.errors = errors
        self.rng = rng
        self.ticks_per_rev = errors.ticks_per_rev
        # counts per metre of rim for the unquantized case uses a nominal 1 count/rad
        self._counts_per_rad = errors.ticks_per_rev / TWO_PI if errors.ticks_per_rev else 1.0
        self._r_right = wheel_radius * 2.0 * errors.ed / (errors.ed + 1.0)  # m, true
        self._r_left = wheel_radius * 2.0 / (errors.ed + 1.0)  # m, true
        self._half_track = 0.5 * track_width * errors.eb  # m, true
        self._noise = errors.wheel_noise
        self._slip = errors.slip_in_contact
        self._phi_left = 0.0  # rad, true cumulative wheel rotation
        self._phi_right = 0.0
        self._block: list[float] = []
        self._next = 0

    @property
    def counts_per_rad(self) -> float:
        """Encoder counts per radian of wheel rotation."""
        return self._counts_per_rad

    def advance(self, ds: float, dtheta: float, in_contact: bool = False,
                commanded: tuple[float, float] = (0.0, 0.0), dt: float = 0.0) -> None:
        """Record one physics step of true chassis motion.

        Args:
            ds: true arc length travelled by the chassis centre (m).
            dtheta: true heading change (rad).
            in_contact: whether the chassis touches an obstacle.
            commanded: commanded rim speeds (left, right) in m/s.
            dt: step length (s), used with ``commanded`` for slip.
        """
        self.advance_steps((ds,), (dtheta,), (commanded if in_contact else None,), dt)

    def advance_steps(self, ds: list, dtheta: list, wheels: list, dt: float) -> tuple[list, list]:
        """:meth:`advance` then :meth:`counts` for each physics step of a control step, in one loop.

        Args:
            ds, dtheta: per physics step, the chassis's true arc length (m) and heading change (rad).
            wheels: per physics step, the commanded rim speeds (left, right) m/s when the chassis
                is in contact, else None.
            dt: physics step (s).

        Returns:
            (left, right): the cumulative counts after each step.
        """
        half_track, slip, noise = self._half_track, self._slip, self._noise
        r_left, r_right, per_rad = self._r_left, self._r_right, self._counts_per_rad
        phi_left, phi_right = self._phi_left, self._phi_right
        quantized = bool(self.ticks_per_rev)
        floor, sqrt = math.floor, math.sqrt
        block, i = self._block, self._next
        n_block = len(block)
        lefts, rights = [], []
        for step_ds, step_dtheta, commanded in zip(ds, dtheta, wheels):
            s_left = step_ds - step_dtheta * half_track
            s_right = step_ds + step_dtheta * half_track
            if commanded is not None and slip:
                s_left += slip * (commanded[0] * dt - s_left)
                s_right += slip * (commanded[1] * dt - s_right)
            if noise:
                if i + 2 > n_block:  # the next two standard normals from the block
                    block = self.rng.standard_normal(_NOISE_BLOCK).tolist()
                    n_block = len(block)
                    i = 0
                s_left += noise * sqrt(abs(s_left)) * block[i]
                s_right += noise * sqrt(abs(s_right)) * block[i + 1]
                i += 2
            phi_left += s_left / r_left
            phi_right += s_right / r_right
            left = phi_left * per_rad
            right = phi_right * per_rad
            if quantized:
                lefts.append(float(floor(left)))
                rights.append(float(floor(right)))
            else:
                lefts.append(left)
                rights.append(right)
        self._phi_left, self._phi_right = phi_left, phi_right
        self._block, self._next = block, i
        return lefts, rights

    def counts(self) -> tuple[float, float]:
        """Cumulative counts (left, right) as the encoder interface reports them."""
        left = self._phi_left * self._counts_per_rad
        right = self._phi_right * self._counts_per_rad
        if self.ticks_per_rev:
            return float(math.floor(left)), float(math.floor(right))
        return left, right

    def read(self) -> WheelTicks:
        """Cumulative counts as a :class:`WheelTicks`."""
        return WheelTicks(*self.counts())
