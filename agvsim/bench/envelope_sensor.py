"""The camera side of the envelope benchmark's frames: optics, sensor and encoding.

Independent of :mod:`localizer.tools.synthetic` (which shares the localizer's assumptions: ideal
box pixels, Gaussian blur, a linear response). Here a linear-light image of the scene (the
area-averaged radiance of the supersampled render, :mod:`agvsim.bench.envelope_frames`) goes
through, in this order:

1. a point-spread function (:func:`psf_kernel`): Gaussian, defocus disc (pillbox) or motion
   streak (a line), in linear light;
2. vignetting (:func:`vignetting`, a cos^4-like falloff to a given share at the corners);
3. exposure: ``white_level * radiance + flare`` (full-scale units, 1 = the brightest code);
4. with ``bayer``, the raw sensor's colour-filter sensitivities on an RGGB mosaic;
5. shot noise (electrons, Gaussian approximation) and read noise (8-bit codes, sd);
6. clipping to the full scale;
7. with ``bayer``, 12-bit raw codes, OpenCV's demosaicing (``COLOR_BayerBG2BGR``, OpenCV's
   name of the RGGB layout) and white balance;
8. encoding to 8 bits: linear, or the sRGB transfer curve (the standard piecewise one);
9. with ``jpeg_quality``, JPEG compression at that quality (OpenCV's codec) on the 8-bit
   frame (colour when ``bayer``), then, for colour, OpenCV's BGR -> grey conversion.

Every random draw comes from the ``numpy.random.Generator`` passed in.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: the point-spread functions (:attr:`FrameSettings.psf`)
PSFS = ("gaussian", "disc", "streak")
#: the 8-bit encodings (:attr:`FrameSettings.encoding`)
ENCODINGS = ("linear", "srgb")
#: raw colour-filter sensitivities (R, G, B) to a neutral grey, relative to green; the white
#: balance divides them out again after demosaicing
BAYER_SENSITIVITY = (0.55, 1.0, 0.7)
#: raw codes of the Bayer sensor's ADC (12 bits, stored in 16)
RAW_BITS = 12
#: the thesis camera's width (px): blur sizes are given at this width and scaled with the resolution
REFERENCE_WIDTH = 512


@dataclass(frozen=True)
class FrameSettings:
    """Everything about the camera that renders one condition's frames.

    Blur sizes are given at 512 px width and scaled by ``width / 512`` (the same angular
    blur: every resolution has the thesis camera's horizontal field of view)."""

    width: int = 512  # px
    height: int = 480  # px
    psf: str = "gaussian"  # one of PSFS
    blur: float = 0.5  # px at 512 px width: Gaussian sd, disc radius or streak length
    streak_angle: float = 0.0  # rad, streak direction from the image x axis (towards +y)
    vignette: float = 1.0  # relative illumination at the image corners (1: none)
    white_level: float = 0.9  # full-scale units reached by reflectance 1 at the image centre
    flare: float = 0.01  # full-scale units of veiling glare added everywhere
    full_well: float = 8000.0  # electrons at full scale (shot noise); 0: no shot noise
    read_noise: float = 0.8  # 8-bit codes, sd of the read noise; 0: none
    encoding: str = "linear"  # one of ENCODINGS
    bayer: bool = False  # RGGB mosaic + OpenCV demosaicing
    jpeg_quality: int = 0  # 1..100, 0: no JPEG

    def __post_init__(self) -> None:
        if self.psf not in PSFS or self.encoding not in ENCODINGS:
            raise ValueError(f"FrameSettings: psf must be one of {PSFS} and encoding one of {ENCODINGS}, "
                             f"got {self.psf!r}, {self.encoding!r}")
        if not (0.0 < self.vignette <= 1.0 and self.blur >= 0.0 and 0 <= self.jpeg_quality <= 100):
            raise ValueError(f"FrameSettings: vignette must be in (0, 1], blur >= 0 px and jpeg_quality in "
                             f"0..100, got {self.vignette}, {self.blur}, {self.jpeg_quality}")

    @property
    def scale(self) -> float:
        """Pixels per 512-width pixel (blur sizes are scaled by it)."""
        return self.width / REFERENCE_WIDTH

    @property
    def blur_px(self) -> float:
        """The blur size (px) at this resolution."""
        return self.blur * self.scale


def psf_kernel(kind: str, size: float, angle: float = 0.0) -> np.ndarray | None:
    """The normalised ``(k, k)`` float32 kernel of a PSF (``None`` for no blur).

    ``kind``: ``"gaussian"`` (sd ``size`` px), ``"disc"`` (pillbox of radius ``size`` px, its
    rim antialiased by 8 x 8 subsamples per kernel pixel) or ``"streak"`` (a line of length
    ``size`` px at ``angle`` rad, drawn with 16 bilinear splats per pixel of length)."""
    if size <= 1e-6:
        return None
    if kind == "gaussian":
        r = max(1, int(math.ceil(4.0 * size)))
        x = np.arange(-r, r + 1, dtype=np.float64)
        g = np.exp(-0.5 * (x / size) ** 2)
        k = np.outer(g, g)
    elif kind == "disc":
        r = int(math.ceil(size)) + 1
        sub = (np.arange(8) + 0.5) / 8.0 - 0.5
        c = np.arange(-r, r + 1, dtype=np.float64)
        xs = (c[:, None] + sub[None, :]).ravel()
        inside = (xs[:, None] ** 2 + xs[None, :] ** 2) <= size * size
        n = 2 * r + 1
        k = inside.reshape(n, 8, n, 8).mean(axis=(1, 3)).astype(np.float64)
        if k.sum() == 0.0:
            return None
    elif kind == "streak":
        r = int(math.ceil(0.5 * size)) + 1
        n = 2 * r + 1
        k = np.zeros((n, n))
        m = max(2, int(math.ceil(16 * size)))
        t = (np.arange(m) + 0.5) / m - 0.5
        px, py = r + t * size * math.cos(angle), r + t * size * math.sin(angle)
        x0, y0 = np.floor(px).astype(int), np.floor(py).astype(int)
        fx, fy = px - x0, py - y0
        for dx, dy, w in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
            np.add.at(k, (y0 + dy, x0 + dx), w)
    else:
        raise ValueError(f"psf kind must be one of {PSFS}, got {kind!r}")
    return (k / k.sum()).astype(np.float32)


def apply_psf(image: np.ndarray, kernel: np.ndarray | None) -> np.ndarray:
    """``image`` (H, W) float32 linear light convolved with ``kernel`` (edges reflected)."""
    import cv2

    if kernel is None:
        return image
    return cv2.filter2D(image, cv2.CV_32F, kernel, borderType=cv2.BORDER_REFLECT)


def vignetting(shape: tuple[int, int], fx: float, fy: float, cx: float, cy: float, corner: float) -> np.ndarray:
    """Relative illumination ``(H, W)`` float32: ``(1 + k r^2)^-2`` (the cos^4 law with
    ``tan θ = r``, rescaled) over the normalised image radius ``r`` (``(x - cx) / fx``,
    ``(y - cy) / fy``), with ``k`` chosen so that the farthest corner gets ``corner`` (0..1]."""
    h, w = shape
    xn = ((np.arange(w, dtype=np.float64) - cx) / fx) ** 2
    yn = ((np.arange(h, dtype=np.float64) - cy) / fy) ** 2
    r2 = yn[:, None] + xn[None, :]
    if corner >= 1.0:
        return np.ones(shape, np.float32)
    rc2 = max(xn[0], xn[-1]) + max(yn[0], yn[-1])
    k = (corner ** -0.5 - 1.0) / rc2
    return ((1.0 + k * r2) ** -2).astype(np.float32)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve (IEC 61966-2-1) on full-scale units 0..1 (float32)."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4, dtype=np.float32) - 0.055)


def _noise(e: np.ndarray, s: FrameSettings, rng: np.random.Generator) -> np.ndarray:
    """Shot noise (``e * full_well`` electrons) and read noise (codes) on full-scale ``e``."""
    out = e
    if s.full_well > 0:
        out = out + np.sqrt(np.clip(e, 0.0, None) / s.full_well) * rng.standard_normal(e.shape, dtype=np.float32)
    if s.read_noise > 0:
        out = out + (s.read_noise / 255.0) * rng.standard_normal(e.shape, dtype=np.float32)
    return np.clip(out, 0.0, 1.0).astype(np.float32)


def _to_8bit(x: np.ndarray, encoding: str) -> np.ndarray:
    if encoding == "srgb":
        x = srgb_encode(x)
    return np.clip(np.rint(np.clip(x, 0.0, 1.0) * 255.0), 0, 255).astype(np.uint8)


def bayer_mosaic_gain(shape: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` float32 raw sensitivity of each site of an RGGB mosaic (R at (0, 0), B at (1, 1))."""
    r, g, b = BAYER_SENSITIVITY
    m = np.full(shape, g, np.float32)
    m[0::2, 0::2] = r
    m[1::2, 1::2] = b
    return m


def expose(radiance: np.ndarray, s: FrameSettings, camera, rng: np.random.Generator) -> np.ndarray:
    """The 8-bit grey frame ``(H, W)`` uint8 of the linear scene radiance ``(H, W)``
    (reflectance x illumination, area-averaged over each pixel) through steps 1-9 of the
    module's pipeline. ``camera``: its intrinsics place the vignetting."""
    import cv2

    lin = apply_psf(radiance.astype(np.float32, copy=False), psf_kernel(s.psf, s.blur_px, s.streak_angle))
    if s.vignette < 1.0:
        lin = lin * vignetting(lin.shape, camera.fx, camera.fy, camera.cx, camera.cy, s.vignette)
    e = (s.white_level * lin + s.flare).astype(np.float32)
    if not s.bayer:
        out = _to_8bit(_noise(e, s, rng), s.encoding)
    else:
        raw = _noise(e * bayer_mosaic_gain(e.shape), s, rng)
        full = (1 << RAW_BITS) - 1
        codes = (np.rint(raw * full).astype(np.uint16) << (16 - RAW_BITS)).astype(np.uint16)
        bgr = cv2.cvtColor(codes, cv2.COLOR_BayerBG2BGR).astype(np.float32) / float(full << (16 - RAW_BITS))
        r, g, b = BAYER_SENSITIVITY
        bgr /= np.array([b, g, r], np.float32)  # white balance
        out = _to_8bit(bgr, s.encoding)
    if s.jpeg_quality:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(s.jpeg_quality)])
        if not ok:
            raise RuntimeError("OpenCV could not encode a JPEG frame")
        out = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    if out.ndim == 3:
        out = cv2.cvtColor(out, cv2.COLOR_BGR2GRAY)
    return np.ascontiguousarray(out)
