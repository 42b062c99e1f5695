"""The key of a top-down view: swatches with labels, a scale bar, and the axes' tick labels.

Drawn with OpenCV (shapes) and :func:`localizer.tools.annotation.draw_text` (text at its final size),
into the panels :class:`agvsim.analysis.topdown.TopDownView` leaves beside the map, never on it.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from localizer.tools.annotation import draw_text, text_box

TEXT_PX = 14  # key and axis labels: capitals about 10 px high
SWATCH = (30, 14)  # px
_INK = (30, 30, 30)
_GAP = 18  # px between entries on a row


def nice_step(scale: float, min_px: float) -> float:
    """The smallest of 1, 2, 5 x 10^k metres at least ``min_px`` pixels long at ``scale`` px/m."""
    raw = min_px / scale
    k = math.floor(math.log10(raw))
    for m in (1, 2, 5, 10):
        if m * 10 ** k >= raw:
            return float(m * 10 ** k)
    return float(10 ** (k + 1))


def draw_swatch(img: np.ndarray, kind: str, x: int, y: int, color, extra=None) -> None:
    """Draw one key symbol with its top left at ``(x, y)`` (``SWATCH`` px)."""
    w, h = SWATCH
    cy = y + h // 2
    if kind == "line":
        cv2.line(img, (x + 1, cy), (x + w - 1, cy), color, int(extra or 3), cv2.LINE_AA)
    elif kind == "patch":
        cv2.rectangle(img, (x + 2, y + 1), (x + w - 2, y + h - 1), color, -1)
        cv2.rectangle(img, (x + 2, y + 1), (x + w - 2, y + h - 1), (80, 80, 80), 1)
    elif kind == "zone":  # the zone's colour blended as on the map
        colour, alpha = color
        roi = img[y + 1:y + h, x + 2:x + w - 1]
        roi[:] = (alpha * np.array(colour) + (1 - alpha) * roi).astype(np.uint8)
    elif kind == "target":
        cv2.line(img, (x + 4, cy + 3), (x + w - 4, cy + 3), (200, 40, 40), 6, cv2.LINE_AA)
        cv2.line(img, (x + 4, cy + 3), (x + w - 4, cy + 3), color, 4, cv2.LINE_AA)
        cv2.arrowedLine(img, (x + w // 2, cy + 3), (x + w // 2, y - 1), (200, 40, 40), 1, cv2.LINE_AA, tipLength=0.35)
    elif kind == "station":
        cv2.circle(img, (x + 9, cy), 5, color, 2, cv2.LINE_AA)
        cv2.line(img, (x + 9, cy), (x + w - 2, cy), color, 2, cv2.LINE_AA)
    elif kind == "vehicle":
        pts = np.array([[x + 4, y + 2], [x + w - 4, y + 2], [x + w - 4, y + h - 2], [x + 4, y + h - 2]], np.int32)
        cv2.fillPoly(img, [pts], color, cv2.LINE_AA)
        cv2.polylines(img, [pts], True, (40, 40, 40), 1, cv2.LINE_AA)
        cv2.line(img, (x + w // 2, cy), (x + w - 4, cy), (40, 40, 40), 2, cv2.LINE_AA)
    elif kind == "ellipse":
        cv2.ellipse(img, (x + w // 2, cy), (w // 2 - 2, h // 2 - 2), 0, 0, 360, color, 1, cv2.LINE_AA)
    elif kind == "fov":
        tri = np.array([[x + 2, cy], [x + w - 2, y], [x + w - 2, y + h]], np.int32)
        roi = img.copy()
        cv2.fillPoly(roi, [tri], color)
        img[:] = cv2.addWeighted(roi, 0.3, img, 0.7, 0)
    elif kind == "wall":
        cv2.line(img, (x + 1, cy), (x + w - 1, cy), color, 4, cv2.LINE_AA)


def entry_width(label: str) -> int:
    return SWATCH[0] + 6 + text_box(label, TEXT_PX, 0)[0]


def draw_entries(img: np.ndarray, box: tuple[int, int, int, int], entries, row_h: int) -> int:
    """Flow ``entries`` (``(kind, colour, extra, label)``) left to right in ``box`` (x0, y0, x1, y1),
    wrapping rows ``row_h`` px apart; returns the y below the last row."""
    x0, y0, x1, _ = box
    x, y = x0, y0
    for kind, color, extra, label in entries:
        w = entry_width(label)
        if x > x0 and x + w > x1:
            x, y = x0, y + row_h
        draw_swatch(img, kind, x, y + (row_h - SWATCH[1]) // 2, color, extra)
        draw_text(img, label, (x + SWATCH[0] + 6, y + (row_h - text_box("Ag", TEXT_PX, 0)[1]) // 2),
                  TEXT_PX, color=_INK, halo_color=None)
        x += w + _GAP
    return y + row_h


def rows_needed(entries, width: int) -> int:
    """How many rows :func:`draw_entries` takes for ``entries`` in ``width`` px."""
    rows, x = 1, 0
    for *_, label in entries:
        w = entry_width(label)
        if x > 0 and x + w > width:
            rows, x = rows + 1, 0
        x += w + _GAP
    return rows


def draw_scale_bar(img: np.ndarray, x: int, y: int, scale: float, row_h: int, max_px: int = 160) -> int:
    """A bar of a round length in metres at ``(x, y)`` with its length written after it; returns its width."""
    length = nice_step(scale, 0.4 * max_px)
    px = int(round(length * scale))
    cy = y + row_h // 2
    cv2.rectangle(img, (x, cy - 3), (x + px, cy + 3), (255, 255, 255), -1)
    cv2.rectangle(img, (x, cy - 3), (x + px // 2, cy + 3), _INK, -1)
    cv2.rectangle(img, (x, cy - 3), (x + px, cy + 3), _INK, 1)
    label = f"{length:g} m"
    draw_text(img, label, (x + px + 6, y + (row_h - text_box("Ag", TEXT_PX, 0)[1]) // 2), TEXT_PX,
              color=_INK, halo_color=None)
    return px + 6 + text_box(label, TEXT_PX, 0)[0]


def draw_axes(img: np.ndarray, view) -> None:
    """Ticks and labels in metres along the map area's left and bottom edges (in the gutters)."""
    u0, v0, u1, v1 = view.map_box
    xmin, ymin, xmax, ymax = view.map.bounds
    step = nice_step(view.scale, 60.0)
    th = text_box("0", TEXT_PX, 0)[1]
    unit = "x (m)"
    unit_x = u1 - text_box(unit, TEXT_PX, 0)[0] - 2
    draw_text(img, unit, (unit_x, v1 + 5), TEXT_PX, color=_INK, halo_color=None)
    for x in np.arange(math.ceil(xmin / step) * step, xmax + 1e-9, step):
        u = int(round(view.to_pixels(np.array([x, ymin]))[0]))
        cv2.line(img, (u, v1), (u, v1 + 4), _INK, 1)
        label = f"{x:g}"
        lw = text_box(label, TEXT_PX, 0)[0]
        if u + lw // 2 + 4 < unit_x:  # no label under the unit
            draw_text(img, label, (u - lw // 2, v1 + 5), TEXT_PX, color=_INK, halo_color=None)
    for y in np.arange(math.ceil(ymin / step) * step, ymax + 1e-9, step):
        v = int(round(view.to_pixels(np.array([xmin, y]))[1]))
        cv2.line(img, (u0 - 4, v), (u0, v), _INK, 1)
        label = f"{y:g}"
        draw_text(img, label, (u0 - 6 - text_box(label, TEXT_PX, 0)[0], v - th // 2), TEXT_PX, color=_INK,
                  halo_color=None)
    draw_text(img, "y (m)", (2, max(0, v0 - th - 2)), TEXT_PX, color=_INK, halo_color=None)
    cv2.rectangle(img, (u0 - 1, v0 - 1), (u1, v1), (150, 150, 150), 1)
