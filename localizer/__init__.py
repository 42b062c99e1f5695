"""Vision localizer for two-bar wall targets (S. H. Wang's thesis, chapters 3-4).

This package is independent of the simulator: it works on any grayscale
camera frame of a printed target. It never imports ``agvsim`` or ``envs``.

Public API::

    Camera.thesis(focal_mm=16.0) / Camera.from_intrinsics(...) / Camera.from_opencv_yaml(path)
    TargetSpec()                                  # thesis target, metres
    detect_targets(image, camera, target=TargetSpec(), method="exact", **params)
        -> list[TargetObservation]                # SI units, thesis angle conventions
    DetectorParams, DetectionStats, TargetPose, annotate
    localizer.synthetic                          # exact synthetic frames for tests/benches
"""
from localizer.annotate import annotate
from localizer.camera import Camera
from localizer.detect import detect_targets
from localizer.geometry import TargetPose
from localizer.observation import ImageMeasurements, TargetObservation
from localizer.params import METHODS, DetectionStats, DetectorParams
from localizer.pose import alpha_a14, thesis_alpha
from localizer.target import POLARITIES, TargetSpec

__all__ = [
    "Camera", "DetectionStats", "DetectorParams", "ImageMeasurements", "METHODS", "POLARITIES",
    "TargetObservation", "TargetPose", "TargetSpec", "alpha_a14", "annotate", "detect_targets",
    "thesis_alpha",
]
