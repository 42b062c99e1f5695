"""Procedural textures: targets, wall surfaces, obstacles and distractors.

Every texture is an ``(H, W)`` float32 array of *linear* diffuse reflectance
(albedo, 0..1), row 0 at the top of the surface; :func:`to_rgba8` turns it
into the ``(H, W, 4)`` uint8 image handed to OpenGL. The renderer draws in
pyrender's FLAT mode, which neither decodes nor re-encodes sRGB, so texture
filtering and multisample resolve stay linear and edges stay where they are.

All randomness comes from the ``numpy.random.Generator`` passed in.
"""
from __future__ import annotations

import math

import numpy as np

from localizer.tools.synthetic import BLACK_REFLECTANCE, WHITE_REFLECTANCE
from localizer.model.target import TargetSpec

#: Texels per bar width b of a target texture: at 1 m with the 16 mm lens a bar
#: (75 mm) spans about 70 px, so 256 texels keep 3.6 texels per pixel, and every
#: thesis-target edge (multiples of b/2) lies on a texel boundary of mip levels 0..7.
TARGET_TEXELS_PER_BAR = 256
MAX_TEXTURE_SIZE = 2048  # texels


def to_rgba8(albedo: np.ndarray) -> np.ndarray:
    """``(H, W)`` reflectance (0..1) -> ``(H, W, 4)`` uint8 grey, opaque (linear, no gamma).

    Four bytes per texel keep every row 4-byte aligned: pyrender uploads textures with
    OpenGL's default ``GL_UNPACK_ALIGNMENT`` of 4, so 3-byte RGB rows of a width that is
    not a multiple of 4 would be read sheared, with bytes from beyond the array.
    """
    a = np.clip(np.asarray(albedo, dtype=np.float32), 0.0, 1.0)
    g = np.rint(a * 255.0).astype(np.uint8)
    out = np.empty(g.shape + (4,), np.uint8)
    out[..., :3] = g[..., None]
    out[..., 3] = 255
    return out


# ------------------------------------------------------------------ targets
def target_texture(spec: TargetSpec, polarity: str, texels_per_bar: int = TARGET_TEXELS_PER_BAR) -> np.ndarray:
    """The printed face of a two-bar target (margin included), reflectance.

    Args:
        spec: target geometry (m).
        polarity: ``"positive"`` (black bars on white paper) or ``"negative"``.
        texels_per_bar: texels across one bar width ``b`` (reduced if the texture
            would exceed :data:`MAX_TEXTURE_SIZE`).
    Returns:
        ``(H, W)`` float32, covering ``spec.outer_width x spec.outer_height``;
        texels cut by a region boundary hold the area-weighted reflectance.
    """
    if polarity not in ("positive", "negative"):
        raise ValueError(f"polarity must be 'positive' or 'negative', got {polarity!r}")
    b = spec.bar_width
    t = b / texels_per_bar  # m per texel
    while max(spec.outer_width, spec.outer_height) / t > MAX_TEXTURE_SIZE:
        t *= 2.0
    w = int(math.ceil(spec.outer_width / t - 1e-9))
    h = int(math.ceil(spec.outer_height / t - 1e-9))
    bar, paper = (BLACK_REFLECTANCE, WHITE_REFLECTANCE) if polarity == "positive" else \
        (WHITE_REFLECTANCE, BLACK_REFLECTANCE)
    # coverage of each texel column / row by the bars (exact box integrals), in target (u, v)
    u_edges = np.linspace(-spec.outer_width / 2, spec.outer_width / 2, w + 1)
    v_edges = np.linspace(-spec.outer_height / 2, spec.outer_height / 2, h + 1)

    def cover(edges: np.ndarray, lo: float, hi: float) -> np.ndarray:
        return np.clip(np.minimum(edges[1:], hi) - np.maximum(edges[:-1], lo), 0.0, None) / np.diff(edges)

    cu = cover(u_edges, -1.5 * b, -0.5 * b) + cover(u_edges, 0.5 * b, 1.5 * b)
    cv = cover(v_edges, -spec.bar_height / 2, spec.bar_height / 2)
    coverage = cv[:, None] * cu[None, :]
    return (paper + (bar - paper) * coverage).astype(np.float32)


