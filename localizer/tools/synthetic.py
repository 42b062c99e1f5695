"""Exact synthetic frames of targets with known pose (for tests and benchmarks).

The renderer computes, for every pixel, the exact fraction of its area covered
by each target region (margin rectangle, two bars) under perspective
projection with a level pinhole camera -- an exact perspective warp of the
target texture with ideal box-filter pixels. The vertical edges are exact; the
slanted tops and bottoms are integrated with ``SUBSAMPLES`` column samples per
pixel. Then, in this order: optical blur (Gaussian, pixels), exposure
(``gain * reflectance + flare``), sensor noise (Gaussian, grey levels),
clipping to 0..255 (saturation), rounding to uint8.

Randomness comes only from the ``numpy.random.Generator`` passed in.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from localizer.model.camera import Camera
from localizer.model.geometry import TargetPose, bar_edges_u
from localizer.numeric import check_number
from localizer.model.target import TargetSpec

SUBSAMPLES = 16  # column samples per pixel for slanted edges

#: Reflectances of the printed target (matte black ink, white paper).
BLACK_REFLECTANCE = 0.06
WHITE_REFLECTANCE = 0.90


@dataclass(frozen=True)
class Lighting:
    """Exposure: grey level = gain * reflectance + flare, then clipped to 0..255."""

    gain: float  # grey levels per unit reflectance
    flare: float = 0.0  # grey levels added everywhere (veiling glare)


LIGHTING: dict[str, Lighting] = {
    "dim": Lighting(gain=75.0, flare=2.0),          # white ~70, black ~6
    "normal": Lighting(gain=235.0, flare=5.0),      # white ~217, black ~19
    "saturated": Lighting(gain=520.0, flare=40.0),  # white clipped (508 -> 255), black ~71
}


def quad_coverage(height: int, width: int, xl: float, xr: float, ytl: float, ytr: float,
                   ybl: float, ybr: float):
    """Pixel-area coverage of a quad with vertical sides ``x = xl``, ``x = xr``.

    Top and bottom are straight lines through ``(xl, ytl)``-``(xr, ytr)`` and
    ``(xl, ybl)``-``(xr, ybr)`` (pixels, y down). Returns ``(r0, c0, cov)``
    with ``cov`` the coverage (0..1) of the window starting at row ``r0``,
    column ``c0``; ``cov`` is empty when the quad is out of the image.
    """
    k = SUBSAMPLES
    c0 = max(int(math.floor(xl + 0.5)), 0)
    c1 = min(int(math.floor(xr + 0.5)), width - 1)
    r0 = max(int(math.floor(min(ytl, ytr) + 0.5)), 0)
    r1 = min(int(math.floor(max(ybl, ybr) + 0.5)), height - 1)
    if c1 < c0 or r1 < r0:
        return 0, 0, np.zeros((0, 0))
    cols = np.arange(c0, c1 + 1, dtype=float)
    xs = cols[:, None] - 0.5 + (np.arange(k) + 0.5) / k  # (C, K)
    lo, hi = xs - 0.5 / k, xs + 0.5 / k
    w = np.clip(np.minimum(hi, xr) - np.maximum(lo, xl), 0.0, 1.0 / k)  # (C, K)
    t = (np.clip(xs, xl, xr) - xl) / max(xr - xl, 1e-12)
    yt = ytl + (ytr - ytl) * t
    yb = ybl + (ybr - ybl) * t
    rows = np.arange(r0, r1 + 1, dtype=float)
    cov = np.empty((rows.size, cols.size))
    # rows fully inside every column's [yt, yb] are covered by sum(w)
    top_band_end = int(math.floor(yt.max() + 0.5)) + 1
    bot_band_start = int(math.floor(yb.min() + 0.5)) - 1
    full = np.zeros(rows.size, bool)
    if bot_band_start > top_band_end:
        full = (rows > top_band_end) & (rows < bot_band_start)
    cov[full] = w.sum(axis=1)[None, :]
    part = ~full
    ri = rows[part][:, None, None]
    overlap = np.clip(np.minimum(ri + 0.5, yb[None]) - np.maximum(ri - 0.5, yt[None]), 0.0, 1.0)
    cov[part] = (overlap * w[None]).sum(axis=2)
    return r0, c0, cov


def target_outline(camera: Camera, pose: TargetPose, target: TargetSpec = TargetSpec()) -> dict:
    """Ideal (undistorted) image geometry of a target at ``pose``.

    Returns a dict with ``edges_x`` (4,) x of the bar edges, ``top_y``/``bottom_y``
    (4,) y of the bar tops/bottoms at those edges, ``outer`` (4, 2) margin corners
    (TL, TR, BR, BL), ``bar_heights`` (2,) pixel heights at the bar centres.
    """
    b, hh = target.bar_width, target.bar_height / 2.0
    u = bar_edges_u(b)
    top = _project_ideal(camera, pose.points(u, -hh))
    bot = _project_ideal(camera, pose.points(u, hh))
    uo = target.outer_width / 2.0
    vo = target.outer_height / 2.0
    outer = _project_ideal(camera, pose.points(np.array([-uo, uo, uo, -uo]), np.array([-vo, -vo, vo, vo])))
    uc = np.array([-b, b])
    hc = _project_ideal(camera, pose.points(uc, hh))[:, 1] - _project_ideal(camera, pose.points(uc, -hh))[:, 1]
    return {"edges_x": top[:, 0], "top_y": top[:, 1], "bottom_y": bot[:, 1], "outer": outer, "bar_heights": hc}


def _project_ideal(camera: Camera, pts: np.ndarray) -> np.ndarray:
    z = pts[..., 2]
    return np.stack([camera.cx + camera.fx * pts[..., 0] / z, camera.cy + camera.fy * pts[..., 1] / z], axis=-1)


def render_reflectance(camera: Camera, poses: Sequence[TargetPose], target: TargetSpec = TargetSpec(),
                       polarities: Sequence[str] | str = "positive", background=0.5) -> np.ndarray:
    """Reflectance image (float, ``camera.shape``) with the targets drawn exactly.

    ``background`` is a constant reflectance or a ``camera.shape`` float array
    of reflectances (0..1).
    """
    h, w = camera.height, camera.width
    if np.isscalar(background):
        refl = np.full((h, w), float(background))
    else:
        refl = np.array(background, dtype=float, copy=True)
        if refl.shape != (h, w):
            raise ValueError(f"background must have shape {(h, w)}, got {refl.shape}")
    if isinstance(polarities, str):
        polarities = [polarities] * len(poses)
    for pose, pol in zip(poses, polarities):
        if pose.distance * math.cos(pose.beta) <= target.outer_width:
            raise ValueError("target too close to the camera plane to render")
        bar, paper = (BLACK_REFLECTANCE, WHITE_REFLECTANCE) if pol == "positive" else \
            (WHITE_REFLECTANCE, BLACK_REFLECTANCE)
        uo, vo = target.outer_width / 2.0, target.outer_height / 2.0
        b, hh = target.bar_width, target.bar_height / 2.0
        quads = [((-uo, uo), vo, paper), ((-1.5 * b, -0.5 * b), hh, bar), ((0.5 * b, 1.5 * b), hh, bar)]
        for (ua, ub), vv, value in quads:
            p = _project_ideal(camera, pose.points(np.array([ua, ub, ua, ub]), np.array([-vv, -vv, vv, vv])))
            r0, c0, cov = quad_coverage(h, w, p[0, 0], p[1, 0], p[0, 1], p[1, 1], p[2, 1], p[3, 1])
            if cov.size:
                win = refl[r0:r0 + cov.shape[0], c0:c0 + cov.shape[1]]
                win += (value - win) * cov
    return refl


def expose(refl: np.ndarray, lighting: Lighting | str = "normal", blur: float = 0.0, noise: float = 0.0,
           rng: np.random.Generator | None = None) -> np.ndarray:
    """Turn a reflectance image into a uint8 camera frame.

    Args:
        refl: ``(H, W)`` float reflectance.
        lighting: a :class:`Lighting` or a key of :data:`LIGHTING`.
        blur: Gaussian optical blur sigma (pixels).
        noise: sensor noise sigma (grey levels); needs ``rng`` when > 0.
    """
    import cv2

    light = LIGHTING[lighting] if isinstance(lighting, str) else lighting
    img = np.asarray(refl, dtype=np.float32)
    if blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), sigmaX=float(blur), sigmaY=float(blur),
                               borderType=cv2.BORDER_REPLICATE)
    img = img * np.float32(light.gain) + np.float32(light.flare)
    if noise > 0:
        if rng is None:
            raise ValueError("noise > 0 needs a numpy.random.Generator (rng)")
        img = img + rng.normal(0.0, noise, img.shape).astype(np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def render_frame(camera: Camera, poses: Sequence[TargetPose] | TargetPose, target: TargetSpec = TargetSpec(),
                 polarities: Sequence[str] | str = "positive", lighting: Lighting | str = "normal",
                 blur: float = 0.0, noise: float = 0.0, background=0.5,
                 rng: np.random.Generator | None = None) -> np.ndarray:
    """A uint8 ``camera.shape`` frame showing ``poses`` (see module docstring)."""
    if isinstance(poses, TargetPose):
        poses = [poses]
    refl = render_reflectance(camera, poses, target, polarities, background)
    return expose(refl, lighting, blur, noise, rng)


def photo_background(photo: np.ndarray, camera: Camera) -> np.ndarray:
    """A reflectance background (``camera.shape``, 0..~0.95) from a uint8 photo (grey or BGR/RGB)."""
    import cv2

    img = np.asarray(photo)
    if img.ndim == 3:
        img = cv2.cvtColor(img[..., :3], cv2.COLOR_RGB2GRAY)
    img = cv2.resize(img, (camera.width, camera.height), interpolation=cv2.INTER_AREA)
    return img.astype(np.float64) / 255.0 * 0.95


# ---------------------------------------------------------------- envelope
def in_envelope(camera: Camera, pose: TargetPose, target: TargetSpec = TargetSpec(),
                min_bar_px: float = 5.0, min_rows: float = 16.0, border_px: float = 2.0) -> bool:
    """Whether ``pose`` is in the working envelope: the whole printed target in view
    (``border_px`` inside the image), every bar at least ``min_bar_px`` wide and
    ``min_rows`` tall."""
    if pose.z <= target.outer_width:
        return False
    # the parts of target_outline the tests need, computed as it does, each only when reached
    uo = target.outer_width / 2.0
    vo = target.outer_height / 2.0
    o = _project_ideal(camera, pose.points(np.array([-uo, uo, uo, -uo]), np.array([-vo, -vo, vo, vo])))
    if o[:, 0].min() < border_px or o[:, 0].max() > camera.width - 1 - border_px:
        return False
    if o[:, 1].min() < border_px or o[:, 1].max() > camera.height - 1 - border_px:
        return False
    b, hh = target.bar_width, target.bar_height / 2.0
    u = bar_edges_u(b)
    top = _project_ideal(camera, pose.points(u, -hh))
    widths = np.diff(top[:, 0])
    if widths.min() < min_bar_px:
        return False
    bot = _project_ideal(camera, pose.points(u, hh))
    return bool((bot[:, 1] - top[:, 1]).min() >= min_rows)


def pose_at_column(camera: Camera, distance: float, alpha: float, x_px: float | None = None,
                   height: float = 0.0) -> TargetPose:
    """A pose whose target centre images at column ``x_px`` (default: the principal point)."""
    x_px = camera.cx if x_px is None else x_px
    beta = math.atan((x_px - camera.cx) / camera.fx)
    return TargetPose(distance, beta, alpha, height)


def random_pose(rng: np.random.Generator, camera: Camera, target: TargetSpec = TargetSpec(),
                distance: tuple[float, float] = (1.0, 10.0), max_alpha: float = math.radians(70.0),
                max_tries: int = 1000) -> TargetPose:
    """A uniformly drawn in-envelope pose (distance, alpha, image column, height)."""
    for _ in range(max_tries):
        d = rng.uniform(*distance)
        a = rng.uniform(-max_alpha, max_alpha)
        x = rng.uniform(0.0, camera.width - 1.0)
        yrow = rng.uniform(0.0, camera.height - 1.0)
        pose = pose_at_column(camera, d, a, x)
        pose = TargetPose(d, pose.beta, a, (yrow - camera.cy) / camera.fy * pose.z)
        if in_envelope(camera, pose, target):
            return pose
    raise ValueError("could not draw an in-envelope pose; widen the ranges")


# ------------------------------------------------------ adversarial patterns
def adversarial_frames(camera: Camera, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Target-free uint8 frames that defeat naive bar detectors.

    Keys: ``chessboard``, ``chessboard_small``, ``barcode``, ``striped_sign``,
    ``door_frame``, ``grating``, ``noise``, ``black``, ``white``. Each is
    ``camera.shape``, lightly blurred and noisy.
    """
    import cv2

    h, w = camera.shape
    out: dict[str, np.ndarray] = {}

    def finish(refl, lighting="normal"):
        return expose(refl, lighting, blur=0.6, noise=1.5, rng=rng)

    yy, xx = np.mgrid[0:h, 0:w]
    for name, sq in (("chessboard", 40), ("chessboard_small", 14)):
        board = (((xx - 60) // sq + (yy - 40) // sq) % 2 == 0).astype(float)
        inside = (xx >= 60) & (xx < 60 + 8 * sq) & (yy >= 40) & (yy < 40 + 8 * sq)
        out[name] = finish(np.where(inside, np.where(board > 0, 0.06, 0.9), 0.9))
    refl = np.full((h, w), 0.9)
    x = 80
    while x < w - 80:  # random-width barcode, 1-4 module bars of 3 px
        bw, gw = 3 * rng.integers(1, 5), 3 * rng.integers(1, 5)
        refl[120:300, x:x + bw] = 0.06
        x += bw + gw
    out["barcode"] = finish(refl)
    refl = np.full((h, w), 0.5)
    refl[100:360, 100:400] = 0.9
    for k in range(6):  # six equal vertical stripes on a sign
        refl[130:330, 130 + 40 * k:150 + 40 * k] = 0.06
    out["striped_sign"] = finish(refl)
    refl = np.full((h, w), 0.8)
    refl[40:, 150:175] = 0.1  # door posts and lintel: posts narrow, opening wide
    refl[40:, 330:355] = 0.1
    refl[40:65, 150:355] = 0.1
    refl[65:, 175:330] = 0.35
    out["door_frame"] = finish(refl)
    phase = (np.sin(2 * np.pi * xx / 18.0) > 0).astype(float)
    out["grating"] = finish(np.where(phase > 0, 0.9, 0.06))
    out["noise"] = rng.integers(0, 256, (h, w), dtype=np.uint8)
    out["black"] = np.zeros((h, w), np.uint8)
    out["white"] = np.full((h, w), 255, np.uint8)
    del cv2
    return out


#: the grid of :func:`equal_bar_rows`: bars in a row, bar widths (px), gap minus bar width
#: (px; the run test undoes up to ``max_edge_shift`` = 1 px of dark-side shift on each edge, so
#: 5 px bars with 9-10 px gaps pass as a blurred target), height / (2.5 x mean run) (a facing
#: target is ~2.5 mean runs tall on the thesis camera), (dark, bright) grey levels
EQUAL_BAR_GRID = ((3, 4, 6), (3, 4, 5, 6, 8, 10, 12), (0, 1, 2, 3, 4, 5), (0.8, 1.0, 1.3),
                  ((24, 172), (60, 200), (0, 255), (90, 150)))


def equal_bar_frame(camera: Camera, n: int, width: int, pitch: int, height: int, dark: int = 24,
                    bright: int = 172, positive: bool = True, x0: int = 150, y0: int = 200) -> np.ndarray:
    """A uint8 ``camera.shape`` frame of ``n`` equal bars ``width`` px wide at a ``pitch`` px
    pitch, ``height`` rows tall from row ``y0`` and column ``x0``, exact pixels: grey ``dark``
    on ``bright`` (``positive``) or the reverse. No target: every neighbouring pair of bars
    looks like one, but a target's bars have a half-bar margin beyond them, not a third bar
    (a fuzzed frame of 4 bars 5 px wide at a 15 px pitch, 16 rows, 24 on 172 gave three)."""
    h, w = camera.shape
    if not (n >= 1 and width >= 1 and pitch > width and height >= 1 and x0 >= 0 and y0 >= 0
            and x0 + (n - 1) * pitch + width <= w and y0 + height <= h):
        raise ValueError(f"{n} bars {width} px wide at a {pitch} px pitch, {height} rows tall at "
                         f"({x0}, {y0}) do not fit a {w} x {h} frame")
    fg, bg = (dark, bright) if positive else (bright, dark)
    img = np.full((h, w), bg, np.uint8)
    for k in range(n):
        img[y0:y0 + height, x0 + k * pitch:x0 + k * pitch + width] = fg
    return img


def equal_bar_rows(camera: Camera, blur: float = 0.0, noise: float = 0.0,
                   rng: np.random.Generator | None = None, every: int = 1):
    """Rows of equal bars (:func:`equal_bar_frame`) over :data:`EQUAL_BAR_GRID`, both
    polarities: yields ``(name, frame)`` (3,024 frames; a generator, as they are 0.7 GB
    together). With ``blur`` (Gaussian sigma, px) and ``noise`` (sd, grey levels; needs
    ``rng``) the exact frames are blurred and noised as :func:`expose` does; ``every``: only
    every ``every``-th frame of the grid (the noise draws dominate the time)."""
    import cv2

    every = check_number("equal_bar_rows every", every, low=1, integer=True)
    if noise > 0 and rng is None:
        raise ValueError("noise > 0 needs a numpy.random.Generator (rng)")
    ns, widths, extra, heights, levels = EQUAL_BAR_GRID
    k = -1
    for n in ns:
        for width in widths:
            for d in extra:
                gap = width + d
                for hf in heights:
                    height = max(8, int(round(hf * 2.5 * (2 * width + gap) / 3.0)))
                    for dark, bright in levels:
                        for positive in (True, False):
                            k += 1
                            if k % every:
                                continue
                            img = equal_bar_frame(camera, n, width, width + gap, height, dark, bright, positive)
                            if blur > 0 or noise > 0:
                                f = img.astype(np.float32)
                                if blur > 0:
                                    f = cv2.GaussianBlur(f, (0, 0), sigmaX=float(blur), sigmaY=float(blur),
                                                         borderType=cv2.BORDER_REPLICATE)
                                if noise > 0:
                                    f = f + rng.normal(0.0, noise, f.shape).astype(np.float32)
                                img = np.clip(np.rint(f), 0, 255).astype(np.uint8)
                            name = (f"{n}x{width}px/{width + gap}px pitch, {height} rows, "
                                    f"{dark if positive else bright} on {bright if positive else dark}")
                            yield name, img


def real_photos(camera: Camera) -> dict[str, np.ndarray]:
    """Target-free real photographs shipped with scikit-image, as reflectance
    backgrounds of ``camera.shape`` (empty dict if scikit-image is missing)."""
    try:
        import skimage.data as skd
    except ImportError:  # pragma: no cover - optional dependency
        return {}
    names = ("astronaut", "brick", "camera", "chelsea", "coffee", "coins", "grass", "gravel",
             "motorcycle_left", "rocket", "page", "text", "hubble_deep_field", "checkerboard_photo")
    out = {}
    for name in names:
        try:
            if name == "checkerboard_photo":
                import os

                import cv2

                path = os.path.join(os.path.dirname(skd.__file__), "chessboard_GRAY.png")
                img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
            elif name == "motorcycle_left":
                img = skd.stereo_motorcycle()[0]
            else:
                img = getattr(skd, name)()
        except Exception:  # noqa: BLE001 - data not shipped in this build
            continue
        if img is None:
            continue
        img = np.asarray(img)
        if img.dtype != np.uint8:
            img = np.clip(img * (255.0 if img.max() <= 1.0 else 1.0), 0, 255).astype(np.uint8)
        out[name] = photo_background(img, camera)
    return out
