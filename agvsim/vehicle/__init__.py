"""The AGV: pymunk dynamics, wheel encoders and dead reckoning."""
from agvsim.vehicle.dynamics import DiffDriveVehicle, VehicleParams
from agvsim.vehicle.encoders import EncoderModel, OdometryErrorModel, WheelTicks
from agvsim.vehicle.odometry import DeadReckoning, OdometryIncrement

__all__ = [
    "DeadReckoning",
    "DiffDriveVehicle",
    "EncoderModel",
    "OdometryErrorModel",
    "OdometryIncrement",
    "VehicleParams",
    "WheelTicks",
]