# ------------------------------------------------------------------ surfaces
def _noise(rng: np.random.Generator, shape: tuple[int, int], scale: int, amp: float) -> np.ndarray:
    """Smooth value noise: ``amp``-sigma Gaussian field with features ``scale`` texels wide (tileable)."""
    small = rng.normal(0.0, 1.0, (max(2, shape[0] // scale), max(2, shape[1] // scale))).astype(np.float32)
    return cubic_resize(small, shape) * np.float32(amp)


def _cubic_taps(n_in: int, n_out: int) -> tuple[np.ndarray, np.ndarray]:
    """Source indices ``(n_out, 4)`` (edges repeated) and float32 weights of the bicubic taps."""
    pos = ((np.arange(n_out) + 0.5) * (1.0 / (n_out / n_in)) - 0.5).astype(np.float32)
    first = np.floor(pos)
    x = pos - first  # float32
    a, one = np.float32(-0.75), np.float32(1.0)
    w0 = ((a * (x + one) - np.float32(5.0) * a) * (x + one) + np.float32(8.0) * a) * (x + one) - np.float32(4.0) * a
    w1 = ((a + np.float32(2.0)) * x - (a + np.float32(3.0))) * x * x + one
    w2 = ((a + np.float32(2.0)) * (one - x) - (a + np.float32(3.0))) * (one - x) * (one - x) + one
    w3 = one - w0 - w1 - w2
    taps = np.clip(first.astype(np.int64)[:, None] + np.arange(-1, 3), 0, n_in - 1)
    return taps, np.stack([w0, w1, w2, w3], axis=1)


def cubic_resize(img: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` float32 ``img`` resampled to ``shape`` = ``(h, w)``: separable bicubic
    convolution (Keys, a = -0.75), pixel centres aligned, edge texels repeated, in float32,
    each tap's product added left to right. The weights and taps are OpenCV's ``INTER_CUBIC``;
    OpenCV's own sums differ from it in the last bit (their order depends on the CPU's kernels),
    this one does not."""
    img = np.asarray(img, np.float32)
    cols, wc = _cubic_taps(img.shape[1], shape[1])
    rows, wr = _cubic_taps(img.shape[0], shape[0])
    g = img[:, cols]
    across = ((g[..., 0] * wc[:, 0] + g[..., 1] * wc[:, 1]) + g[..., 2] * wc[:, 2]) + g[..., 3] * wc[:, 3]
    g = across[rows]  # (h, 4, w)
    wr = wr[:, :, None]
    return ((g[:, 0] * wr[:, 0] + g[:, 1] * wr[:, 1]) + g[:, 2] * wr[:, 2]) + g[:, 3] * wr[:, 3]


#: Surface name -> (tile width m, tile height m) for tiled wall/floor textures.
SURFACE_TILE = {
    "painted": (2.0, 2.0), "concrete": (2.0, 2.0), "brick": (1.0, 1.0), "panel": (2.0, 2.4),
    "glass": (2.0, 2.0), "floor": (4.0, 4.0), "default": (2.0, 2.0),
}
#: Surfaces stretched once across their wall piece (not tiled).
STRETCHED_SURFACES = ("door", "poster")


def surface_texture(surface: str, rng: np.random.Generator, size: int = 256) -> np.ndarray:
    """A wall or floor look, reflectance ``(size, size)`` (``door``/``poster``: one whole piece).

    Known: painted, concrete, brick, panel, door, poster, glass, floor; anything
    else gets a plain painted look.
    """
    n = size
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float32)
    if surface == "concrete":
        img = 0.42 + _noise(rng, (n, n), 32, 0.015) + _noise(rng, (n, n), 4, 0.012)
        img[(yy % (n // 2)) < 1.5] -= 0.08  # formwork joints every metre
    elif surface == "brick":
        rows = 16  # 62.5 mm courses on a 1 m tile
        course = (yy // (n / rows)).astype(int)
        offset = np.where(course % 2 == 0, 0.0, n / 8)
        mortar = ((yy % (n / rows)) < 2) | (((xx + offset) % (n / 4)) < 2)
        brick_shade = rng.uniform(-0.05, 0.05, (rows, 8)).astype(np.float32)
        col = (((xx + offset) // (n / 4)).astype(int)) % 8
        img = 0.30 + brick_shade[course, col] + _noise(rng, (n, n), 8, 0.015)
        img = np.where(mortar, 0.55, img)
    elif surface == "panel":  # painted steel panels 1 m wide: vertical seams (a bar-like distractor)
        img = 0.58 + _noise(rng, (n, n), 32, 0.01)
        seam = ((xx % (n // 2)) < 3)
        img = np.where(seam, 0.22, img)
        img[(yy > n * 0.45) & (yy < n * 0.47)] = 0.35
    elif surface == "door":  # a roller door in a dark frame: two posts and a lintel
        img = 0.50 + 0.05 * np.sign(np.sin(2 * np.pi * yy / (n / 24)))
        frame = (xx < n * 0.05) | (xx > n * 0.95) | (yy < n * 0.04)
        img = np.where(frame, 0.08, img)
        img[(yy > n * 0.55) & (yy < n * 0.6) & (xx > n * 0.45) & (xx < n * 0.55)] = 0.12  # handle
    elif surface == "poster":
        img = np.full((n, n), 0.55, np.float32) + _noise(rng, (n, n), 32, 0.02)
        for _ in range(6):  # framed posters of blocks and "text" lines
            x0, y0 = rng.integers(0, n - 60), rng.integers(n // 5, n - 80)
            w, h = rng.integers(30, 60), rng.integers(40, 70)
            img[y0:y0 + h, x0:x0 + w] = rng.uniform(0.2, 0.9)
            for k in range(y0 + 4, y0 + h - 4, 6):
                if rng.random() < 0.7:
                    img[k:k + 2, x0 + 3:x0 + rng.integers(8, w - 2)] = 0.1
    elif surface == "glass":
        img = 0.12 + _noise(rng, (n, n), 64, 0.02)
        img[(xx % (n // 2)) < 4] = 0.35  # mullions
    elif surface == "floor":  # sealed concrete with slabs
        img = 0.35 + _noise(rng, (n, n), 32, 0.03) + _noise(rng, (n, n), 4, 0.01)
        img[((xx % (n // 2)) < 1.5) | ((yy % (n // 2)) < 1.5)] -= 0.07
    else:  # painted
        img = 0.68 + _noise(rng, (n, n), 32, 0.012)
    return np.clip(img, 0.02, 0.95).astype(np.float32)


def obstacle_texture(kind: str, rng: np.random.Generator, size: int = 256) -> np.ndarray:
    """Side texture of an obstacle, reflectance ``(size, size)`` covering one tile (see :data:`OBSTACLE_TILE`).

    ``rack``: pallet racking with dark shelving uprights, beams and boxes;
    ``machine``: grey housing with hazard tape and a control panel;
    ``pillar``: concrete with a hazard-tape collar; ``pallet``: wrapped goods on a pallet.
    """
    n = size
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float32)
    if kind == "rack":  # tile = one 2.7 m bay, full height; uprights at both sides
        img = 0.18 + _noise(rng, (n, n), 16, 0.02)  # shadowed inside of the rack
        for level in range(4):  # beams + boxes per level
            y_beam = int(n * (0.98 - level * 0.25))
            for k in range(3):
                x0 = int(n * (0.06 + k * 0.31))
                bw = int(n * rng.uniform(0.2, 0.28))
                bh = int(n * rng.uniform(0.12, 0.2))
                img[max(0, y_beam - bh):y_beam - 3, x0:x0 + bw] = rng.uniform(0.35, 0.7)
            img[max(0, y_beam - 3):y_beam + 1, :] = 0.55
        upright = (xx < n * 0.035) | (xx > n * 0.965)
        holes = ((yy % 10) < 3) & ((xx % (n * 0.965)) > n * 0.012) & ((xx % (n * 0.965)) < n * 0.022)
        img = np.where(upright, np.where(holes, 0.05, 0.25), img)
    elif kind == "machine":
        img = 0.45 + _noise(rng, (n, n), 32, 0.015)
        band = yy > n * 0.86
        tape = ((xx + yy) % 24) < 12
        img = np.where(band, np.where(tape, 0.05, 0.65), img)
        img[int(n * 0.3):int(n * 0.5), int(n * 0.6):int(n * 0.8)] = 0.25  # control panel
        img[int(n * 0.35):int(n * 0.38), int(n * 0.63):int(n * 0.77)] = 0.8
    elif kind == "pillar":
        img = 0.5 + _noise(rng, (n, n), 16, 0.02)
        collar = yy > n * 0.85
        tape = ((xx - yy) % 20) < 10
        img = np.where(collar, np.where(tape, 0.05, 0.7), img)
    elif kind == "pallet":
        img = 0.6 + _noise(rng, (n, n), 16, 0.05)  # stretch-wrapped goods
        img[int(n * 0.85):, :] = 0.35  # pallet deck
        for x0 in (0.0, 0.45, 0.9):
            img[int(n * 0.88):, int(n * x0):int(n * (x0 + 0.1))] = 0.1  # gaps between blocks
    else:
        img = 0.5 + _noise(rng, (n, n), 32, 0.02)
    return np.clip(img, 0.02, 0.95).astype(np.float32)


#: Obstacle kind -> tile width (m) along its sides; the tile height is the obstacle's height.
OBSTACLE_TILE = {"rack": 2.7, "machine": 3.0, "pillar": 1.2, "pallet": 1.2}


# -------------------------------------------------------------- distractors
#: Distractor kinds placed on walls (size in m: width, height).
DISTRACTOR_SIZES = {
    "striped_sign": (0.40, 0.30),
    "barcode": (0.30, 0.15),
    "hazard_sign": (0.35, 0.35),
    "bars_sign": (0.30, 0.22),
}


def distractor_texture(kind: str, rng: np.random.Generator, texels_per_m: int = 1024) -> np.ndarray:
    """Reflectance of a wall distractor of ``kind`` (see :data:`DISTRACTOR_SIZES`).

    ``striped_sign``: five or six equal black/white vertical stripes on a white board
    (a row scanner sees many equal runs); ``barcode``: random-width bars;
    ``hazard_sign``: diagonal hazard stripes; ``bars_sign``: two black bars of
    unequal widths or heights on white (almost a target, but wrong proportions).
    """
    w_m, h_m = DISTRACTOR_SIZES[kind]
    w, h = int(round(w_m * texels_per_m)), int(round(h_m * texels_per_m))
    img = np.full((h, w), WHITE_REFLECTANCE, np.float32)
    yy, xx = np.mgrid[0:h, 0:w]
    m = int(0.04 * texels_per_m)  # border
    if kind == "striped_sign":
        k = int(rng.integers(5, 7))
        stripe = (w - 2 * m) / (2 * k - 1)
        inner = (xx >= m) & (xx < w - m) & (yy >= m) & (yy < h - m)
        img[inner & ((((xx - m) / stripe).astype(int) % 2) == 0)] = BLACK_REFLECTANCE
    elif kind == "barcode":
        x = m
        module = max(2, int(0.0015 * texels_per_m))
        while x < w - m:
            bw = module * int(rng.integers(1, 5))
            img[m:h - m // 2 - int(0.03 * texels_per_m), x:min(x + bw, w - m)] = BLACK_REFLECTANCE
            x += bw + module * int(rng.integers(1, 5))
    elif kind == "hazard_sign":
        img = np.where(((xx + yy) % int(0.08 * texels_per_m)) < int(0.04 * texels_per_m),
                       BLACK_REFLECTANCE, 0.75).astype(np.float32)
        img[:m] = img[-m:] = BLACK_REFLECTANCE
        img[:, :m] = img[:, -m:] = BLACK_REFLECTANCE
    elif kind == "bars_sign":
        bw = (w - 2 * m) / 3
        widths = (bw * rng.uniform(0.5, 0.8), bw * rng.uniform(1.2, 1.5))
        img[m:h - m, m:m + int(widths[0])] = BLACK_REFLECTANCE
        img[m + int(0.3 * (h - 2 * m)):h - m, w - m - int(widths[1]):w - m] = BLACK_REFLECTANCE
    else:
        raise ValueError(f"unknown distractor kind {kind!r}; expected one of {', '.join(DISTRACTOR_SIZES)}")
    return img.astype(np.float32)
