"""Search (coarse + fine, §4.4.1), grouping and verification (§4.5.2) of candidates.

A candidate target is a *stack*: consecutive image rows each holding a
matching bar-gap-bar triple. Work per frame, in order of cost:

1. coarse scan: every ``N``-th line thresholded, run-length coded and searched
   for triples in one batch (:mod:`localizer.search.scan`);
2. every triple's grey levels on its own line: contrast between the runs,
   light margins, no grating (the cheap part of §4.5.2), then the minimum
   height and aspect tests in advance: 11 pixels across each surviving hit on
   17 sampled lines around it (:func:`localizer._kernels.search.coarse_seeds`);
3. per remaining hit, the fine search of the thesis -- which walks up and down
   line by line from the hit until no line matches -- over one small region of
   interest thresholded at the hit's own midway level; on each line the runs
   around the hit's gap are found by walking out from it (:func:`localizer._kernels.fine.fine_stack`);
   then the full verification (:func:`localizer._kernels.verify.verify`).

Hits inside a stack already found are not searched again (the thesis's grouping).
The pixel loops are compiled with numba (:mod:`localizer._kernels.search`,
``.fine``, ``.verify``; cached in ``__pycache__`` after the first call in a fresh
environment).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from localizer._kernels import search
from localizer._kernels.records import REASONS, SearchSettings, as_record
from localizer.model.camera import Camera
from localizer.model.params import DetectionStats, DetectorParams
from localizer.search.scan import noise_contrast, run_test
from localizer.model.target import TargetSpec


#: ``DetectionStats.rejected`` keys of :data:`localizer._kernels.records.REASONS`, in order
_REASON_KEYS = tuple(reason.name.lower() for reason in REASONS)
assert [int(r) for r in REASONS] == list(range(1, len(REASONS) + 1))


@dataclass(frozen=True)
class Stack:
    """A verified (or candidate) target region.

    ``rows`` ``(n,)`` image rows (increasing; at most ``max_row_gap`` missing in a
    row); ``x`` ``(n, 4)`` run boundaries of each row's triple (first pixel of
    bar 1, gap, bar 2, one past bar 2); ``positive``: black bars on white;
    ``dark``/``bright``: mean grey levels of the bars and gap (or the reverse for
    negative targets); ``ends`` ``(2, 2)`` rough (first, last) row of each bar at
    its centre column (filled in by verification).
    """

    rows: np.ndarray
    x: np.ndarray
    positive: bool
    dark: float = float("nan")
    bright: float = float("nan")
    ends: tuple = ()
    median_x: np.ndarray | None = None

    @property
    def polarity(self) -> str:
        return "positive" if self.positive else "negative"

    @property
    def n_rows(self) -> int:
        """Rows spanned, first to last (a few may be missing, ``max_row_gap``)."""
        return int(self.rows[-1] - self.rows[0] + 1)

    @property
    def bounds(self) -> np.ndarray:
        """``(4,)`` median run boundaries (columns)."""
        if self.median_x is not None:
            return self.median_x
        return np.median(self.x, axis=0)


def find_stacks(image: np.ndarray, camera: Camera, target: TargetSpec, p: DetectorParams,
                stats: DetectionStats | None, keep_candidates: bool = True) -> tuple[list[Stack], list[Stack]]:
    """Coarse scan every ``coarse_step``-th row, check the hits' grey levels, fine-scan
    around each plausible new hit and verify the stack found
    (:func:`localizer._kernels.verify.verify`).

    The whole search runs in one compiled call (:func:`localizer._kernels.search.recognize`,
    with the settings of :func:`search_settings`); only the packing of the results is Python.

    Returns ``(candidates, verified)``: every stack found (only the verified ones unless
    ``keep_candidates``), and the verified ones (with grey levels and bar ends filled in)
    top to bottom, left to right. ``stats`` is filled in when given (None: no bookkeeping).
    """
    r = search.recognize(image, search_settings(p, camera.fx, camera.fy, target.bar_width, target.bar_height))
    if stats is not None:
        add_counts(stats, r.counts)
    rows, x = r.rows, r.x
    stacks: list[Stack] = []
    verified: list[Stack] = []
    for c in r.candidates.tolist():
        if c[3]:
            st = candidate_stack(rows, x, c)
            verified.append(st)
            stacks.append(st)
        elif keep_candidates:
            stacks.append(candidate_stack(rows, x, c))
    if len(verified) > 1:
        verified.sort(key=lambda s: (int(s.rows[0]), float(s.x[0, 0])))
    return stacks, verified


def candidate_stack(rows: np.ndarray, x: np.ndarray, c: tuple) -> Stack:
    """The :class:`Stack` of a search's candidate ``c`` (a CANDIDATE record as a tuple) whose lines
    are ``rows[start:stop]`` with run boundaries ``x[start:stop]`` (grey levels and bar ends only
    when verified)."""
    a, b, pos, ok, t0, b0, t1, b1, median_x, dark, bright = c
    if ok:
        return Stack(rows[a:b], x[a:b], pos, dark, bright, ((t0, b0), (t1, b1)), median_x)
    return Stack(rows[a:b], x[a:b], pos, median_x=median_x)


def add_counts(stats: DetectionStats, counts: np.ndarray) -> None:
    """Add a search's work counts and rejections (its ``(1,)`` SEARCH_COUNTS record) to ``stats``."""
    (rows_scanned, runs, seeds, candidates, rejected), = counts.tolist()
    stats.rows_scanned += rows_scanned
    stats.runs += runs
    stats.seeds += seeds
    stats.candidates += candidates
    for key, k in zip(_REASON_KEYS, rejected.tolist()[1:]):  # REASONS: Reject 1, 2, ... in order
        if k:
            stats.rejected[key] = stats.rejected.get(key, 0) + k


