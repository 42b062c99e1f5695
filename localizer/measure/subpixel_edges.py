"""Subpixel edges around the rough edges of a verified stack (after thesis §4.6).

The gradient peak located by its centroid inside a symmetric window re-centred on the
estimate (two passes). For box-filter pixels the centroid of the differences of a
blurred step is unbiased for any symmetric blur; clipping (saturation) and the
truncation by nearby edges shift all edges towards their dark side by one common
amount, which the exact pose fit estimates (:mod:`localizer.measure.exact_pose`). On saturated
(clipped) targets with some blur the edges are then re-measured by a clipped,
blurred-step model whose blur and levels are shared by all edges of the target
(:mod:`localizer._kernels.clipped`). Kernels: :mod:`localizer._kernels.subpixel`.
"""
from __future__ import annotations

import numpy as np

from localizer._kernels.subpixel import edge_rows, horizontal_stage, line_fits, subpixel, vertical_stage
from localizer.model.camera import Camera
from localizer.measure.edges import EdgeMeasurements, rough_ends, undistort_vertical
from localizer.search.recognize import Stack


def edge_inputs(image: np.ndarray, st: Stack) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What :func:`subpixel_edges` measures a stack on: ``(rows (n,), bounds (4,), ends (2, 2))``,
    the stack's rows but the first and last eighth (blur, slanted tops), its median run
    boundaries and its rough bar ends (top, bottom row per bar; found at the rough bar
    centres for a stack that was not verified)."""
    bounds = np.asarray(st.bounds, np.float64)
    rows = edge_rows(image, st.rows, bounds)
    ends = st.ends
    if not ends:
        thr = 0.5 * (st.dark + st.bright)
        cx0 = 0.5 * (bounds[:2].sum() - 1.0), 0.5 * (bounds[2:].sum() - 1.0)
        ends = [rough_ends(image, st, int(np.clip(round(c), 0, image.shape[1] - 1)), thr) for c in cx0]
    return rows, bounds, np.asarray(ends, np.int64)


def subpixel_edges(image: np.ndarray, camera: Camera, st: Stack) -> EdgeMeasurements:
    """Subpixel edges (gradient-peak centroid, :func:`localizer._kernels.subpixel.centroid_edge`)
    of the verified stack ``st`` in ``image`` (H, W) uint8.

    For box-filter pixels the centroid of the differences of a blurred step is
    unbiased for any symmetric blur. Clipping (saturation) moves every edge
    towards its dark side, by an amount that the exact pose fit estimates as a
    common ``delta`` (:mod:`localizer.measure.exact_pose`); what is left is a per-edge part that
    depends on the edge's pixel phase (up to about +-0.3 px for sharp saturated
    edges, where the clipped pixels hide where in them the edge lies), which the
    covariance allows for. When the target is clipped and blurred (fitted blur
    sd >= 0.3 px, mean run >= 8 px), the vertical edges are replaced by a joint
    clipped-erf fit of the row-mean profile (:func:`localizer._kernels.clipped.fit_bar_profile`: four edges,
    one blur sd, one unclipped bright and one dark level) and each top/bottom
    point by a position-only fit with that blur and those levels
    (:func:`localizer._kernels.clipped.refine_horizontal_clipped`), which removes most of that per-edge part.

    Vertical edges: on every stack row (but the first and last eighth) the
    differences ``f(x+1) - f(x)`` of an ``L = 11``-pixel window around each of the
    four rough edges (:func:`localizer._kernels.subpixel.vertical_edges`, compiled); one centroid per row
    and edge, averaged over rows (eq: ``X = sum
    x_i / n``, §4.6.2). Tops and bottoms: the same on every interior column of
    each bar, in a vertical window around the line through the rough bar ends;
    a straight line fitted per bar and side, evaluated at the bar's centre
    column. Returns pixel coordinates (undistorted when the camera has distortion).
    """
    rows, bounds, ends = edge_inputs(image, st)
    if not camera.has_distortion:
        m, xs, xcol, ys = subpixel(image, rows, bounds, ends, bool(st.positive))
        edges, sd_e, cxs, top, bottom, top_sd, bottom_sd = m
    else:  # the same stages, with the measured points undistorted in between
        xs, fit = vertical_stage(image, rows, bounds, bool(st.positive))
        xs = undistort_vertical(camera, xs, rows)
        edges, sd_e, cxs, ccat, grp, ys, sd_fallback = horizontal_stage(image, xs, fit, ends, bool(st.positive))
        und = camera.undistort_points(np.stack([ccat.astype(float), ys], 1))
        xcol, ys = und[:, 0].copy(), und[:, 1].copy()
        icpt, sig = line_fits(grp, xcol, cxs, ys, sd_fallback)
        top, bottom, top_sd, bottom_sd = icpt[:2], icpt[2:], sig[:2], sig[2:]
    return EdgeMeasurements(edges, sd_e, cxs, top, bottom, top_sd, bottom_sd, (int(rows[0]), int(rows[-1])),
                            _raw=(xs, rows, xcol, ys))

