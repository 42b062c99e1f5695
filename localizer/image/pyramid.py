"""Large frames: find the targets on a coarser level of the image, measure each where its blur
is one or two pixels.

A sensor of several megapixels behind an ordinary lens spreads an edge over many pixels: the
thesis camera's 3 px of optical blur at 512 x 480 is 7.5 px at 1280 x 1024 and 14 px at
2448 x 2048. The recognizer follows the blur it measures, but its windows (edge centroids of
at most +-4 px, the refinement's blur of at most 4 px) are sized for edges of a few pixels: on
edges blurred over 7.5 px the centroids stay near their rough starts and the tops and bottoms
of narrow bars come out up to 2 px inside (range +6 %), and at 14 px a third of the targets
are not found. An area-averaged (box-filtered) copy of the frame holds the same information
about such an edge in fewer pixels. So a frame of at least ``2 * LEVEL_ROWS`` rows is searched
on its coarse level (area-downsampled by the power of two ``k`` that leaves at least
``LEVEL_ROWS`` rows: about the thesis camera's resolution, where a target is large enough to be
found wherever it is in the envelope), and each target found there (without the pixel-level
refinement) is measured again on a crop of the finest level whose blur is at most
``SIGMA_TARGET`` px (the full frame's pixels for a sharp target), with the full frame's
detector parameters (lengths scaled to the level): the blur the thesis camera's pipeline is
accurate at (blur2 at 512 x 480: range error 0.05 % mean). That level may be coarser than the
search's (a strongly blurred target; if it does not confirm the target there, e.g. a small one
that has become too few pixels for the recognizer, the levels down to the search's are tried
in turn). A crop is a pinhole camera too (principal point moved by the crop's corner), so
the pose it gives needs no conversion; its pixel measurements are moved back to the frame's
coordinates. A candidate of the coarse level that its finer level does not confirm is not
reported (lettering that a coarse level blurs into bars); one that is not confirmed on any
level from its own to the search's is reported as measured on the search level.

Pixel convention (:class:`localizer.model.camera.Camera`): pixel ``j`` covers ``[j - 0.5, j + 0.5]``;
level ``k``'s pixel ``j`` covers the frame's pixels ``k j .. k j + k - 1``, i.e. frame
coordinate ``x = k (x_k + 0.5) - 0.5`` (:meth:`Camera.scaled`).
"""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from localizer._kernels.area import area_half, area_quarter
from localizer._kernels.subpixel import rows_blur
from localizer.model.camera import Camera
from localizer.model.params import DetectorParams
from localizer.model.observation import ImageMeasurements, TargetObservation

__all__ = ["LEVEL_ROWS", "SIGMA_TARGET", "coarse_factor", "detect_pyramid", "level_image"]

#: the coarse level keeps at least this many rows (the thesis camera's 480)
LEVEL_ROWS = 480
#: a target is measured on the finest level where its blur sd is at most this (px): the envelope
#: benchmark's blur3_1280 and blur3_2448 frames (7.5 and 14 px) measured where their blur is at
#: most 1.5 px (a factor of 8) gave a range error of 0.38 % mean and 3.9 % max (targets of 9-29
#: rows: too few pixels), at most 2 px 0.22 % and 1.8 %, at most 2.5 px 0.28 % and 4.1 %
SIGMA_TARGET = 2.0
#: the coarsest level a target is measured on (a factor of the frame's pixels)
MAX_FACTOR = 16
#: the crop around a coarse target, in target widths either side and bar heights above and below
CROP_WIDTHS = 0.75
CROP_HEIGHTS = 0.75
#: a crop's coarse lines: at least this many across the target's shorter bar
CROP_LINES = 8


def coarse_factor(height: int) -> int:
    """The power of two ``k >= 1`` by which a frame ``height`` rows high is downsampled for the
    search: the largest that leaves at least :data:`LEVEL_ROWS` rows."""
    k = 1
    while height // (2 * k) >= LEVEL_ROWS:
        k *= 2
    return k