@functools.lru_cache(maxsize=32)
def search_settings(p: DetectorParams, fx: float, fy: float, bar_width: float, bar_height: float) -> np.ndarray:
    """The :class:`~localizer._kernels.records.SearchSettings` (as its ``(1,)`` record, which
    the caller must not change) of parameters ``p`` (resolved:
    :meth:`DetectorParams.resolved`), a camera's focal lengths (px) and a target's bar width
    and height (m) (cached: ~30 conversions).

    The aspect test's bounds are rows / columns of a target facing the camera
    (``H / W * fy / fx``, ``W = 3b``) widened by ``aspect_tolerance`` (and by
    ``1 / cos(max_alpha)`` above); the bar-height test's slope is
    ``2 (b / H) sin(max_alpha) / fy`` (eq 4.3, :func:`localizer._kernels.verify.verify_grey`).
    """
    ratio = bar_height / (3.0 * bar_width) * fy / fx  # rows / columns of a target facing the camera
    return as_record(SearchSettings(
        step=int(p.coarse_step), window=int(p.threshold_window), contrast_window=int(p.contrast_window),
        local_contrast=float(p.local_contrast), noise_contrast=noise_contrast(int(p.threshold_window)),
        global_level=min(255, int(math.ceil(p.global_threshold))),
        **run_test(p)._asdict(), min_contrast=float(p.min_contrast), min_contrast_ratio=float(p.min_contrast_ratio),
        min_rows=int(p.min_rows), max_row_gap=int(p.max_row_gap), aspect_lo=ratio * (1.0 - p.aspect_tolerance),
        aspect_hi=ratio / math.cos(p.max_alpha) * (1.0 + p.aspect_tolerance), uniformity=float(p.uniformity),
        height_term=2.0 * bar_width / bar_height * math.sin(p.max_alpha) / fy, check_margins=bool(p.check_margins),
        max_candidates=int(p.max_candidates), max_targets=int(p.max_targets)))
