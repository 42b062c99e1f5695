"""Drawing results on frames (thesis Fig. 5.3), text at its final pixel size, and optional debug images."""
from __future__ import annotations

import importlib.util
import math
import os
from functools import lru_cache
from typing import Sequence

import numpy as np

from localizer.model.observation import TargetObservation

#: Text height (px, the font's em size) of the labels :func:`annotate` draws: capitals about 10 px.
LABEL_PX = 14


@lru_cache(maxsize=16)
def _font(size: int):
    """DejaVu Sans (matplotlib's own copy: it has α, β and °) at ``size`` px, else Pillow's default."""
    from PIL import ImageFont

    spec = importlib.util.find_spec("matplotlib")
    if spec is not None and spec.submodule_search_locations:
        path = os.path.join(spec.submodule_search_locations[0], "mpl-data", "fonts", "ttf", "DejaVuSans.ttf")
        if os.path.exists(path):
            return ImageFont.truetype(path, size)
    return ImageFont.load_default(size)


def text_box(text: str, size: int = LABEL_PX, halo: int = 2) -> tuple[int, int]:
    """``(width, height)`` in pixels that :func:`draw_text` covers for ``text`` at ``size`` px
    (with its ``halo``)."""
    x0, y0, x1, y1 = _font(int(size)).getbbox(text, anchor="lt", stroke_width=int(halo))
    return int(math.ceil(x1 - min(x0, 0))), int(math.ceil(y1 - min(y0, 0)))


def glyph_height(text: str, size: int = LABEL_PX) -> int:
    """Height in pixels of ``text``'s inked glyphs at ``size`` px (no halo): what a reader sees."""
    _, y0, _, y1 = _font(int(size)).getbbox(text, anchor="ls")
    return int(round(y1 - y0))


def draw_text(image: np.ndarray, text: str, org: tuple[int, int], size: int = LABEL_PX,
              color=(255, 255, 255), halo_color=(0, 0, 0), halo: int = 2) -> tuple[int, int, int, int]:
    """Draw ``text`` in place on ``image`` ((H, W, 3) or (H, W) uint8) at its final size.

    Args:
        org: ``(x, y)`` pixel of the text box's top left corner (halo included).
        size: font size in pixels (the em height; capitals are about 0.73 of it).
        color, halo_color: in ``image``'s own channel order (RGB or BGR); ``halo_color=None``
            or ``halo=0`` for no outline (the halo keeps text readable over any background).
    Returns:
        ``(x0, y0, x1, y1)`` the pixel box drawn into (clipped to the image).
    """
    from PIL import Image, ImageDraw

    font = _font(int(size))
    stroke = int(halo) if halo_color is not None else 0
    w, h = text_box(text, size, stroke)
    x0, y0 = int(org[0]), int(org[1])
    H, W = image.shape[:2]
    cx0, cy0, cx1, cy1 = max(0, x0), max(0, y0), min(W, x0 + w), min(H, y0 + h)
    if cx1 <= cx0 or cy1 <= cy0:
        return cx0, cy0, cx0, cy0
    crop = Image.fromarray(np.ascontiguousarray(image[cy0:cy1, cx0:cx1]))
    grey = image.ndim == 2
    fill = int(np.mean(color)) if grey else tuple(int(c) for c in color)
    stroke_fill = None
    if stroke:
        stroke_fill = int(np.mean(halo_color)) if grey else tuple(int(c) for c in halo_color)
    ImageDraw.Draw(crop).text((x0 - cx0 + stroke, y0 - cy0 + stroke), text, font=font, fill=fill, anchor="lt",
                              stroke_width=stroke, stroke_fill=stroke_fill)
    image[cy0:cy1, cx0:cx1] = np.asarray(crop)
    return cx0, cy0, cx1, cy1


