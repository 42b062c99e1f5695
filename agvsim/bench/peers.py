"""The localizer's peers in the benchmarks: ArUco + solvePnP (OpenCV) and AprilTag 3 (pupil-apriltags).

Both are fiducial systems a plant engineer could hang instead of two-bar targets, so the
benchmarks time them on the same frames as the localizer, one thread each (the caller sets
OpenCV's thread count). Each detector returns the poses it found; a frame's markers are an
ArUco ``DICT_4X4_50`` id 0 and an AprilTag ``tag36h11`` id 0 (:func:`marker_images`), whose black
squares are ``size`` metres across (the side solvePnP and AprilTag's pose take).

AprilTag 3 is optional (``pip install pupil-apriltags``, or ``make bench``): without it
:func:`peer_detectors` returns ArUco alone and the reports say how to get it.
"""
from __future__ import annotations

import contextlib

__all__ = ["APRILTAG_INSTALL", "MARKER_NAMES", "marker_images", "one_opencv_thread", "peer_detectors",
           "silent_c_stderr"]

#: how to get the AprilTag contender when it is missing
APRILTAG_INSTALL = "pip install pupil-apriltags (or make bench)"
#: the peers, in the order the reports list them
MARKER_NAMES = ("aruco", "apriltag")

#: the one pupil_apriltags Detector of the process: destroying one can segfault
#: (pupil-labs/apriltags#46), so it is created once and kept until exit.
_APRILTAG_DETECTOR: list = []


@contextlib.contextmanager
def one_opencv_thread():
    """OpenCV on one thread while the block runs (as every contender: OpenCV would spread ArUco
    over the cores), its thread count restored after."""
    import cv2

    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(threads)


@contextlib.contextmanager
def silent_c_stderr():
    """The process's file descriptor 2 sent to the null device while the block runs: AprilTag 3's
    pose estimation writes "Error, more than one new minima found." to the C library's stderr
    on some frames (about one in 130 of the envelope's), a note of its own that no Python code
    can catch and that would bury the benchmark's progress lines. Costs a few microseconds a
    call (two ``dup2``), charged to the peer."""
    import os
    import sys

    sys.stderr.flush()
    saved = os.dup(2)
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


def marker_images() -> dict:
    """name -> the marker as a square uint8 image (0 black, 255 white): its black square with
    one cell of black border, no quiet zone (``(96, 96)`` for ArUco's 6 cells, ``(100, 100)``
    for AprilTag's 8; a caller pads the white quiet zone it wants)."""
    import cv2

    aruco = cv2.aruco.generateImageMarker(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50), 0, 96,
                                          borderBits=1)
    april = cv2.aruco.generateImageMarker(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11), 0, 100,
                                          borderBits=1)
    return {"aruco": aruco, "apriltag": april}


def peer_detectors(camera, size: float = 0.1) -> dict:
    """name -> ``fn(image)`` for each installed peer: ``image`` an ``(H, W)`` uint8 frame of
    ``camera`` (a :class:`localizer.Camera`), the result a list with one pose per marker found
    (ArUco: solvePnP's ``(ok, rvec, tvec)`` with ``SOLVEPNP_IPPE_SQUARE``; AprilTag: its
    detections with the pose estimated). ``size``: the markers' black square (m)."""
    import cv2
    import numpy as np

    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50),
                                  cv2.aruco.DetectorParameters())
    h = 0.5 * size
    obj = np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], np.float32)
    k = camera.K
    dist = np.zeros(5)

    def aruco(img):
        corners, _, _ = det.detectMarkers(img)
        return [cv2.solvePnP(obj, c.reshape(4, 2), k, dist, flags=cv2.SOLVEPNP_IPPE_SQUARE) for c in corners]

    out = {"aruco": aruco}
    try:
        from pupil_apriltags import Detector
    except ImportError:
        return out
    if not _APRILTAG_DETECTOR:
        _APRILTAG_DETECTOR.append(Detector(families="tag36h11", nthreads=1))
    apr = _APRILTAG_DETECTOR[0]
    params = (camera.fx, camera.fy, camera.cx, camera.cy)

    def april(img):
        with silent_c_stderr():
            return apr.detect(img, estimate_tag_pose=True, camera_params=params, tag_size=size)

    out["apriltag"] = april
    return out
