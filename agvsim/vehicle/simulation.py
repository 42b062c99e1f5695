"""The simulated world stepped at a fixed physics rate: pymunk chassis,
encoders and dead reckoning.

Control steps are a whole number of physics steps (default 100 Hz physics,
10 Hz control). Nothing here renders.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from agvsim.vehicle.physics import build_space
from localizer.numeric import check_number
from agvsim.vehicle.dynamics import DiffDriveVehicle, VehicleParams
from agvsim.vehicle.encoders import EncoderModel, OdometryErrorModel
from agvsim.vehicle.odometry import DeadReckoning


@dataclass(frozen=True)
class SimConfig:
    """Rates, vehicle and odometry of a simulation run."""

    physics_rate: float = 100.0  # Hz
    control_rate: float = 10.0  # Hz; physics_rate / control_rate must be a whole number
    vehicle: VehicleParams = field(default_factory=VehicleParams)
    odometry: OdometryErrorModel = field(default_factory=lambda: OdometryErrorModel.preset("typical"))

    def __post_init__(self) -> None:
        for name in ("physics_rate", "control_rate"):
            check_number(f"SimConfig.{name}", getattr(self, name), low=0.0, low_open=True, unit="Hz")
        ratio = self.physics_rate / self.control_rate
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(
                f"SimConfig: physics_rate ({self.physics_rate} Hz) must be a whole multiple of "
                f"control_rate ({self.control_rate} Hz)")
        if isinstance(self.odometry, str):
            object.__setattr__(self, "odometry", OdometryErrorModel.preset(self.odometry))

    @property
    def substeps(self) -> int:
        """Physics steps per control step."""
        return int(round(self.physics_rate / self.control_rate))

    @property
    def physics_dt(self) -> float:
        return 1.0 / self.physics_rate  # s

    @property
    def control_dt(self) -> float:
        return 1.0 / self.control_rate  # s


@dataclass(frozen=True)
class StepResult:
    """What one control step of the vehicle produced.

    Attributes:
        ds: odometry distance increment over the step (m; negative when reversing).
        dtheta: odometry heading increment over the step (rad).
        command: the (v m/s, ω rad/s) actually applied: the request clipped to the
            vehicle's limits (:meth:`VehicleParams.clip_command`), once, here.
        contacts: ids of walls/obstacles touched during the step.
        collided: a contact began during the step.
        in_contact: touching a wall or obstacle at the end of the step.
    """

    ds: float  # m
    dtheta: float  # rad
    command: tuple[float, float]  # m/s, rad/s
    contacts: frozenset[str]
    collided: bool
    in_contact: bool


class Simulation:
    """A vehicle on a map: physics, encoders, dead reckoning.

    Args:
        world_map: an :class:`agvsim.world.map.Map`.
        start_pose: true (and dead-reckoning) start pose (x m, y m, θ rad).
        config: rates, vehicle, odometry error model.
        rng: the run's generator (odometry noise).
    """

    def __init__(self, world_map, start_pose: tuple[float, float, float],
                 config: SimConfig, rng: np.random.Generator) -> None:
        self.map = world_map
        self.config = config
        self.space, self.contacts = build_space(world_map)
        self.vehicle = DiffDriveVehicle(self.space, start_pose, config.vehicle, self.contacts)
        p = config.vehicle
        self.encoders = EncoderModel(p.wheel_radius, p.track_width, config.odometry, rng)
        self.odometry = DeadReckoning(start_pose, p.wheel_radius, p.track_width,
                                      self.encoders.counts_per_rad, self.encoders.read())
        self.time = 0.0  # s
        self.distance = 0.0  # m, true path length of the chassis centre
        self.steps = 0  # physics steps taken
        self._physics_dt, self._substeps, self._control_dt = config.physics_dt, config.substeps, config.control_dt

    @property
    def true_pose(self) -> tuple[float, float, float]:
        """Ground-truth pose; for rendering, rewards and evaluation only."""
        return self.vehicle.pose

    @property
    def odometry_pose(self) -> tuple[float, float, float]:
        return self.odometry.pose

    def place_vehicle(self, pose: tuple[float, float, float]) -> None:
        """Carry the vehicle to ``pose`` (x m, y m, θ rad) without its wheels turning: dead
        reckoning does not notice (a kidnapped robot). Raises ``ValueError`` if the chassis
        there would overlap a wall or an obstacle."""
        x, y, _ = (float(v) for v in pose)
        vp = self.config.vehicle
        clearance = self.map.clearance(x, y)
        xmin, ymin, xmax, ymax = self.map.bounds
        if not (xmin <= x <= xmax and ymin <= y <= ymax):
            raise ValueError(f"vehicle pose ({x:.2f}, {y:.2f}) is outside the map's bounds {self.map.bounds}")
        if clearance < 0.5 * math.hypot(vp.length, vp.width):
            raise ValueError(f"vehicle pose ({x:.2f}, {y:.2f}): {clearance:.2f} m from the nearest wall or "
                             f"obstacle, the chassis needs {0.5 * math.hypot(vp.length, vp.width):.2f} m")
        self.vehicle.place(pose)

    def step(self, v: float, omega: float) -> StepResult:
        """Drive with the command (v m/s, ω rad/s) for one control step."""
        if not (math.isfinite(v) and math.isfinite(omega)):  # the hot path stays two float checks
            check_number("command v", v, unit="m/s")
            check_number("command omega", omega, unit="rad/s")
        config = self.config
        contacts = self.contacts
        events_before = contacts.events
        contacts.reset_window()
        v, omega = config.vehicle.clip_command(v, omega)
        dt = self._physics_dt
        substeps = self._substeps
        # physics, then the encoders and dead reckoning over the same physics steps: the
        # encoders read only the true motion, dead reckoning only the counts
        ds_steps, dtheta_steps, wheels = self.vehicle.drive(v, omega, dt, substeps)
        self.odometry.update_steps(*self.encoders.advance_steps(ds_steps, dtheta_steps, wheels, dt))
        distance = 0.0
        for ds in ds_steps:
            distance += abs(ds)
        self.distance += distance
        self.steps += substeps
        self.time += self._control_dt
        ds, dtheta = self.odometry.take_increment()
        return StepResult(ds, dtheta, (v, omega), frozenset(contacts.since_reset),
                          contacts.events > events_before, bool(contacts.touching))
