"""Vision localizer for two-bar wall targets (S. H. Wang's thesis, chapters 3-4).

This package is independent of the simulator: it works on any grayscale
camera frame of a printed target. It never imports ``agvsim`` or ``envs``.

Public API::

    Camera.thesis(focal_mm=16.0) / Camera.from_intrinsics(...) / Camera.from_opencv_yaml(path)
    TargetSpec()                                  # thesis target, metres
    detect_targets(image, camera, target=TargetSpec(), method="exact", **params)
        -> list[TargetObservation]                # SI units, thesis angle conventions
    DetectorParams, DetectionStats, TargetPose, CameraMount, annotate
    localizer.synthetic                          # exact synthetic frames for tests/benches
    localizer.thesis_points                      # the thesis's test points (Tables 5.1-5.4)

Modules, in pipeline order: :mod:`localizer.scan` (scan lines), :mod:`localizer.recognize`
(search and verification), :mod:`localizer.thesis_edges` / :mod:`localizer.subpixel_edges`
(edge records in :mod:`localizer.edges`), :mod:`localizer.thesis_pose` /
:mod:`localizer.exact_pose` (pose records in :mod:`localizer.pose`),
:mod:`localizer.photometric`, :mod:`localizer.detect`. Compiled kernels:
:mod:`localizer._kernels` (flags: :mod:`localizer._jit`).
"""
from __future__ import annotations

from localizer.lazy import lazy_exports

#: public name -> module that defines it. Loaded on first use (PEP 562), so importing a
#: light module such as :mod:`localizer.numeric` or :mod:`localizer.mount` does not load
#: numba and the compiled kernels.
_LAZY = {
    "annotate": "localizer.annotation",
    "Camera": "localizer.camera",
    "CameraMount": "localizer.mount",
    "detect_targets": "localizer.detect",
    "TargetPose": "localizer.geometry",
    "ImageMeasurements": "localizer.observation",
    "TargetObservation": "localizer.observation",
    "METHODS": "localizer.params",
    "DetectionStats": "localizer.params",
    "DetectorParams": "localizer.params",
    "POLARITIES": "localizer.target",
    "TargetSpec": "localizer.target",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
