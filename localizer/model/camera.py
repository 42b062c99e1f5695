"""Pinhole camera model (thesis §3.3.1, §4.1, §4.7).

Camera frame (OpenCV convention, used everywhere in :mod:`localizer`)::

          z (optical axis, into the scene)
         /
        o-----> x (right)
        |
        v y (down)

The thesis's frame has X right, Y vertical and Z along the optical axis with
the image plane in front of the lens (eqs 4.1-4.2, no sign flip); it equals
this one with Y pointing down. The camera is level: its optical axis and
image rows are parallel to the floor (thesis §3.5 assumption 1).

Pixel convention: pixel ``(row i, column j)`` of an image array has its
centre at image coordinates ``(x, y) = (j, i)`` and covers
``[j - 0.5, j + 0.5] x [i - 0.5, i + 0.5]``. A point ``(X, Y, Z)`` in the camera
frame projects to ``x = cx + fx * X / Z``, ``y = cy + fy * Y / Z`` (before lens
distortion). The thesis camera has its principal point at pixel (256, 240)
(§4.7).
"""
from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from localizer._kernels.records import Intrinsics, as_record
from localizer.numeric import check_number


@functools.lru_cache(maxsize=64)
def _intrinsics_record(fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """``(1,)`` :data:`~localizer._kernels.records.INTRINSICS` record of these intrinsics (px;
    cached: the caller must not change it)."""
    return as_record(Intrinsics(fx, fy, cx, cy))


#: Thesis camera (Pulnix TM-450): sensor 8.8 x 6.6 mm imaged on 512 x 480 pixels.
THESIS_SENSOR_MM = (8.8, 6.6)
THESIS_SIZE_PX = (512, 480)


@dataclass(frozen=True)
class Camera:
    """Intrinsics and image size of a level pinhole camera.

    Attributes:
        fx, fy: focal lengths (pixels); unequal for non-square pixels.
        cx, cy: principal point (pixels, pixel-centre convention above).
        width, height: image size (pixels); images are ``height x width`` arrays.
        dist: lens distortion coefficients in OpenCV order
            ``(k1, k2, p1, p2[, k3[, k4, k5, k6]])`` or ``()`` for none.
    """

    fx: float  # px
    fy: float  # px
    cx: float  # px
    cy: float  # px
    width: int  # px
    height: int  # px
    dist: tuple[float, ...] = field(default=())  # OpenCV order, unitless

    def __post_init__(self) -> None:
        for name in ("fx", "fy"):
            object.__setattr__(self, name, check_number(f"Camera.{name}", getattr(self, name), low=0.0,
                                                        low_open=True, unit="px"))
        for name in ("cx", "cy"):
            object.__setattr__(self, name, check_number(f"Camera.{name}", getattr(self, name), unit="px"))
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):  # not merely a whole float
                raise ValueError(f"Camera.{name} must be an integer >= 8 (px), got {value!r}")
            object.__setattr__(self, name, check_number(f"Camera.{name}", value, low=8, integer=True, unit="px"))
        dist = () if self.dist is None else tuple(float(v) for v in np.ravel(self.dist))
        if len(dist) not in (0, 4, 5, 8, 12, 14):
            raise ValueError(f"Camera.dist must have 0, 4, 5, 8, 12 or 14 OpenCV coefficients, got {len(dist)}")
        if not all(math.isfinite(v) for v in dist):
            raise ValueError(f"Camera.dist must be finite, got {dist!r}")
        if dist and not any(dist):
            dist = ()
        object.__setattr__(self, "dist", dist)

    # ----------------------------------------------------------- constructors
    @classmethod
    def thesis(cls, focal_mm: float = 16.0) -> "Camera":
        """The thesis camera with a ``focal_mm`` lens (16 and 50 mm in ch. 5).

        8.8 x 6.6 mm sensor on 512 x 480 pixels, principal point (256, 240):
        ``fx = focal_mm / 8.8 * 512``, ``fy = focal_mm / 6.6 * 480``.
        """
        focal_mm = check_number("Camera.thesis focal_mm", focal_mm, low=0.0, low_open=True, unit="mm")
        (sw, sh), (w, h) = THESIS_SENSOR_MM, THESIS_SIZE_PX
        return cls(fx=focal_mm / sw * w, fy=focal_mm / sh * h, cx=256.0, cy=240.0, width=w, height=h)

    @classmethod
    def from_intrinsics(cls, fx: float, fy: float, cx: float, cy: float, width: int, height: int,
                        dist=None) -> "Camera":
        """A camera from OpenCV-style intrinsics (pixels) and distortion coefficients."""
        return cls(fx=fx, fy=fy, cx=cx, cy=cy, width=width, height=height,
                   dist=() if dist is None else tuple(np.ravel(dist)))

    @classmethod
    def from_opencv_yaml(cls, path: str | Path) -> "Camera":
        """Load an OpenCV calibration file (``cv2.FileStorage`` YAML or XML).

        Expects ``camera_matrix`` (3x3), ``image_width``, ``image_height`` and
        optionally ``distortion_coefficients`` (the names written by OpenCV's
        calibration sample). Raises ``FileNotFoundError`` or ``ValueError``
        naming the file and the field.
        """
        import cv2

        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"camera calibration file not found: {path}")
        try:
            fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        except (cv2.error, SystemError) as exc:
            # a file cut off or malformed: OpenCV's parser raises (through its Python binding, as a
            # SystemError whose cause is the cv2.error); its message names the line
            error = exc if isinstance(exc, cv2.error) else exc.__cause__ or exc.__context__
            where = _parse_error(error)
            raise ValueError(f"{path}: not a complete OpenCV FileStorage file (YAML or XML){where}; expected the "
                             "fields camera_matrix, image_width, image_height and optionally "
                             "distortion_coefficients") from None
        if not fs.isOpened():
            raise ValueError(f"{path}: not an OpenCV FileStorage file")
        try:
            def matrix(name: str, required: bool) -> np.ndarray | None:
                node = fs.getNode(name)
                if node.empty():
                    if required:
                        raise ValueError(f"{path}: missing field '{name}'")
                    return None
                mat = node.mat()
                if mat is None:
                    raise ValueError(f"{path}: field '{name}' is not an opencv-matrix")
                return np.asarray(mat, dtype=float)

            def integer(name: str) -> int:
                node = fs.getNode(name)
                if node.empty() or not node.isReal() and not node.isInt():
                    raise ValueError(f"{path}: missing or non-numeric field '{name}' (pixels)")
                value = node.real()
                if value != int(value):
                    raise ValueError(f"{path}: field '{name}' must be an integer, got {value}")
                return int(value)

            k = matrix("camera_matrix", True)
            if k.shape != (3, 3):
                raise ValueError(f"{path}: field 'camera_matrix' must be 3x3, got shape {k.shape}")
            dist = matrix("distortion_coefficients", False)
            width, height = integer("image_width"), integer("image_height")
        except (cv2.error, SystemError) as exc:  # a file OpenCV parses but whose top level is no map of fields
            raise ValueError(f"{path}: not an OpenCV calibration file (expected a map of the fields camera_matrix, "
                             f"image_width, image_height and optionally distortion_coefficients; OpenCV could not "
                             f"read its fields: {type(exc).__name__})") from None
        finally:
            fs.release()
        try:
            return cls.from_intrinsics(k[0, 0], k[1, 1], k[0, 2], k[1, 2], width, height, dist)
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None

    def to_opencv_yaml(self, path: str | Path) -> None:
        """Write this camera as an OpenCV calibration file readable by :meth:`from_opencv_yaml`."""
        import cv2

        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
        fs.write("image_width", self.width)
        fs.write("image_height", self.height)
        fs.write("camera_matrix", self.K)
        fs.write("distortion_coefficients", np.asarray(self.dist or (0.0, 0.0, 0.0, 0.0, 0.0), dtype=float))
        fs.release()

    # ------------------------------------------------------------ properties
    @property
    def K(self) -> np.ndarray:
        """3x3 intrinsic matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` (pixels)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` in pixels."""
        return self.width, self.height

    @property
    def shape(self) -> tuple[int, int]:
        """Image array shape ``(height, width)``."""
        return self.height, self.width

    @property
    def has_distortion(self) -> bool:
        return bool(self.dist)

    @functools.cached_property
    def intrinsics(self) -> Intrinsics:
        """``(fx, fy, cx, cy)`` (px) as the compiled kernels take them (computed once)."""
        return Intrinsics(self.fx, self.fy, self.cx, self.cy)

    @property
    def intrinsics_record(self) -> np.ndarray:
        """:attr:`intrinsics` as a ``(1,)`` record array, the form of the per-frame kernels'
        arguments (shared by every camera of the same intrinsics: do not change it). Cached by
        value, not per camera: a program that makes a camera per frame (or a crop's camera per
        target, :meth:`cropped`) would otherwise build it in every call (~40 us cold)."""
        return _intrinsics_record(self.fx, self.fy, self.cx, self.cy)

    def scaled(self, width: int, height: int) -> "Camera":
        """The same optics imaged on ``width x height`` pixels (intrinsics scaled)."""
        sx, sy = width / self.width, height / self.height
        return Camera(self.fx * sx, self.fy * sy, (self.cx + 0.5) * sx - 0.5, (self.cy + 0.5) * sy - 0.5,
                      width, height, self.dist)

    def cropped(self, x0: int, y0: int, x1: int, y1: int) -> "Camera":
        """The camera of the crop ``image[y0:y1, x0:x1]`` (pixels): the same optics, the principal
        point moved by the crop's corner (a pinhole camera: a pose found in the crop needs no
        conversion). Built without :meth:`__post_init__`'s checks when they could only pass
        (:func:`_derived`)."""
        return _derived(self.fx, self.fy, self.cx - x0, self.cy - y0, x1 - x0, y1 - y0, self.dist)

    def binned(self, k: int) -> "Camera":
        """The camera of this one's image area-averaged over ``k x k`` blocks (a pyramid level,
        :func:`localizer.image.pyramid.level_image`): its ``(width // k) k`` first columns and
        ``(height // k) k`` first rows, level pixel ``j`` covering pixels ``k j .. k j + k - 1``
        (focal lengths divided by ``k``, principal point ``(c + 0.5) / k - 0.5``). Built as
        :meth:`cropped` builds its cameras."""
        return _derived(self.fx / k, self.fy / k, (self.cx + 0.5) / k - 0.5, (self.cy + 0.5) / k - 0.5,
                        self.width // k, self.height // k, self.dist)

    # ------------------------------------------------------------ projection
    def project(self, points_cam) -> np.ndarray:
        """Project camera-frame points (m) to pixel coordinates.

        Args:
            points_cam: ``(..., 3)`` array of ``(X, Y, Z)`` with ``Z > 0`` (m).
        Returns:
            ``(..., 2)`` array of ``(x, y)`` pixel coordinates, lens distortion applied.
        """
        p = np.asarray(points_cam, dtype=float)
        if p.shape[-1:] != (3,):
            raise ValueError(f"points_cam must have shape (..., 3), got {p.shape}")
        if not np.all(p[..., 2] > 0):
            raise ValueError("points_cam must lie in front of the camera (Z > 0)")
        xn = p[..., 0] / p[..., 2]
        yn = p[..., 1] / p[..., 2]
        if self.dist:
            xn, yn = self._distort(xn, yn)
        return np.stack([self.cx + self.fx * xn, self.cy + self.fy * yn], axis=-1)

    def _distort(self, xn: np.ndarray, yn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = np.zeros(8)
        d[: min(8, len(self.dist))] = self.dist[:8]
        k1, k2, p1, p2, k3, k4, k5, k6 = d
        r2 = xn * xn + yn * yn
        radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
        xd = xn * radial + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn)
        yd = yn * radial + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn
        return xd, yd

    def undistort_points(self, points_px) -> np.ndarray:
        """Remove lens distortion from measured pixel points.

        Args:
            points_px: ``(N, 2)`` distorted pixel coordinates ``(x, y)``.
        Returns:
            ``(N, 2)`` pixel coordinates of an ideal pinhole camera with the same ``K``.
        """
        p = np.asarray(points_px, dtype=float).reshape(-1, 2)
        if not self.dist or len(p) == 0:
            return p.copy()
        import cv2

        out = cv2.undistortPoints(p.reshape(-1, 1, 2), self.K, np.asarray(self.dist), None, None, self.K,
                                      criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-9))
        return out.reshape(-1, 2)


