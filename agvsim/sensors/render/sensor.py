"""The camera's optics and sensor, applied to the linear radiance image.

Order (as light goes): motion blur (the vehicle moves during the exposure)
-> optical defocus blur -> lens distortion -> exposure and gain -> shot and
read noise -> saturation (clip to 0..255) -> 8-bit quantisation. Output is a
``uint8`` grey frame like the thesis's frame grabber, or 3-channel on request.

Radiance is relative: a white target (reflectance 0.9) on a wall in normal
light has radiance about 0.9, which :class:`SensorModel`'s default gain maps to
about 215 grey levels (like ``localizer.tools.synthetic.LIGHTING["normal"]``); the
same target in a 2.8x bright zone saturates.

Randomness only from the ``numpy.random.Generator`` passed in.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.numeric import check_number

from localizer.model.camera import Camera
from agvsim.sensors.render.mount import rotation_from_vector


def _nonneg(owner: str, name: str, value) -> float:
    return check_number(f"{owner}.{name}", value, low=0.0)


@dataclass(frozen=True)
class SensorModel:
    """Fixed properties of the camera's sensor.

    Attributes:
        gain: grey levels per unit radiance at exposure 1.0.
        flare: grey levels added everywhere (veiling glare, black level).
        full_well: photo-electrons at 255 grey levels (sets the shot noise).
        read_noise: read-out noise sigma (grey levels).
    """

    gain: float = 235.0  # grey levels per unit relative radiance
    flare: float = 5.0  # grey levels
    full_well: float = 20000.0  # e- at 255 grey levels
    read_noise: float = 0.8  # grey levels, sigma

    def __post_init__(self) -> None:
        for name in ("gain", "flare", "full_well", "read_noise"):
            object.__setattr__(self, name, _nonneg("SensorModel", name, getattr(self, name)))
        check_number("SensorModel.gain", self.gain, low=0.0, low_open=True)
        check_number("SensorModel.full_well", self.full_well, low=0.0, low_open=True)


def exposure_motion(camera: Camera, radiance: np.ndarray, depth: np.ndarray,
                    twist_cam: tuple[np.ndarray, np.ndarray], exposure_time: float,
                    max_samples: int = 16, z_min: float | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int] | None:
    """The camera's motion over the exposure: ``(rot_a, tr_a, rot_b, tr_b, n)``, camera(t) ->
    camera(0) at the exposure's start and end (rotation ``(3, 3)``, translation ``(3,)`` m) and
    the number of samples ``n`` along each pixel's path (from the largest image motion,
    2..``max_samples``); None when nothing moves by 0.05 px.

    Args:
        radiance: ``(H, W)`` (its shape only). depth: ``(H, W)`` m along the axis, 0 = far.
        twist_cam: ``(v, w)``: linear (m/s) and angular (rad/s) velocity, ``(3,)`` each, camera frame.
        z_min: the smallest positive depth (m) if the caller has it (1e3 if none), else taken
            from ``depth``.
    """
    v, w = (np.asarray(a, float) for a in twist_cam)
    h, wd = radiance.shape
    if z_min is None:
        z_min = float(np.min(depth[depth > 0])) if np.any(depth > 0) else 1e3
    flow_rot = exposure_time * (abs(w[1]) * camera.fx + abs(w[0]) * camera.fy + abs(w[2]) * max(h, wd) / 2)
    flow_tr = exposure_time * float(np.linalg.norm(v)) * camera.fx / max(min(z_min, 1e3), 0.1)
    if flow_rot + flow_tr < 0.05:
        return None
    n = int(min(max_samples, max(2, math.ceil(2 * (flow_rot + flow_tr)))))
    ends = []
    for t in (-0.5, 0.5):
        dt = t * exposure_time
        ends.append(rotation_from_vector(w * dt))
        ends.append(v * dt)
    return ends[0], ends[1], ends[2], ends[3], n


def motion_blur(radiance: np.ndarray, depth: np.ndarray, camera: Camera, twist_cam: tuple[np.ndarray, np.ndarray],
                exposure_time: float, max_samples: int = 16) -> np.ndarray:
    """Average of the image over the exposure while the camera moves (static scene).

    Args:
        radiance: ``(H, W)`` float32 linear image rendered at mid-exposure.
        depth: ``(H, W)`` depth (m along the optical axis; 0 = far).
        twist_cam: ``(v, w)``: the camera's linear velocity (m/s) and angular velocity
            (rad/s), both ``(3,)`` in the camera frame at mid-exposure.
        exposure_time: s.
    Returns:
        ``(H, W)`` float32. Each output pixel averages the scene points it saw at
        ``n`` instants across the exposure (:func:`exposure_motion`), found by
        back-projecting with the pixel's depth at the exposure's ends and
        interpolating between them (disocclusions are ignored).
    """
    import cv2

    motion = exposure_motion(camera, radiance, depth, twist_cam, exposure_time, max_samples)
    if motion is None:
        return radiance
    h, wd = radiance.shape
    z = np.where(depth > 0, depth, 1e3).astype(np.float32)
    jj, ii = np.meshgrid(np.arange(wd, dtype=np.float32), np.arange(h, dtype=np.float32))
    xn = (jj - camera.cx) / camera.fx
    yn = (ii - camera.cy) / camera.fy
    # exact sample positions at the start and end of the exposure; in between, pixel positions
    # are interpolated linearly (the motion over one exposure is small)
    ends = []
    for rot, tr in ((motion[0], motion[1]), (motion[2], motion[3])):
        X, Y = xn * z, yn * z
        p0x = rot[0, 0] * X + rot[0, 1] * Y + rot[0, 2] * z + tr[0]
        p0y = rot[1, 0] * X + rot[1, 1] * Y + rot[1, 2] * z + tr[1]
        p0z = np.maximum(rot[2, 0] * X + rot[2, 1] * Y + rot[2, 2] * z + tr[2], 1e-3)
        ends.append(((camera.cx + camera.fx * p0x / p0z).astype(np.float32),
                     (camera.cy + camera.fy * p0y / p0z).astype(np.float32)))
    (ax, ay), (bx, by) = ends
    dx, dy = bx - ax, by - ay
    n = motion[4]
    acc = np.zeros_like(radiance, dtype=np.float32)
    for f in (np.arange(n, dtype=np.float32) + 0.5) / n:
        acc += cv2.remap(radiance, ax + f * dx, ay + f * dy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return acc / np.float32(n)


def defocus(radiance: np.ndarray, sigma_px: float) -> np.ndarray:
    """Gaussian optical blur of ``sigma_px`` pixels (0: unchanged)."""
    if sigma_px <= 0:
        return radiance
    import cv2

    return cv2.GaussianBlur(radiance, (0, 0), sigmaX=float(sigma_px), sigmaY=float(sigma_px),
                            borderType=cv2.BORDER_REPLICATE)


def defocus_depth(radiance: np.ndarray, depth: np.ndarray, fx: float, aperture_m: float, focus_m: float,
                  extra_sigma_px: float = 0.0, levels: tuple[float, ...] = (0.0, 0.5, 1.0, 1.5, 2.5, 4.0, 6.0)) -> np.ndarray:
    """Thin-lens defocus: blur grows with the distance of each pixel's surface from the focus plane.

    The blur circle's diameter on the sensor is ``c = fx * aperture * |1/focus - 1/z|`` pixels
    (thin lens, ``fx`` in pixels); it is modelled as a Gaussian of ``sigma = c / 4`` (the
    standard deviation of a uniform disc), combined with ``extra_sigma_px``. The image is
    blurred at the sigmas in ``levels`` and each pixel interpolates between the two levels
    around its own sigma (occlusion boundaries are not treated specially).

    Args:
        radiance: ``(H, W)`` float32. depth: ``(H, W)`` m along the optical axis (0 = far).
        fx: focal length (px). aperture_m: aperture diameter (m). focus_m: focus distance (m).
    Returns:
        ``(H, W)`` float32.
    """
    z = np.where(depth > 0, depth, 1e3).astype(np.float32)
    coc = np.float32(fx * aperture_m) * np.abs(np.float32(1.0 / focus_m) - 1.0 / z)
    sigma = np.sqrt((coc / 4.0) ** 2 + np.float32(extra_sigma_px) ** 2)
    lv = np.asarray(levels, np.float32)
    sigma = np.clip(sigma, lv[0], lv[-1])
    k = np.clip(np.searchsorted(lv, sigma, side="right") - 1, 0, len(lv) - 2)
    frac = (sigma - lv[k]) / (lv[k + 1] - lv[k])
    out = np.zeros_like(radiance, dtype=np.float32)
    for i in range(len(lv)):
        wgt = np.where(k == i, 1.0 - frac, 0.0) + np.where(k + 1 == i, frac, 0.0)
        if np.any(wgt > 0):
            out += wgt.astype(np.float32) * defocus(radiance, float(lv[i]))
    return out


def distortion_maps(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """``(map_x, map_y)`` (``camera.shape`` float32): where in the ideal pinhole image each
    pixel of the distorted image looks (inverse of ``camera.project``'s distortion)."""
    jj, ii = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    pts = np.stack([jj.ravel(), ii.ravel()], axis=1)
    und = camera.undistort_points(pts)
    return (und[:, 0].reshape(camera.shape).astype(np.float32), und[:, 1].reshape(camera.shape).astype(np.float32))


def apply_distortion(radiance: np.ndarray, maps: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Resample the ideal image through the lens distortion maps of :func:`distortion_maps`."""
    import cv2

    return cv2.remap(radiance, maps[0], maps[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def expose(radiance: np.ndarray, sensor: SensorModel, exposure: float, noise: bool,
           rng: np.random.Generator | None, noise_scale: float = 1.0) -> np.ndarray:
    """Radiance -> uint8 grey: gain, flare, shot + read noise, saturation, rounding.

    Args:
        radiance: ``(H, W)`` float32, relative.
        exposure: relative exposure x gain (1.0 nominal).
        noise: add shot and read noise (needs ``rng``).
        noise_scale: multiplies both noise sigmas.
    """
    grey = radiance * np.float32(sensor.gain * exposure) + np.float32(sensor.flare)
    if noise and noise_scale > 0:
        if rng is None:
            raise ValueError("sensor noise needs a numpy.random.Generator (rng)")
        e_per_grey = sensor.full_well / 255.0
        sigma = np.sqrt(np.maximum(grey, 0.0) / np.float32(e_per_grey) + np.float32(sensor.read_noise ** 2))
        grey = grey + (rng.standard_normal(grey.shape, dtype=np.float32) * sigma * np.float32(noise_scale))
    return np.clip(np.rint(grey), 0, 255).astype(np.uint8)
