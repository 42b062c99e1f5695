"""Differential-drive AGV dynamics in pymunk (top-down, no gravity).

The model follows pymunk's ``examples/tank.py``: a kinematic *control body*
carries the commanded velocity, and two joints tie the dynamic chassis to it
with bounded force. A :class:`pymunk.PivotJoint` with ``max_bias = 0``
corrects only velocity (no position), so it acts as tyre friction: it drives
the chassis towards the commanded forward speed and its sideways speed
towards zero, with at most the traction force ``mu * m * g``. A
:class:`pymunk.GearJoint` does the same for the yaw rate. Walls and obstacles
are static shapes the chassis collides with.

Frames and units: map frame x east, y north (m); heading θ counter-clockwise
from +x (rad); forward speed v (m/s) along the heading; yaw rate ω (rad/s).
"""
from __future__ import annotations

from localizer.numeric import check_number

import math
from dataclasses import dataclass

import pymunk

from agvsim.vehicle.physics import COLLISION_VEHICLE, ContactMonitor

GRAVITY = 9.81  # m/s^2


@dataclass(frozen=True)
class VehicleParams:
    """Physical and control limits of the AGV (true values, not nominal ones)."""

    length: float = 1.0  # m, chassis along the heading
    width: float = 0.7  # m, chassis across the heading
    mass: float = 200.0  # kg
    max_speed: float = 1.5  # m/s, forward or reverse, and per wheel
    max_yaw_rate: float = 1.5  # rad/s
    max_accel: float = 1.0  # m/s^2, forward acceleration limit
    max_yaw_accel: float = 3.0  # rad/s^2
    wheel_radius: float = 0.1  # m, nominal drive-wheel radius
    track_width: float = 0.6  # m, nominal distance between the drive wheels
    traction: float = 0.8  # tyre friction coefficient (dimensionless)

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            check_number(f"VehicleParams.{name}", value, low=0.0, low_open=True)
        if self.track_width >= self.width + 0.2:
            raise ValueError(f"VehicleParams.track_width ({self.track_width} m) must fit the chassis width ({self.width} m)")

    def clip_command(self, v: float, omega: float) -> tuple[float, float]:
        """Clip (v m/s, ω rad/s) to the speed limits, then scale both so that
        neither wheel exceeds ``max_speed`` (keeps the path curvature)."""
        v = min(max(v, -self.max_speed), self.max_speed)
        omega = min(max(omega, -self.max_yaw_rate), self.max_yaw_rate)
        wheel = abs(v) + abs(omega) * 0.5 * self.track_width
        if wheel > self.max_speed:
            scale = self.max_speed / wheel
            v *= scale
            omega *= scale
        return v, omega


