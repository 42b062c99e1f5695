"""Pose filter: an EKF fusing wheel odometry with two-bar target observations.

Plain data in, plain data out; imports neither ``agvsim`` nor ``envs``.

    from localizer.filter import (PoseEKF, FilterConfig, TargetMap, CameraMount,
                                  OdometryNoise, Measurement)
    ekf = PoseEKF(x0, P0, TargetMap(ids, positions, yaws, polarities), CameraMount(forward=0.0, lateral=-0.3, yaw=-pi/2))
    ekf.add_odometry(t, ds, dtheta, in_contact)   # every control step (cheap); in_contact: the bumper
    result = ekf.process_frame(t_capture, detect_targets(image, camera))
    ekf.pose(), ekf.covariance()              # current estimate for the controller
    ekf.status, ekf.lost_reason               # "tracking" | "lost" | "relocalizing", and why
"""
from localizer.filter.association import (ACCEPTED, AMBIGUOUS, DUPLICATE, GATED, NO_CANDIDATE, Association,
                                          GateConfig, associate, innovation)
from localizer.filter.config import FilterConfig
from localizer.filter.ekf import LOST, RELOCALIZING, STATUSES, TRACKING, FrameResult, PoseEKF
from localizer.filter.measurement import (Measurement, TargetMap, ViewLimits,
                                          measurement_jacobian, pose_from_measurement,
                                          pose_from_measurement_jacobian, predict_all,
                                          predict_measurement)
from localizer.model.mount import CameraMount
from localizer.filter.motion import ContactSlip, OdometryAccumulator, OdometryNoise, arc_motion, compose, compose_jacobians
from localizer.filter.relocalize import Hypothesis, RelocalizeConfig, Relocalizer
from localizer.filter.update import PoseKF, nis, position_sigma, predict_pose, update_pose
from localizer.numeric import wrap_angle

__all__ = [
    "ACCEPTED", "AMBIGUOUS", "Association", "CameraMount", "ContactSlip", "DUPLICATE", "LOST", "RELOCALIZING",
    "STATUSES", "TRACKING", "FilterConfig", "FrameResult",
    "GATED", "GateConfig", "Hypothesis", "Measurement", "NO_CANDIDATE", "OdometryAccumulator",
    "OdometryNoise", "PoseEKF", "PoseKF", "RelocalizeConfig", "Relocalizer", "TargetMap", "ViewLimits",
    "arc_motion", "associate", "compose", "compose_jacobians", "innovation", "measurement_jacobian", "nis",
    "pose_from_measurement", "pose_from_measurement_jacobian", "position_sigma", "predict_all", "predict_measurement",
    "predict_pose", "update_pose", "wrap_angle",
]
