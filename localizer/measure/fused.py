"""The common path of :func:`localizer.detect_targets` in one compiled call: its settings and its call.

For the ``exact`` method on a camera without lens distortion (and no debug images),
:func:`detect_frame` searches the frame and measures every verified stack in
:func:`localizer._kernels.frame.detect_frame`, and returns what Python still has to do per
target. The settings of that call are resolved once per detector parameters, camera and
target (:func:`frame_plan`). The other paths (the thesis method, distorted cameras, debug
images) and the photometric refinement stay in :mod:`localizer.detect`, which turns both into
observations.
"""
from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from localizer._kernels import frame
from localizer._kernels.records import (FusedColumn, FusedTarget, Intrinsics, MeasureSettings, TargetConstants,
                                        as_record)
from localizer.model.params import DetectionStats, DetectorParams
from localizer.search.recognize import add_counts, search_settings

__all__ = ["EdgeChecks", "FramePlan", "FrameTargets", "detect_frame", "frame_plan"]

#: the first covariance column of the fused call's table (9 columns, row by row)
COV = int(FusedColumn.COV00)


class FramePlan(NamedTuple):
    """The settings of one frame's compiled call (:func:`frame_plan`; the records are shared:
    do not change them)."""

    search: np.ndarray  # (1,) SEARCH_SETTINGS record
    measure: np.ndarray  # (1,) MEASURE_SETTINGS record


class FrameTargets(NamedTuple):
    """What :func:`detect_frame` found: the search's rows ``(N,)`` and run boundaries ``(N, 4)``
    of its candidates' lines, the candidates (CANDIDATE records), and per verified stack a
    :class:`~localizer._kernels.records.FusedTarget` (:func:`localizer._kernels.frame.detect_frame`)
    and its covariance ``(3, 3)`` (over d, beta, alpha: ``covariances[j]`` is ``targets[j]``'s)."""

    rows: np.ndarray
    x: np.ndarray
    candidates: np.ndarray
    targets: list[FusedTarget]
    covariances: np.ndarray  # (V, 3, 3)


class EdgeChecks(NamedTuple):
    """:mod:`localizer.detect`'s decisions on a target's edge-based pose, as the fused call makes them."""

    encoded_shift: float  # share of the blur sd: the edges' common shift that says "linearize" (ENCODED_SHIFT)
    max_shift_share: float  # share of the blur sd: a larger shift is not a target (MAX_SHIFT_SHARE)
    max_alpha: float  # rad, the largest |alpha| reported
    max_fit_rms: float  # the largest normalised fit residual reported
    clipped_floor: float  # px, the per-edge error floor of a clipped target (at least)


@functools.lru_cache(maxsize=64)
def frame_plan(p: DetectorParams, camera: Intrinsics, target: TargetConstants, checks: EdgeChecks) -> FramePlan:
    """The :class:`FramePlan` of resolved parameters ``p`` (:meth:`DetectorParams.resolved`), an
    undistorted camera's intrinsics (px), a target's bar width, height and margin (m), and
    :mod:`localizer.detect`'s decisions on a target's edges (cached)."""
    fx, fy, cx, cy = camera
    bar_width, bar_height, margin = target
    return FramePlan(search_settings(p, fx, fy, bar_width, bar_height), as_record(MeasureSettings(
        fx=fx, fy=fy, cx=cx, cy=cy, bar_width=bar_width, bar_height=bar_height, margin=margin,
        sigma_floor=float(p.edge_sigma_floor), clipped_floor=max(float(p.edge_sigma_floor), checks.clipped_floor),
        iterations=8, width_tolerance=float(p.width_tolerance), width_slack=float(p.width_slack),
        min_rows=float(p.min_rows), srgb=p.response == "srgb", auto_response=p.response == "auto",
        encoded_shift=checks.encoded_shift, max_shift_share=checks.max_shift_share,
        refine_all=p.photometric == "all", refine_clipped=p.photometric == "clipped",
        refine_auto=p.photometric == "auto", refine_alpha_var=float(p.refine_alpha_sd) ** 2,
        refine_range_sd=float(p.refine_range_sd), max_alpha=checks.max_alpha, max_fit_rms=checks.max_fit_rms)))


def detect_frame(image: np.ndarray, plan: FramePlan, lut: np.ndarray, stats: DetectionStats | None,
                 search_image: np.ndarray | None = None) -> FrameTargets:
    """The search and measurement of ``image`` (``(H, W)`` uint8, C-contiguous) in one compiled
    call (:func:`localizer._kernels.frame.detect_frame`; ``lut`` the sRGB inverse), the search's
    counts added to ``stats`` when given; the search on ``search_image`` when given (the frame's
    sharpened copy, same shape), the measurement on ``image`` always. Raises what the compiled
    call raises (a degenerate measurement: ``ZeroDivisionError``, ...): the caller then takes the
    step-by-step path."""
    sr, table = frame.detect_frame(image, image if search_image is None else search_image, plan.search, plan.measure,
                                   lut)
    if stats is not None:
        add_counts(stats, sr.counts)
    return FrameTargets(sr.rows, sr.x, sr.candidates, [FusedTarget._make(t) for t in table.tolist()],
                        table[:, COV:COV + 9].reshape(-1, 3, 3))