def level_image(image: np.ndarray, k: int, box: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """``image`` ``(H, W)`` uint8 (its window ``box = (x0, y0, x1, y1)``, default the whole image)
    area-averaged over ``k x k`` blocks (``k`` a power of two): ``((y1 - y0) // k, (x1 - x0) // k)``
    uint8, C-contiguous (the last rows and columns that do not fill a block dropped, so that
    level pixels are whole blocks; ``k = 1``: the window itself, a view). The values of ``log2 k``
    halvings in turn, each 2 x 2 mean rounded to 8 bits as OpenCV's ``INTER_AREA`` rounds it
    (:mod:`localizer._kernels.area`: two halvings at a time, read from the window in place)."""
    h, w = image.shape
    x0, y0, x1, y1 = (0, 0, w, h) if box is None else box
    if k == 1:
        return image[y0:y1, x0:x1]
    if not image.flags.c_contiguous:
        image = np.ascontiguousarray(image)
    hh, ww = (y1 - y0) // k, (x1 - x0) // k  # the level's shape
    while k > 1:
        step = 4 if k >= 4 else 2
        k //= step
        out = np.empty((hh * k, ww * k), np.uint8)
        (area_quarter if step == 4 else area_half)(image, y0=y0, x0=x0, out=out)
        image, y0, x0 = out, 0, 0
    return image


def _blur(image: np.ndarray, o: TargetObservation, step: int = 1) -> float:
    """The blur sd (px) of observation ``o``'s target in ``image`` (in whose pixels ``o`` is
    measured): the row-mean profile over every ``step``-th row of its stack (but the first and
    last eighth) across its four edges (``rows_blur``)."""
    m = o.measurements
    r0, r1 = m.rows
    e = (r1 - r0 + 1) // 8
    rows = np.arange(r0 + e, r1 + 1 - e, step, dtype=np.int64)
    if rows.size < 3:
        rows = np.arange(r0, r1 + 1, dtype=np.int64)
    bounds = np.asarray(m.edges_x, np.float64) + 0.5
    return float(rows_blur(image, rows, bounds))


def _to_frame(o: TargetObservation, k: float, dx: float = 0.0, dy: float = 0.0) -> TargetObservation:
    """``o`` measured on a level of factor ``k`` (or a crop at ``(dx, dy)``) with its measurements
    in the frame's pixels (built field by field: ``dataclasses.replace`` costs several times more)."""
    m = o.measurements
    fx = lambda x: k * (x + 0.5) - 0.5 + dx  # noqa: E731
    fy = lambda y: k * (y + 0.5) - 0.5 + dy  # noqa: E731
    ex = tuple(fx(x) for x in m.edges_x)
    top = tuple(fy(y) for y in m.top_y)
    bot = tuple(fy(y) for y in m.bottom_y)
    moved = ImageMeasurements(
        edges_x=ex, outer_edges=(ex[0], ex[3]), h1=bot[0] - top[0], h2=bot[1] - top[1], delta_x=ex[3] - ex[0],
        delta_y=0.5 * (bot[0] - top[0] + bot[1] - top[1]), centre=(fx(m.centre[0]), fy(m.centre[1])),
        bar_cx=tuple(fx(x) for x in m.bar_cx), top_y=top, bottom_y=bot,
        rows=(int(math.floor(fy(m.rows[0] - 0.5) + 0.5)), int(math.ceil(fy(m.rows[1] + 0.5) - 0.5))),
        n_rows=int(round(k * m.n_rows)), dark=m.dark, bright=m.bright)
    return TargetObservation(o.distance, o.beta, o.alpha, o.z, o.x, o.height, o.polarity, o.method, o.covariance,
                             moved, o.alpha_candidates, o.alpha_ambiguous, o.edge_bias, o.fit_rms)


def _crop(camera: Camera, m: ImageMeasurements) -> tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)``: the frame's pixels around a target measured as ``m`` (frame pixels)."""
    wd = m.delta_x
    hb = max(m.h1, m.h2)
    x0 = max(int(math.floor(m.edges_x[0] - CROP_WIDTHS * wd)), 0)
    x1 = min(int(math.ceil(m.edges_x[3] + CROP_WIDTHS * wd)) + 1, camera.width)
    y0 = max(int(math.floor(min(m.top_y) - CROP_HEIGHTS * hb)), 0)
    y1 = min(int(math.ceil(max(m.bottom_y) + CROP_HEIGHTS * hb)) + 1, camera.height)
    return x0, y0, x1, y1


@functools.lru_cache(maxsize=64)
def _params_at(p: DetectorParams, k: int, search: bool = False, max_step: int = 0) -> DetectorParams:
    """The frame's resolved detector parameters ``p`` for its level of factor ``k``: the lengths
    that scale with the image (scan step, threshold window, minimum rows) divided by ``k``, no
    pyramid, and no pixel-level refinement on the ``search`` level; ``max_step`` > 0: coarse
    lines at most that many rows apart (cached)."""
    changes = {"pyramid": False}
    if search:
        changes["photometric"] = "off"
    step = max(1, round(p.coarse_step / k)) if k > 1 else p.coarse_step
    if max_step > 0:
        step = min(step, max_step)
    changes["coarse_step"] = step
    if k > 1:
        changes["threshold_window"] = 2 * max(4, round((p.threshold_window - 1) / (2 * k))) + 1  # odd, as resolved()
        changes["min_rows"] = max(3, round(p.min_rows / k))
    return dataclasses.replace(p, **changes)


