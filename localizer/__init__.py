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
    localizer.thesis_points                      # the thesis's test points (Tables 5.1-5.4)

Modules, in pipeline order: :mod:`localizer.scan` (scan lines), :mod:`localizer.recognize`
(search and verification), :mod:`localizer.thesis_edges` / :mod:`localizer.subpixel_edges`
(edge records in :mod:`localizer.edges`), :mod:`localizer.thesis_pose` /
:mod:`localizer.exact_pose` (pose records in :mod:`localizer.pose`),
:mod:`localizer.photometric`, :mod:`localizer.detect`. Compiled kernels:
:mod:`localizer._kernels` (flags: :mod:`localizer._jit`).
"""
from localizer.annotate import annotate
from localizer.camera import Camera
from localizer.detect import detect_targets
from localizer.geometry import TargetPose
from localizer.observation import ImageMeasurements, TargetObservation
from localizer.params import METHODS, DetectionStats, DetectorParams
from localizer.target import POLARITIES, TargetSpec

__all__ = [
    "Camera", "DetectionStats", "DetectorParams", "ImageMeasurements", "METHODS", "POLARITIES",
    "TargetObservation", "TargetPose", "TargetSpec", "annotate", "detect_targets",
]
