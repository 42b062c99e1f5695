"""Edge measurements of a verified stack (thesis §4.6): the record both edge detectors return.

Two detectors share the rough geometry of a verified stack
(:class:`localizer.search.recognize.Stack`):

* :func:`localizer.thesis.edges.thesis_edges` -- the thesis's half-pixel rule (§4.6.2);
* :func:`localizer.measure.subpixel_edges.subpixel_edges` -- gradient-peak centroids, and on
  saturated blurred targets a clipped-erf edge model.

Both return an :class:`EdgeMeasurements` in undistorted pixel coordinates.
Coordinates follow :mod:`localizer.model.camera` (pixel centres at integers).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from localizer._kernels.verify import rough_ends as rough_ends_kernel
from localizer.model.camera import Camera
from localizer.search.recognize import Stack

#: the sign of alpha read from the bars' measured height difference is sure (not ambiguous)
#: when the difference is at least this many standard errors from zero
#: (:func:`localizer.thesis.edges.height_sign`)
SIGN_SIGMAS = 3.0


@dataclass(frozen=True)
class EdgeMeasurements:
    """Edge positions of one target (pixels, undistorted).

    ``edges_x`` (4,): x of the bar edges, left to right, averaged over rows;
    ``edges_sigma`` (4,): their standard errors. ``top_y``/``bottom_y`` (2,):
    y of the bar tops/bottoms at the bar centre columns ``bar_cx`` (2,);
    ``top_sigma``/``bottom_sigma`` (2,). ``rows`` (first, last) image rows used
    for the vertical edges. :attr:`points` maps names to ``(N, 2)`` edge points for
    drawing. ``height_sign``: the sign of ``h2 - h1`` that chooses the root of eq 4.13
    (§4.2.2; 0 undecided), ``height_difference``: ``(h2 - h1, its sd)`` (px) measured over
    each bar's columns (NaN if not measured); both from
    :func:`localizer.thesis.edges.thesis_edges`.
    """

    edges_x: np.ndarray
    edges_sigma: np.ndarray
    bar_cx: np.ndarray
    top_y: np.ndarray
    bottom_y: np.ndarray
    top_sigma: np.ndarray
    bottom_sigma: np.ndarray
    rows: tuple[int, int]
    height_sign: int = 0
    #: (x (n, 4), rows (n,), cols (m,), y (m,)): the edge points measured, for ``points``
    _raw: tuple | None = field(default=None, compare=False, repr=False)
    height_difference: tuple[float, float] = (float("nan"), float("nan"))

    @property
    def height_sign_sure(self) -> bool:
        """Whether :attr:`height_difference` is at least :data:`SIGN_SIGMAS` standard errors
        from zero (the sign of alpha is then measured, not a tie-break's guess)."""
        diff, sd = self.height_difference
        return bool(abs(diff) >= SIGN_SIGMAS * sd)

    @property
    def bar_heights(self) -> np.ndarray:
        """(h1, h2) pixel heights of the left and right bar at their centres."""
        return self.bottom_y - self.top_y

    @property
    def points(self) -> dict:
        """``{"vertical": (4n, 2), "horizontal": (m, 2)}`` (x, y) edge points measured, for
        drawing."""
        if self._raw is None:
            return {}
        xs, rows, xcol, ys = self._raw
        return {"vertical": np.stack([xs.ravel(), np.repeat(rows, xs.shape[1]).astype(float)], 1),
                "horizontal": np.stack([xcol, ys], 1)}


def rough_ends(image: np.ndarray, st: Stack, col: int, thr: float) -> tuple[int, int]:
    """First and last row of the bar crossing the stack ``st`` at column ``col``, walking from
    the stack while the pixel keeps the bar's shade at threshold ``thr`` (grey level)
    (:func:`localizer._kernels.verify.rough_ends`)."""
    return rough_ends_kernel(image, int(st.rows[0]), int(st.rows[-1]), st.n_rows, int(col), float(thr),
                             bool(st.positive))


def undistort_vertical(camera: Camera, xs: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The vertical-edge x ``xs`` (n, 4) measured on image ``rows`` (n,), undistorted (px)."""
    if not camera.has_distortion:
        return xs
    pts = np.stack([xs.ravel(), np.repeat(rows, xs.shape[1]).astype(float)], axis=1)
    return camera.undistort_points(pts)[:, 0].reshape(xs.shape)