def _same(a: TargetObservation, b: TargetObservation) -> bool:
    """Whether two observations are of one target: centres within a quarter of its width."""
    ma, mb = a.measurements, b.measurements
    return abs(ma.centre[0] - mb.centre[0]) < 0.25 * ma.delta_x and abs(ma.centre[1] - mb.centre[1]) < 0.25 * ma.delta_y


def _measure_at(detect, image: np.ndarray, coarse: tuple[np.ndarray, int], camera: Camera, p: DetectorParams,
                box: tuple[int, int, int, int], j: int, bar_rows: float) -> list[TargetObservation]:
    """The targets ``detect`` finds on the crop ``box = (x0, y0, x1, y1)`` of ``image`` (frame pixels)
    area-averaged by ``j``, in the frame's pixels; ``coarse = (level, k)`` the frame's level of
    factor ``k``, from which a level of ``j >= k`` is made (the same pixels: both halve aligned
    blocks in turn; the frame's pixels are not read again). The crop starts on the level's blocks
    (its first column and row rounded down to multiples of ``j``): on the search's level it is
    then a window of the pixels the target was found on, not of others area-averaged in another
    phase (on blurred narrow bars the recognizer's tests can pass on one and not the other).
    ``bar_rows``: the target's shorter bar as found on the search level (frame rows)."""
    x0, y0, x1, y1 = box
    x0, y0 = x0 - x0 % j, y0 - y0 % j
    cam = camera.cropped(x0, y0, x1, y1)
    small, k = coarse
    if j >= k > 1:
        q, nr, nc = j // k, (y1 - y0) // j, (x1 - x0) // j
        patch = level_image(small, q, (x0 // k, y0 // k, x0 // k + nc * q, y0 // k + nr * q))
    else:
        patch = level_image(image, j, (x0, y0, x1, y1))
    if j > 1:
        cam = cam.binned(j)
    # the crop of the search's level or a finer one looks again for a target found there: its lines
    # at most an eighth of the target's bar height apart (the frame's spacing may cross a small
    # target on only three or four lines, and in another phase than the search level's, where a
    # blurred narrow target can pass on one set of lines and not on the other). A coarser level
    # keeps the frame's spacing: there a target that has become too few pixels to measure is to
    # fail (blur3_1280: confirmed on the 320 x 256 level on dense lines, 19 rows, range 10 % off)
    step = max(1, int(bar_rows / (CROP_LINES * j))) if j <= k else 0
    fine = detect(np.ascontiguousarray(patch), cam, _params_at(p, j, max_step=step))
    return [_to_frame(f, j, x0, y0) for f in fine]


def detect_pyramid(detect, image: np.ndarray, camera: Camera, p: DetectorParams) -> list[TargetObservation]:
    """The targets of a large frame ``image`` ``(H, W)`` uint8 (module docstring).

    Args:
        detect: ``detect(image, camera, params) -> list[TargetObservation]`` on one level, with
            resolved :class:`DetectorParams` (:func:`localizer.detect_targets` on a frame it
            need not check; called with ``pyramid=False`` only).
        p: the detector parameters resolved for the whole frame (its scan step, threshold
            window, minimum rows: the crops keep them); ``coarse_step``, ``threshold_window`` and
            ``min_rows`` are scaled for the coarse level.
    Returns:
        the observations in the frame's pixels, top to bottom, left to right.
    """
    k = coarse_factor(image.shape[0])
    small = level_image(image, k)
    out = []
    # the search: on the coarse level, without the pixel-level refinement (each target is
    # measured again below)
    for o in detect(small, camera.binned(k), _params_at(p, k, search=True)):
        coarse = _to_frame(o, k)
        # its blur, measured on the frame itself (on the coarse level a sharp edge and one of up to
        # k px look alike): the finest level where it is at most SIGMA_TARGET px
        s = _blur(image, coarse, step=max(1, k // 2))
        j = 1
        while s / j > SIGMA_TARGET and j < MAX_FACTOR:
            j *= 2
        x0, y0, x1, y1 = _crop(camera, coarse.measurements)
        # finer than the coarse level: that level alone (a target it does not confirm is not
        # reported); coarser: there, else on the coarse level (a small target may be too few
        # pixels for the recognizer on the coarser one)
        for lv in ([j] if j < k else [j // 2 ** i for i in range(int(math.log2(j // k)) + 1)]):
            fine = _measure_at(detect, image, (small, k), camera, p, (x0, y0, x1, y1), lv,
                               min(coarse.measurements.h1, coarse.measurements.h2))
            fine = [f for f in fine if _same(f, coarse)]
            if len(fine) == 1:
                out.append(fine[0])
                break
        else:
            if j >= k:  # not confirmed on the coarse level itself: its own measurement there
                out.append(coarse)
        # (a candidate of the coarse level that its finer level does not confirm is not reported)
    out.sort(key=lambda o: (o.measurements.rows[0], o.measurements.edges_x[0]))
    return out