def observation_label(index: int, observation: TargetObservation) -> str:
    """``"1: d=3.20 m  α=25.0°  β=-4.1°"``: how :func:`annotate` labels an observation (the
    units the rest of the tool reports: metres, degrees)."""
    o = observation
    def deg(x: float) -> str:  # one decimal, no "-0.0"
        return f"{round(math.degrees(x), 1) + 0.0:.1f}°"

    return f"{index}: d={o.distance:.2f} m  α={deg(o.alpha)}  β={deg(o.beta)}"


def annotate(image: np.ndarray, observations: Sequence[TargetObservation], scale: float = 1.0,
             label_px: int = LABEL_PX) -> np.ndarray:
    """A BGR copy of ``image`` with each target's edges, bar heights and (d, α, β) marked.

    Args:
        image: ``(H, W)`` uint8 grey or ``(H, W, 3)`` BGR frame.
        scale: size of the result relative to ``image`` (the frame is resized first, the marks
            and the labels are drawn at the final size, labels ``label_px`` pixels high).
    Returns:
        ``(round(H·scale), round(W·scale), 3)`` uint8 BGR image (undistorted edge coordinates
        drawn as measured).
    """
    import cv2

    out = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image.copy()
    if scale != 1.0:
        size = (max(1, int(round(out.shape[1] * scale))), max(1, int(round(out.shape[0] * scale))))
        out = cv2.resize(out, size, interpolation=cv2.INTER_AREA)
    sh = 4  # fixed-point bits for subpixel drawing
    f = (1 << sh) * scale

    def pt(x, y):
        return int(round(x * f)), int(round(y * f))

    tick = max(2.0, 3.0 / scale)
    for i, o in enumerate(observations):
        m = o.measurements
        r0, r1 = m.rows
        for x in m.edges_x:
            cv2.line(out, pt(x, r0), pt(x, r1), (0, 255, 0), 1, cv2.LINE_AA, sh)
        for k in range(2):
            cx = m.bar_cx[k]
            cv2.line(out, pt(cx, m.top_y[k]), pt(cx, m.bottom_y[k]), (0, 0, 255), 1, cv2.LINE_AA, sh)
            for y in (m.top_y[k], m.bottom_y[k]):
                cv2.line(out, pt(cx - tick, y), pt(cx + tick, y), (0, 0, 255), 1, cv2.LINE_AA, sh)
        label = observation_label(i + 1, o)
        w, h = text_box(label, label_px)
        x = int(min(max(0.0, m.outer_edges[0] * scale), max(0, out.shape[1] - w)))
        y = int(min(min(m.top_y) * scale, out.shape[0]) - h - 3)
        if y < 0:  # no room above the target: below it
            y = int(min(max(m.bottom_y) * scale + 3, out.shape[0] - h))
        draw_text(out, label, (x, y), label_px, color=(0, 255, 255), halo_color=(0, 0, 0))
    return out


def write_debug_images(directory: str, image: np.ndarray, camera, p, stacks, verified, observations) -> None:
    """Write ``coarse.png`` (thresholded coarse lines), ``stacks.png`` (candidates in
    red, verified in green) and ``result.png`` into ``directory``."""
    import cv2

    from localizer._kernels.noise import frame_noise
    from localizer.search.scan import threshold_lines

    os.makedirs(directory, exist_ok=True)
    rows = np.arange(0, image.shape[0], int(p.coarse_step))
    lines = image[rows]
    binary = np.full(image.shape, 128, np.uint8)
    noise = frame_noise(np.ascontiguousarray(image), int(p.coarse_step))
    binary[rows] = np.where(threshold_lines(lines, p, int(p.threshold_window), noise), 255, 0)
    cv2.imwrite(os.path.join(directory, "coarse.png"), binary)
    vis = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    for group, colour in ((stacks, (0, 0, 255)), (verified, (0, 255, 0))):
        for s in group:
            for y, xb in zip(s.rows, s.x):
                vis[y, xb[0]:xb[3]] = (0.5 * vis[y, xb[0]:xb[3]] + 0.5 * np.array(colour)).astype(np.uint8)
    cv2.imwrite(os.path.join(directory, "stacks.png"), vis)
    cv2.imwrite(os.path.join(directory, "result.png"), annotate(image, observations))
