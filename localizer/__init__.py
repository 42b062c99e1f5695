"""Vision localizer for two-bar wall targets (S. H. Wang's thesis, chapters 3-4).

This package is independent of the simulator: it works on any grayscale
camera frame of a printed target. It never imports ``agvsim`` or ``envs``.

Public API::

    Camera.thesis(focal_mm=16.0) / Camera.from_intrinsics(...) / Camera.from_opencv_yaml(path)
    TargetSpec()                                  # thesis target, metres
    detect_targets(image, camera, target=TargetSpec(), method="exact", **params)
        -> list[TargetObservation]                # SI units, thesis angle conventions
    DetectorParams, DetectionStats, TargetPose, CameraMount, annotate
    localizer.tools.synthetic                     # exact synthetic frames for tests/benches
    localizer.thesis.points                       # the thesis's test points (Tables 5.1-5.4)

The folders, in the order a frame goes through them: :mod:`localizer.model` (the camera, the
target, the parameters, the observation), :mod:`localizer.image` (reading frames, pyramid
levels, the sharpened copy), :mod:`localizer.search` (the row scan and the candidate stacks),
:mod:`localizer.measure` (sub-pixel edges, the exact pose and its covariance, the photometric
refinement), or :mod:`localizer.thesis` (the thesis's own edges and pose); :mod:`localizer.detect`
runs them (``detect_targets``), :mod:`localizer.filter` fuses the observations. Around them:
:mod:`localizer.tools` (calibration, synthetic frames, annotation). Compiled kernels:
:mod:`localizer._kernels` (flags: :mod:`localizer._jit`).
"""
from __future__ import annotations

from localizer.lazy import lazy_exports

#: public name -> module that defines it. Loaded on first use (PEP 562), so importing a
#: light module such as :mod:`localizer.numeric` or :mod:`localizer.model.mount` does not load
#: numba and the compiled kernels.
_LAZY = {
    "annotate": "localizer.tools.annotation",
    "Camera": "localizer.model.camera",
    "CameraMount": "localizer.model.mount",
    "detect_targets": "localizer.detect",
    "TargetPose": "localizer.model.geometry",
    "ImageMeasurements": "localizer.model.observation",
    "TargetObservation": "localizer.model.observation",
    "METHODS": "localizer.model.params",
    "DetectionStats": "localizer.model.params",
    "DetectorParams": "localizer.model.params",
    "POLARITIES": "localizer.model.target",
    "TargetSpec": "localizer.model.target",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