def _parse_error(error) -> str:
    """``": <OpenCV's parse message>"`` of a ``cv2.error`` from reading a file (its line and what is
    wrong, e.g. ``"line 7: Missing , between the elements"``), or ``""``."""
    text = str(error) if error is not None else ""
    match = re.search(r"\((\d+)\): ([^'\n]+)", text)
    if match:
        return f" at line {match.group(1)}: {match.group(2).strip()}"
    return f": {text.strip()}" if text.strip() else ""


def _derived(fx: float, fy: float, cx: float, cy: float, width: int, height: int, dist: tuple) -> Camera:
    """A camera derived from a checked one (:meth:`Camera.cropped`, :meth:`Camera.binned`): built
    without :meth:`Camera.__post_init__`'s checks when they could only pass (finite positive
    focal lengths, a checked ``dist``, plain ``int`` sizes of at least 8 px), which cost ~12 us
    warm and several times that cold (the pyramid derives two cameras per target and frame)."""
    if (type(width) is not int or type(height) is not int or width < 8 or height < 8
            or not (math.isfinite(cx) and math.isfinite(cy))):
        return Camera(fx, fy, cx, cy, width, height, dist)
    cam = object.__new__(Camera)
    for name, value in (("fx", float(fx)), ("fy", float(fy)), ("cx", float(cx)), ("cy", float(cy)), ("width", width),
                        ("height", height), ("dist", dist)):
        object.__setattr__(cam, name, value)
    return cam
