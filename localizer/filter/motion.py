r"""Odometry prediction: composing (Δs, Δθ) increments and their noise.

A control step's odometry increment is an arc of length Δs turning Δθ. In the
frame of the pose at its start it moves the vehicle by (exact for a
constant-curvature arc, as the dead reckoning integrates it)::

    m(Δs, Δθ) = (Δs k cos(Δθ/2), Δs k sin(Δθ/2), Δθ),    k = sinc(Δθ/2) = sin(Δθ/2) / (Δθ/2)

Pose composition ``x ⊕ u`` of a pose x = (px, py, θ) and a relative motion
u = (ux, uy, uφ) given in x's frame::

    x ⊕ u = (px + cos θ ux - sin θ uy,  py + sin θ ux + cos θ uy,  θ + uφ)

    F = ∂(x ⊕ u)/∂x = [[1, 0, -sin θ ux - cos θ uy],      G = ∂(x ⊕ u)/∂u = [[cos θ, -sin θ, 0],
                       [0, 1,  cos θ ux - sin θ uy],                          [sin θ,  cos θ, 0],
                       [0, 0, 1]]                                             [0, 0, 1]]

Between camera frames the increments are accumulated into one relative
motion u with covariance Q_u (:class:`OdometryAccumulator`, O(1) float work
per control step); the filter then predicts once per frame with
``P ← F P Fᵀ + G Q_u Gᵀ``.

Noise model (:class:`OdometryNoise`). Each wheel's arc s gets white noise of
variance ``k_w² |s|`` (the simulator's per-wheel random walk). With
Δs = (s_R + s_L)/2 and Δθ = (s_R - s_L)/b::

    var Δs = k_w² (|s_L| + |s_R|) / 4,  var Δθ = k_w² (|s_L| + |s_R|) / b²,
    cov(Δs, Δθ) = k_w² (|s_R| - |s_L|) / (2 b)

The systematic errors (unequal wheel diameters E_d, wrong wheelbase E_b) are
unknown to the filter. Between corrections they act as a bias that grows
linearly; the model folds them in as extra white noise whose variance per
metre (per radian turned) equals the squared bias rate times ``correlation``,
the typical distance (m) between corrections, so the accumulated variance
over that distance matches the squared bias:

    var Δθ += (e_d / b)² correlation |Δs| + e_b² correlation_turn |Δθ|
    var Δs += e_s² correlation |Δs|

with ``e_d = |E_d - 1|`` (rad of heading per metre times b), ``e_b = |E_b - 1|``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.numeric import check_number

__all__ = ["ContactSlip", "OdometryAccumulator", "OdometryNoise", "arc_motion", "compose", "compose_jacobians"]


@dataclass(frozen=True)
class OdometryNoise:
    """Motion-noise model of the odometry (see the module docstring).

    Attributes:
        wheel_noise: per-wheel random error k_w, σ = k_w sqrt(|s|) (m^(1/2)).
        track_width: nominal wheelbase b (m).
        diameter_bias: |E_d - 1| expected (dimensionless).
        wheelbase_bias: |E_b - 1| expected (dimensionless).
        scale_bias: relative error of Δs expected (dimensionless).
        correlation: distance (m) over which the biases are taken to accumulate.
        correlation_turn: turn (rad) over which the wheelbase bias accumulates.
        inflation: common factor on all variances (>= 1 to be conservative).
    """

    wheel_noise: float = 0.001  # m^(1/2)
    track_width: float = 0.6  # m
    diameter_bias: float = 0.0  # dimensionless
    wheelbase_bias: float = 0.0  # dimensionless
    scale_bias: float = 0.0  # dimensionless
    correlation: float = 10.0  # m
    correlation_turn: float = math.pi  # rad
    inflation: float = 1.0  # dimensionless

    def __post_init__(self) -> None:
        for name, unit in (("wheel_noise", "m^(1/2)"), ("diameter_bias", ""), ("wheelbase_bias", ""),
                           ("scale_bias", "")):
            check_number(f"OdometryNoise.{name}", getattr(self, name), low=0.0, unit=unit)
        for name, unit in (("track_width", "m"), ("correlation", "m"), ("correlation_turn", "rad"),
                           ("inflation", "")):
            check_number(f"OdometryNoise.{name}", getattr(self, name), low=0.0, low_open=True, unit=unit)

    def covariance(self, ds: float, dtheta: float) -> tuple[float, float, float]:
        """(var Δs m², cov(Δs, Δθ) m·rad, var Δθ rad²) of one increment."""
        b = self.track_width
        s_l = abs(ds - 0.5 * b * dtheta)
        s_r = abs(ds + 0.5 * b * dtheta)
        k2 = self.wheel_noise * self.wheel_noise
        var_s = k2 * (s_l + s_r) / 4.0 + self.scale_bias ** 2 * self.correlation * abs(ds)
        var_t = (k2 * (s_l + s_r) / (b * b)
                 + (self.diameter_bias / b) ** 2 * self.correlation * abs(ds)
                 + self.wheelbase_bias ** 2 * self.correlation_turn * abs(dtheta))
        cov = k2 * (s_r - s_l) / (2.0 * b)
        f = self.inflation
        return f * var_s, f * cov, f * var_t


def arc_motion(ds: float, dtheta: float) -> tuple[float, float, float]:
    """m(Δs, Δθ): the relative motion (m, m, rad) of one arc increment."""
    half = 0.5 * dtheta
    k = 1.0 - half * half / 6.0 if abs(half) < 1e-4 else math.sin(half) / half
    return ds * k * math.cos(half), ds * k * math.sin(half), dtheta


def compose(x, u) -> np.ndarray:
    """x ⊕ u (3,) for pose x (3,) and relative motion u (3,); θ is not wrapped."""
    x0, x1, th = np.ravel(x).tolist()
    u0, u1, u2 = np.ravel(u).tolist()
    c, s = math.cos(th), math.sin(th)
    return np.array([x0 + c * u0 - s * u1, x1 + s * u0 + c * u1, th + u2])


def compose_jacobians(x, u) -> tuple[np.ndarray, np.ndarray]:
    """(F, G) = (∂(x ⊕ u)/∂x, ∂(x ⊕ u)/∂u), each (3, 3)."""
    th = np.ravel(x).tolist()[2]
    u0, u1, _ = np.ravel(u).tolist()
    c, s = math.cos(th), math.sin(th)
    # flat lists reshaped: the same arrays as from nested lists, built in half the time
    F = np.array([1.0, 0.0, -s * u0 - c * u1, 0.0, 1.0, c * u0 - s * u1, 0.0, 0.0, 1.0]).reshape(3, 3)
    G = np.array([c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0]).reshape(3, 3)
    return F, G


class OdometryAccumulator:
    """Accumulates odometry increments into one relative motion and its covariance.

    ``u`` (3,) is the motion since the last :meth:`reset` in the frame of the
    pose at that reset; ``Q`` (3, 3) its covariance. Each :meth:`add` costs a
    few float operations (no numpy), so it can run every control step.

    Args:
        noise: the motion-noise model.
    """

    __slots__ = ("noise", "ux", "uy", "uphi", "q", "steps", "distance")

    def __init__(self, noise: OdometryNoise) -> None:
        self.noise = noise
        self.reset()

    def reset(self) -> None:
        """Start a new accumulation (u = 0, Q = 0)."""
        self.ux = self.uy = self.uphi = 0.0
        self.q = [0.0] * 6  # upper triangle of Q: xx, xy, xphi, yy, yphi, phiphi
        self.steps = 0
        self.distance = 0.0  # m, sum of |Δs|

    @property
    def u(self) -> np.ndarray:
        """(3,) accumulated relative motion (m, m, rad)."""
        return np.array([self.ux, self.uy, self.uphi])

    @property
    def Q(self) -> np.ndarray:
        """(3, 3) covariance of :attr:`u`."""
        a, b, c, d, e, f = self.q
        return np.array([a, b, c, b, d, e, c, e, f]).reshape(3, 3)

    def add(self, ds: float, dtheta: float, slip=None) -> None:
        """Append one increment (Δs m, Δθ rad): u ← u ⊕ m(Δs, Δθ), Q ← F Q Fᵀ + G J Σ Jᵀ Gᵀ.

        ``slip``: ``None``, or the extra ``(var Δs m², cov(Δs, Δθ) m·rad, var Δθ rad²)`` of wheel
        slip in this increment (:meth:`ContactSlip.extra`), added to Σ.

        ``J = ∂m/∂(Δs, Δθ) ≈ [[cos(Δθ/2), -Δs/2 sin(Δθ/2)], [sin(Δθ/2), Δs/2 cos(Δθ/2)], [0, 1]]``
        (the sinc factor's derivative is dropped: Δθ per control step is small).

        Runs every control step: :func:`arc_motion` and :meth:`OdometryNoise.covariance` are
        written out here with their arithmetic unchanged (operation for operation, so the
        results are the same to the bit).
        """
        if not (math.isfinite(ds) and math.isfinite(dtheta)):
            raise ValueError(f"odometry increment must be finite, got ds={ds!r}, dtheta={dtheta!r}")
        cos, sin = math.cos, math.sin
        # m(Δs, Δθ) (arc_motion)
        half = 0.5 * dtheta
        k = 1.0 - half * half / 6.0 if abs(half) < 1e-4 else sin(half) / half
        ch, sh = cos(half), sin(half)
        mx, my, mphi = ds * k * ch, ds * k * sh, dtheta
        c, s = cos(self.uphi), sin(self.uphi)
        # F = [[1, 0, f02], [0, 1, f12], [0, 0, 1]]
        f02 = -s * mx - c * my
        f12 = c * mx - s * my
        a, b, cc, d, e, f = self.q
        # F Q F^T
        a2 = a + 2 * f02 * cc + f02 * f02 * f
        b2 = b + f02 * e + f12 * cc + f02 * f12 * f
        c2 = cc + f02 * f
        d2 = d + 2 * f12 * e + f12 * f12 * f
        e2 = e + f12 * f
        # G J Σ J^T G^T with Σ = [[vs, cst], [cst, vt]] (OdometryNoise.covariance)
        nz = self.noise
        bw = nz.track_width
        s_l = abs(ds - 0.5 * bw * dtheta)
        s_r = abs(ds + 0.5 * bw * dtheta)
        k2 = nz.wheel_noise * nz.wheel_noise
        adS = abs(ds)
        var_s = k2 * (s_l + s_r) / 4.0 + nz.scale_bias ** 2 * nz.correlation * adS
        var_t = (k2 * (s_l + s_r) / (bw * bw)
                 + (nz.diameter_bias / bw) ** 2 * nz.correlation * adS
                 + nz.wheelbase_bias ** 2 * nz.correlation_turn * abs(dtheta))
        cst = k2 * (s_r - s_l) / (2.0 * bw)
        infl = nz.inflation
        vs, cst, vt = infl * var_s, infl * cst, infl * var_t
        if slip is not None:
            vs, cst, vt = vs + slip[0], cst + slip[1], vt + slip[2]
        # J rows in the step frame: jx = (ch, -ds/2 sh), jy = (sh, ds/2 ch), jphi = (0, 1)
        # rotate rows by the accumulated heading (G)
        gx0, gx1 = c * ch - s * sh, -0.5 * ds * (c * sh + s * ch)
        gy0, gy1 = s * ch + c * sh, 0.5 * ds * (c * ch - s * sh)
        # quad(p, q) = p0 q0 vs + (p0 q1 + p1 q0) cst + p1 q1 vt, with gphi = (0.0, 1.0)
        self.q = [a2 + (gx0 * gx0 * vs + (gx0 * gx1 + gx1 * gx0) * cst + gx1 * gx1 * vt),
                  b2 + (gx0 * gy0 * vs + (gx0 * gy1 + gx1 * gy0) * cst + gx1 * gy1 * vt),
                  c2 + (gx0 * 0.0 * vs + (gx0 * 1.0 + gx1 * 0.0) * cst + gx1 * 1.0 * vt),
                  d2 + (gy0 * gy0 * vs + (gy0 * gy1 + gy1 * gy0) * cst + gy1 * gy1 * vt),
                  e2 + (gy0 * 0.0 * vs + (gy0 * 1.0 + gy1 * 0.0) * cst + gy1 * 1.0 * vt),
                  f + vt]
        self.ux += c * mx - s * my
        self.uy += s * mx + c * my
        self.uphi += mphi
        self.steps += 1
        self.distance += adS


class ContactSlip:
    r"""Wheel slip while the vehicle touches a wall or obstacle: extra odometry noise.

    Pushing against something, the wheels spin and the encoders count motion the vehicle
    never made (the simulator's ``slip_in_contact``; a real AGV knows its bumper state). The
    error is not white: over one contact it grows with the wheel motion counted since the
    contact began. Each wheel's slip error is taken as ``σ_w = k D_w``, ``D_w`` the wheel's
    counted arc length (m) since the contact began and ``k`` :attr:`fraction` (1: the whole of
    it may be slip). Per increment the variance added is the growth of that bias's variance,
    so a contact's increments sum to exactly ``(k D_w)²`` per wheel; for the pose increment,
    as the wheel noise (:class:`OdometryNoise`)::

        var Δs += (v_L + v_R) / 4,  var Δθ += (v_L + v_R) / b²,  cov(Δs, Δθ) += (v_R - v_L) / (2 b)
        v_w = k² ((D_w + |s_w|)² - D_w²)

    Out of contact nothing is added; the contact's arc lengths start again from zero once the
    vehicle has been free for ``release`` seconds (a bumper that flickers while pushing along
    a wall does not restart the count), and at a fix (:meth:`restart`: the error up to the fix
    is measured, what slips after it is at most the motion counted after it).
    :attr:`slipping` says whether a contact is still counting.

    Args:
        fraction: ``k``, the share of the counted wheel motion that may be slip while in
            contact (dimensionless, >= 0; 0 turns the model off).
        track_width: the wheelbase ``b`` (m).
        release: seconds free of contact after which a contact is over (s).
    """

    __slots__ = ("fraction", "track_width", "release", "arc_left", "arc_right", "last_contact")

    def __init__(self, fraction: float, track_width: float, release: float = 1.0) -> None:
        check_number("ContactSlip.fraction", fraction, low=0.0)
        check_number("ContactSlip.track_width", track_width, low=0.0, low_open=True, unit="m")
        check_number("ContactSlip.release", release, low=0.0, unit="s")
        self.fraction = float(fraction)
        self.track_width = float(track_width)
        self.release = float(release)
        self.arc_left = self.arc_right = 0.0  # m counted since the contact began
        self.last_contact = -math.inf  # s

    @property
    def slipping(self) -> bool:
        """A contact is counting (the odometry may be slipping)."""
        return self.arc_left > 0.0 or self.arc_right > 0.0

    def restart(self) -> None:
        """Count the contact's wheel motion from zero again (after a fix)."""
        self.arc_left = self.arc_right = 0.0

    def extra(self, ds: float, dtheta: float, in_contact: bool, t: float):
        """The slip noise ``(var Δs m², cov m·rad, var Δθ rad²)`` of the increment (Δs m, Δθ rad)
        that ended at ``t`` (s), or ``None`` when not in contact (or the model is off)."""
        if self.fraction == 0.0:
            return None
        if not in_contact:
            if t - self.last_contact > self.release:
                self.arc_left = self.arc_right = 0.0
            return None
        self.last_contact = t
        b = self.track_width
        s_l = abs(ds - 0.5 * b * dtheta)
        s_r = abs(ds + 0.5 * b * dtheta)
        k2 = self.fraction * self.fraction
        dl, dr = self.arc_left, self.arc_right
        v_l = k2 * ((dl + s_l) ** 2 - dl * dl)
        v_r = k2 * ((dr + s_r) ** 2 - dr * dr)
        self.arc_left, self.arc_right = dl + s_l, dr + s_r
        return (v_l + v_r) / 4.0, (v_r - v_l) / (2.0 * b), (v_l + v_r) / (b * b)
