"""Drawing results on frames (thesis Fig. 5.3) and optional debug images."""
from __future__ import annotations

import math
import os
from typing import Sequence

import numpy as np

from localizer.observation import TargetObservation


def annotate(image: np.ndarray, observations: Sequence[TargetObservation]) -> np.ndarray:
    """A BGR copy of ``image`` with each target's edges, bar heights and (d, α) marked.

    Args:
        image: ``(H, W)`` uint8 grey or ``(H, W, 3)`` BGR frame.
    Returns:
        ``(H, W, 3)`` uint8 BGR image (undistorted edge coordinates drawn as measured).
    """
    import cv2

    out = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image.copy()
    sh = 4  # fixed-point bits for subpixel drawing
    f = 1 << sh
    for i, o in enumerate(observations):
        m = o.measurements
        r0, r1 = m.rows
        for x in m.edges_x:
            cv2.line(out, (int(round(x * f)), int(round(r0 * f))), (int(round(x * f)), int(round(r1 * f))),
                     (0, 255, 0), 1, cv2.LINE_AA, sh)
        for k in range(2):
            cx = m.bar_cx[k]
            cv2.line(out, (int(round(cx * f)), int(round(m.top_y[k] * f))),
                     (int(round(cx * f)), int(round(m.bottom_y[k] * f))), (0, 0, 255), 1, cv2.LINE_AA, sh)
            for y in (m.top_y[k], m.bottom_y[k]):
                cv2.line(out, (int(round((cx - 3) * f)), int(round(y * f))),
                         (int(round((cx + 3) * f)), int(round(y * f))), (0, 0, 255), 1, cv2.LINE_AA, sh)
        label = f"{i + 1}: d={o.distance * 1000:.0f}mm a={math.degrees(o.alpha):.1f}"
        org = (int(max(0, m.outer_edges[0])), int(max(12, min(m.top_y) - 8)))
        cv2.putText(out, label, org, cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(out, label, org, cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 255, 255), 1, cv2.LINE_AA)
    return out


def write_debug_images(directory: str, image: np.ndarray, camera, p, stacks, verified, observations) -> None:
    """Write ``coarse.png`` (thresholded coarse lines), ``stacks.png`` (candidates in
    red, verified in green) and ``result.png`` into ``directory``."""
    import cv2

    from localizer.scan import threshold_lines

    os.makedirs(directory, exist_ok=True)
    rows = np.arange(0, image.shape[0], int(p.coarse_step))
    lines = image[rows]
    binary = np.full(image.shape, 128, np.uint8)
    binary[rows] = np.where(threshold_lines(lines, p, int(p.threshold_window)), 255, 0)
    cv2.imwrite(os.path.join(directory, "coarse.png"), binary)
    vis = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    for group, colour in ((stacks, (0, 0, 255)), (verified, (0, 255, 0))):
        for s in group:
            for y, xb in zip(s.rows, s.x):
                vis[y, xb[0]:xb[3]] = (0.5 * vis[y, xb[0]:xb[3]] + 0.5 * np.array(colour)).astype(np.uint8)
    cv2.imwrite(os.path.join(directory, "stacks.png"), vis)
    cv2.imwrite(os.path.join(directory, "result.png"), annotate(image, observations))