class DiffDriveVehicle:
    """A pymunk chassis driven by (v, ω) commands with acceleration limits.

    Args:
        space: the pymunk space holding the static world (see
            :func:`agvsim.vehicle.physics.build_space`).
        pose: initial true pose (x m, y m, θ rad).
        params: vehicle limits and geometry.
        contacts: monitor that records the chassis's contacts.

    The true pose (:attr:`pose`) is ground truth: rendering, rewards and
    evaluation may read it; controllers and estimators must not.
    """

    def __init__(self, space: pymunk.Space, pose: tuple[float, float, float],
                 params: VehicleParams, contacts: ContactMonitor) -> None:
        self.params = params
        self.space = space
        self.contacts = contacts
        x, y, theta = (check_number(f"initial pose {name}", float(p)) for name, p in zip("xyθ", pose))
        moment = pymunk.moment_for_box(params.mass, (params.length, params.width))
        self.body = pymunk.Body(params.mass, moment)
        self.body.position = (x, y)
        self.body.angle = theta
        self.shape = pymunk.Poly.create_box(self.body, (params.length, params.width), radius=0.0)
        self.shape.collision_type = COLLISION_VEHICLE
        self.shape.friction = 0.3
        self.shape.elasticity = 0.0
        self.control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.control.position = (x, y)
        self.control.angle = theta
        traction_force = params.traction * params.mass * GRAVITY  # N
        pivot = pymunk.PivotJoint(self.control, self.body, (0.0, 0.0), (0.0, 0.0))
        pivot.max_bias = 0.0  # velocity correction only: tyre friction
        pivot.max_force = traction_force
        gear = pymunk.GearJoint(self.control, self.body, 0.0, 1.0)
        gear.error_bias = 0.0
        gear.max_bias = 0.0
        gear.max_force = traction_force * 0.5 * params.track_width * 4.0  # N m
        space.add(self.body, self.shape, self.control, pivot, gear)
        self._v_cmd = 0.0  # m/s, slew-limited command in force
        self._w_cmd = 0.0  # rad/s

    # -- state -------------------------------------------------------------
    @property
    def pose(self) -> tuple[float, float, float]:
        """True pose (x m, y m, θ rad), θ unwrapped (continuous)."""
        p = self.body.position
        return (p.x, p.y, self.body.angle)

    @property
    def velocity(self) -> tuple[float, float]:
        """True (forward speed m/s, yaw rate rad/s) of the chassis."""
        vel = self.body.velocity
        angle = self.body.angle
        return (vel.x * math.cos(angle) + vel.y * math.sin(angle), self.body.angular_velocity)

    @property
    def commanded(self) -> tuple[float, float]:
        """The slew-limited (v m/s, ω rad/s) the motors are currently tracking."""
        return (self._v_cmd, self._w_cmd)

    def wheel_speeds(self) -> tuple[float, float]:
        """Commanded rim speeds (left, right) in m/s of the drive wheels."""
        half = 0.5 * self.params.track_width
        return (self._v_cmd - self._w_cmd * half, self._v_cmd + self._w_cmd * half)

    # -- actuation -----------------------------------------------------------
    def apply(self, v: float, omega: float, dt: float) -> None:
        """Track the command (v m/s, ω rad/s) for one physics step of ``dt`` s.

        The command is clipped to the speed limits and slewed at the
        acceleration limits; the control body then carries it.
        """
        v, omega = self.params.clip_command(v, omega)
        self.track(v, omega, dt)

    def track(self, v: float, omega: float, dt: float) -> None:
        """Like :meth:`apply` for a command already clipped by
        :meth:`VehicleParams.clip_command`. :meth:`drive` repeats this arithmetic inline (the
        hot path): keep the two in step (``tests/vehicle/test_kinematics.py`` compares them)."""
        p = self.params
        dv = p.max_accel * dt
        dw = p.max_yaw_accel * dt
        v_cmd = self._v_cmd + min(max(v - self._v_cmd, -dv), dv)
        w_cmd = self._w_cmd + min(max(omega - self._w_cmd, -dw), dw)
        body = self.body
        # pymunk integrates positions with the velocities solved in the previous
        # step, so the velocity set now moves the chassis during the *next*
        # step. Aim it along that step's mid heading (the angle after this
        # step plus half the next turn): the chassis then moves on the chord of
        # the arc that dead reckoning integrates, and ideal odometry is exact.
        angle = body.angle + (body.angular_velocity + 0.5 * w_cmd) * dt
        self.control.velocity = (v_cmd * math.cos(angle), v_cmd * math.sin(angle))
        if w_cmd != self._w_cmd:
            self.control.angular_velocity = w_cmd
        self._v_cmd = v_cmd
        self._w_cmd = w_cmd

    def drive(self, v: float, omega: float, dt: float, substeps: int) -> tuple[list, list, list]:
        """Track the clipped command (v m/s, ω rad/s) for ``substeps`` physics steps of ``dt`` s,
        stepping the space: :meth:`track` then ``space.step`` each, in one loop (the hot path).

        Returns ``(ds, dtheta, wheels)``, one entry per physics step: the chassis centre's true
        arc length (m, from the chord between the poses before and after the step and the mid
        heading), its true heading change (rad), and the commanded rim speeds (left, right) m/s
        (:meth:`wheel_speeds`) when the chassis touches a wall or obstacle after the step, else None.
        """
        p = self.params
        dv = p.max_accel * dt
        dw = p.max_yaw_accel * dt
        half_track = 0.5 * p.track_width
        body = self.body
        control = self.control
        set_velocity = pymunk.Body.velocity.fset  # the setter itself, without pymunk's __setattr__ hook
        set_angular_velocity = pymunk.Body.angular_velocity.fset
        space_step = self.space.step
        touching = self.contacts.touching  # the monitor's dict (updated in place by its callbacks)
        cos, sin = math.cos, math.sin
        v_cmd, w_cmd = self._v_cmd, self._w_cmd
        pos0 = body.position
        x0, y0 = pos0.x, pos0.y
        a0 = body.angle
        out_ds, out_dtheta, out_wheels = [], [], []
        ds_append, dtheta_append, wheels_append = out_ds.append, out_dtheta.append, out_wheels.append
        for _ in range(substeps):
            # track(v, omega, dt), with the body's angle known from the previous step
            dv_step = v - v_cmd
            dv_step = -dv if -dv > dv_step else dv_step
            v_cmd = v_cmd + (dv if dv < dv_step else dv_step)
            dw_step = omega - w_cmd
            dw_step = -dw if -dw > dw_step else dw_step
            w_new = w_cmd + (dw if dw < dw_step else dw_step)
            angle = a0 + (body.angular_velocity + 0.5 * w_new) * dt
            set_velocity(control, (v_cmd * cos(angle), v_cmd * sin(angle)))
            if w_new != w_cmd:
                set_angular_velocity(control, w_new)
            w_cmd = w_new
            space_step(dt)
            pos1 = body.position
            x1, y1 = pos1.x, pos1.y
            a1 = body.angle
            half = 0.5 * (a1 - a0)
            mid = a0 + half
            chord = (x1 - x0) * cos(mid) + (y1 - y0) * sin(mid)
            # chord / arc_chord_factor(half)
            ds_append(chord / (1.0 - half * half / 6.0 if abs(half) < 1e-4 else sin(half) / half))
            dtheta_append(a1 - a0)
            wheels_append((v_cmd - w_cmd * half_track, v_cmd + w_cmd * half_track) if touching else None)
            x0, y0, a0 = x1, y1, a1
        self._v_cmd = v_cmd
        self._w_cmd = w_cmd
        return out_ds, out_dtheta, out_wheels

    def place(self, pose: tuple[float, float, float]) -> None:
        """Put the chassis at ``pose`` (x m, y m, θ rad) at rest, as if carried there (the
        wheels do not turn: the encoders count nothing). For kidnapped-robot experiments."""
        x, y, theta = (check_number(f"pose {name}", float(p)) for name, p in zip("xyθ", pose))
        for body in (self.body, self.control):
            body.position = (x, y)
            body.angle = theta
            body.velocity = (0.0, 0.0)
            body.angular_velocity = 0.0
        self._v_cmd = self._w_cmd = 0.0
        self.space.reindex_shapes_for_body(self.body)

    def stop(self) -> None:
        """Zero the command at once (an emergency stop, no slew)."""
        self._v_cmd = self._w_cmd = 0.0
        self.control.velocity = (0.0, 0.0)
        self.control.angular_velocity = 0.0
