"""A closed loop, recorded as it runs: :class:`LoopRecorder`, the observer a mission calls
after every control step (:func:`agvsim.loop.mission.run_mission`'s ``observer``)."""
from __future__ import annotations

from agvsim.record.process import RunRecording

__all__ = ["LoopRecorder"]


class LoopRecorder:
    """Logs each control step of a :class:`~agvsim.loop.closed_loop.ClosedLoop` to a
    :class:`RunRecording`: the three poses and the estimate's covariance every step, the filter's
    status when it changes, each camera frame captured (with what the localizer found in it,
    when the source keeps that: ``last_detections``) and each frame fused (NIS, accepted)."""

    def __init__(self, recording: RunRecording) -> None:
        self.recording = recording
        self._status: str | None = None

    def __call__(self, loop, step) -> None:
        rec = self.recording
        t = loop.sim.time
        for fused in step.fused:
            rec.fused(fused.capture_time, fused.result.nis, fused.result.accepted)
        status = loop.ekf.status
        rec.poses(t, {"truth": loop.true_pose, "dead_reckoning": loop.odometry_pose, "estimate": loop.estimated_pose},
                  loop.ekf.covariance(), status if status != self._status else None)
        self._status = status
        if step.captured:
            source = loop.source
            rec.frame(t, loop.last_frame, getattr(source, "last_detections", ()))
