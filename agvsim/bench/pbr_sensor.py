"""The camera of the physically based frame set: Mitsuba's linear RGB radiance to an 8-bit grey
frame, as a colour machine-vision camera makes it. Written apart from the simulator's sensor
(:mod:`agvsim.sensors.render.sensor`) and from the envelope benchmark's
(:mod:`agvsim.bench.envelope_sensor`): it shares no code or parameter with them.

The chain, in order: exposure (the scene's radiance scaled so that the brightest 0.5 % of the
frame lands at ``exposure`` of full scale), an RGGB Bayer mosaic (each photosite sees one
channel), photo-electrons (``full_well`` electrons at full scale) drawn as Poisson counts, read
noise (Gaussian, ``read_noise`` electrons), clipping at full scale, a 10-bit ADC, OpenCV's
demosaicing to grey, the response curve (``linear``, ``gamma`` 1/2.2 or ``srgb``), 8 bits, and
JPEG at ``jpeg_quality`` (0: the frame is stored losslessly, as PNG).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

#: the camera's response curves (the frame's encoding of linear light)
RESPONSES = ("linear", "gamma", "srgb")
#: the ADC's levels
ADC_LEVELS = 1023


@dataclass(frozen=True)
class SensorSettings:
    """One frame's camera settings (JSON-ready through :func:`asdict`)."""

    exposure: float  # share of full scale the brightest 0.5 % of the frame reaches (> 1: clipped)
    full_well: float  # electrons at full scale (small: a high gain, a noisy frame)
    read_noise: float  # electrons, sd
    response: str  # one of RESPONSES
    jpeg_quality: int  # 1-100, or 0 for a lossless frame
    white_balance: tuple[float, float, float]  # gains of R, G, B before the mosaic

    def to_dict(self) -> dict:
        return asdict(self)


def sample_settings(rng: np.random.Generator) -> SensorSettings:
    """A camera setting: exposure 0.3-1.1 of full scale, 300-8000 electrons at full scale
    (log-uniform), read noise 1-12 electrons, the response curve and JPEG quality 60-95 (a
    quarter of the frames lossless)."""
    return SensorSettings(
        exposure=float(rng.uniform(0.3, 1.1)),
        full_well=float(np.exp(rng.uniform(np.log(300.0), np.log(8000.0)))),
        read_noise=float(rng.uniform(1.0, 12.0)),
        response=str(rng.choice(RESPONSES, p=(0.3, 0.3, 0.4))),
        jpeg_quality=0 if rng.random() < 0.25 else int(rng.integers(60, 96)),
        white_balance=tuple(float(x) for x in rng.uniform(0.8, 1.2, 3)))


def encode_response(x: np.ndarray, response: str) -> np.ndarray:
    """Linear light in [0, 1] to the response curve's [0, 1]."""
    if response == "linear":
        return x
    if response == "gamma":
        return x ** (1.0 / 2.2)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def expose(radiance: np.ndarray, s: SensorSettings, rng: np.random.Generator | None) -> tuple[np.ndarray, bytes]:
    """``(grey, stored)``: the ``(H, W)`` uint8 frame and the file's bytes (JPEG, or PNG when
    ``jpeg_quality`` is 0), from ``(H, W, 3)`` linear RGB ``radiance``; ``rng`` draws the noise
    (None: a noise-free frame, for measuring the noise)."""
    import cv2

    if radiance.ndim != 3 or radiance.shape[2] != 3:
        raise ValueError(f"radiance: expected an (H, W, 3) array, got shape {radiance.shape}")
    rgb = radiance.astype(np.float64) * np.asarray(s.white_balance)
    h, w = rgb.shape[:2]
    mosaic = np.empty((h, w))
    mosaic[0::2, 0::2] = rgb[0::2, 0::2, 0]  # R
    mosaic[0::2, 1::2] = rgb[0::2, 1::2, 1]  # G
    mosaic[1::2, 0::2] = rgb[1::2, 0::2, 1]  # G
    mosaic[1::2, 1::2] = rgb[1::2, 1::2, 2]  # B
    bright = float(np.percentile(mosaic, 99.5))
    level = mosaic * (s.exposure / bright if bright > 0 else 0.0)
    electrons = level * s.full_well
    if rng is not None:
        electrons = rng.poisson(np.clip(electrons, 0.0, None)).astype(np.float64)
        electrons += rng.normal(0.0, s.read_noise, electrons.shape)
    raw = np.round(np.clip(electrons / s.full_well, 0.0, 1.0) * ADC_LEVELS).astype(np.uint16)
    grey = cv2.cvtColor(raw, cv2.COLOR_BayerRG2GRAY).astype(np.float64) / ADC_LEVELS
    frame = np.round(255.0 * encode_response(np.clip(grey, 0.0, 1.0), s.response)).astype(np.uint8)
    if s.jpeg_quality:
        ok, data = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, int(s.jpeg_quality)])
    else:
        ok, data = cv2.imencode(".png", frame)
    if not ok:
        raise RuntimeError("OpenCV could not encode the frame")
    stored = data.tobytes()
    return cv2.imdecode(np.frombuffer(stored, np.uint8), cv2.IMREAD_GRAYSCALE), stored
