"""A simulated drive written as a log as it runs (``agvsim demo --export-log DIR``,
``--export-bag FILE.mcap``): :class:`LogExporter`, the observer a mission calls after every
control step, into a sink (:class:`agvsim.replay.folder.FolderWriter` or
:class:`agvsim.replay.bag.BagWriter`), with the truth, so that ``agvsim track`` on it can be
held to the closed loop's estimate."""
from __future__ import annotations

from agvsim.replay.drive import VehicleFile

__all__ = ["LogExporter", "vehicle_of"]


def vehicle_of(loop) -> VehicleFile:
    """The vehicle file of a closed loop: its track width, camera mount and odometry preset."""
    from agvsim.vehicle.encoders import PRESETS, OdometryErrorModel

    sim = loop.config.sim
    preset = next((p for p in PRESETS if OdometryErrorModel.preset(p) == sim.odometry), "typical")
    return VehicleFile(track_width=sim.vehicle.track_width, mount=loop.vision.mount, odometry=preset)


class LogExporter:
    """Writes each control step of a closed loop to ``sink``: the measured odometry (v, ω over the
    step, from the odometry increments the filter is given), the true pose, and each frame
    captured. The first call also writes the vehicle and camera files and the start
    (t = 0, at rest, at ``start``: x m, y m, θ rad, the loop's true start pose)."""

    def __init__(self, sink, start) -> None:
        self.sink = sink
        self.start = tuple(float(v) for v in start)
        self._started = False

    def __call__(self, loop, step) -> None:
        sink = self.sink
        if not self._started:
            self._started = True
            sink.describe(vehicle_of(loop), loop.vision.camera)
            sink.odometry(0.0, 0.0, 0.0)
            sink.truth(0.0, self.start)
        t = loop.sim.time
        dt = loop.config.sim.control_dt
        sink.odometry(t, step.sim.ds / dt, step.sim.dtheta / dt)
        sink.truth(t, loop.true_pose)
        if step.captured and loop.last_frame is not None:
            sink.frame(t, loop.last_frame)
