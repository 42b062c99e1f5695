"""User parameters of the detector (frozen), kept apart from per-frame statistics.

Defaults are the thesis's values (§4.4-4.6) where it gives one; grey levels
are 8-bit levels, lengths are pixels or rows at the frame's own resolution
unless said otherwise. ``None`` means "scale the thesis value (given for
480 rows) to the frame height".
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, fields, replace

import numpy as np

from localizer.numeric import check_choice, check_number

METHODS = ("thesis", "exact")
PHOTOMETRIC = ("off", "clipped", "auto", "all")
RESPONSES = ("auto", "linear", "srgb")
#: the choices of every "choice" field of :class:`DetectorParams`
CHOICES = {"photometric": PHOTOMETRIC, "response": RESPONSES}
#: largest window, run or row count (px or rows) a detector parameter may name: more than
#: any frame's side is meaningless, and the kernels' loops and buffers grow with it
MAX_PX = 4096
#: largest ``edge_window`` (px): the neighbourhood of a rough edge, thesis 9; it is cut half
#: way to the next edge anyway, and the kernels loop over all of it on every row
MAX_EDGE_WINDOW = 255

_GREY = dict(low=0.0, high=255.0, unit="grey levels")
_SHARE = dict(low=0.0, high=1.0)
_COUNT = dict(low=1, high=MAX_PX, integer=True)
#: every field of :class:`DetectorParams` -> (kind, check_number bounds). Kinds: "number";
#: "auto" (a number, or None for the resolution's default); "bool"; "choice"
#: (:data:`CHOICES`); "path" (str, os.PathLike or None). ``tests/localizer`` holds that
#: every field is here.
PARAM_RANGES: dict[str, tuple[str, dict]] = {
    "coarse_step": ("auto", dict(_COUNT, unit="rows")),
    "threshold_window": ("auto", dict(low=3, high=MAX_PX, integer=True, unit="px")),
    "global_threshold": ("number", _GREY),
    "local_contrast": ("number", _GREY),
    "contrast_window": ("number", dict(low=2, high=MAX_PX, integer=True, unit="px")),
    "min_bar_px": ("number", dict(_COUNT, unit="px")),
    "width_tolerance": ("number", dict(low=0.0, high=1.0, high_open=True)),
    "width_slack": ("number", dict(low=0.0, high=MAX_PX, unit="px")),
    "max_edge_shift": ("number", dict(low=0.0, high=MAX_PX, unit="px")),
    "min_margin_ratio": ("number", dict(low=0.0, high=10.0)),
    "reject_periodic": ("bool", {}),
    "periodic_tolerance": ("number", _SHARE),
    "min_rows": ("auto", dict(_COUNT, unit="rows")),
    "max_row_gap": ("number", dict(low=0, high=MAX_PX, integer=True, unit="rows")),
    "aspect_tolerance": ("number", dict(low=0.0, high=1.0, high_open=True)),
    "max_alpha": ("number", dict(low=0.0, high=math.pi / 2, low_open=True, high_open=True, unit="rad")),
    "uniformity": ("number", _GREY),
    "min_contrast": ("number", _GREY),
    "min_contrast_ratio": ("number", _SHARE),
    "check_margins": ("bool", {}),
    "edge_window": ("number", dict(low=3, high=MAX_EDGE_WINDOW, integer=True, unit="px")),
    "edge_sigma_floor": ("number", dict(low=0.0, high=100.0, unit="px")),
    "photometric": ("choice", {}),
    "refine_range_sd": ("number", dict(low=0.0, high=1.0)),
    "refine_alpha_sd": ("number", dict(low=0.0, high=math.pi, unit="rad")),
    "response": ("choice", {}),
    "pyramid": ("bool", {}),
    "sharpen_sigma": ("number", dict(low=0.0, high=100.0)),
    "sharpen_amount": ("number", dict(low=0.0, high=10.0)),
    "max_targets": ("number", dict(low=1, high=65536, integer=True)),
    "max_candidates": ("number", dict(low=1, high=65536, integer=True)),
    "debug_dir": ("path", {}),
}


@dataclass(frozen=True)
class DetectorParams:
    # --- search (§4.4.1)
    coarse_step: int | None = None  # rows between coarse scan lines; thesis N = 10 at 480 rows
    # --- thresholding (§4.4.2)
    threshold_window: int | None = None  # px, local midway-threshold window; 33 at 512 columns
    global_threshold: float = 128.0  # grey level used when a line has little contrast
    # grey levels within `contrast_window` px that switch to midway threshold; on a noisy frame at
    # least what its noise reaches in a threshold window (localizer.search.scan.noise_contrast)
    local_contrast: float = 30.0
    contrast_window: int = 5  # px, thesis "area of five pixels"
    # --- feature detection (§4.5.1)
    min_bar_px: int = 3  # px, shortest run accepted as a bar or gap
    width_tolerance: float = 0.35  # relative difference allowed between the three runs
    width_slack: float = 1.5  # px added to the allowed difference (quantisation)
    max_edge_shift: float = 1.0  # px, common dark-side edge shift undone first (blur + saturation)
    min_margin_ratio: float = 0.25  # side margin run / mean run (thesis margin s = b/2)
    reject_periodic: bool = True  # drop triples inside 5+ equal runs (chessboards, gratings)
    periodic_tolerance: float = 0.2  # relative tolerance of "equal" for that test (margins are b/2)
    # --- verification (§4.5.2)
    min_rows: int | None = None  # thesis 15 scan lines at 480 rows
    max_row_gap: int = 1  # rows a stack may miss and stay connected (thesis: 0; 1 survives noise)
    aspect_tolerance: float = 0.35  # relative slack on the height/width ratio
    max_alpha: float = math.radians(80.0)  # rad, largest |alpha| the aspect test allows (70 deg at 1 m looks like ~76 deg)
    uniformity: float = 20.0  # grey levels: max spread of non-boundary pixels in a segment
    min_contrast: float = 100.0  # grey levels between adjacent segments (thesis)
    min_contrast_ratio: float = 0.5  # or: dark mean <= (1 - ratio) * bright mean (dim light)
    check_margins: bool = True  # the blank margin above and below the bars must be present
    # --- edges (§4.6)
    edge_window: int = 9  # px, thesis neighbourhood of a rough edge
    # --- exact pose covariance
    edge_sigma_floor: float = 0.05  # px, model error added to every averaged edge position
    # --- whole-target photometric refinement (localizer.measure.photometric, undistorted cameras):
    # "auto" refines a target whose edge-based pose falls short: range sd above `refine_range_sd`
    # of the range or orientation sd above `refine_alpha_sd` (small, far, dim or strongly
    # blurred targets; a saturated one from several starts); "clipped" every target whose bright
    # side is clipped (saturated light, where edges measured one at a time lose up to ~0.6 px
    # each) and no other; "all" every target; "off" none. Costs ~0.3-1 ms per refined target (up
    # to ~3 ms for a saturated one that falls short). The thresholds: of 7,792 targets of the
    # envelope benchmark's 512 x 480 frames (seeds 0 and 1, 9 and 17 conditions), the 7,495
    # under both were at most 1.49 % off in range and 1.83 deg in orientation (bars of 60 rows or
    # more) from their edges alone (the floors: 2 % and 3 deg); seeds 2-6 then held one at 2.15 %
    # with a range sd of 0.73 % (blur3, seed 2, frame 21; refined: 0.22 %), so the range's is
    # 0.7 %: it refines 30-38 % of blur3's targets (sd 3 px; 24-29 % at 0.8 %), 5-8 % of saturated
    # ones (BENCHMARKS.md: the speed and accuracy each costs)
    photometric: str = "auto"
    refine_range_sd: float = 0.007  # share of the range ("auto": refine above it)
    refine_alpha_sd: float = math.radians(2.0)  # rad ("auto": refine above it)
    # --- the camera's response (grey level against light), for the edges and the refinement:
    # "linear" (machine-vision and raw frames: the pixels as they are); "srgb" (most USB, phone
    # and web cameras encode their frames with the sRGB curve: each target's pixels are
    # linearized through its inverse before its edges are measured); "auto" decides per target
    # from its edges (localizer.detect.ENCODED_SHIFT)
    response: str = "auto"
    # --- large frames (at least 2 x 480 rows): True searches a coarse level (area-averaged to about
    # 480 rows) and measures each target on a crop of the finest level where its blur is at most
    # 2 px (localizer.image.pyramid; coarser than the search's for a strongly blurred target): the thesis
    # camera's 3 px of blur at 2448 x 2048 (14 px) 40/40 found against 25/40 at the frame's own
    # resolution, at 1280 x 1024 (7.5 px) a range error of 0.22 % mean against 1.38 %;
    # False: the whole frame at its own resolution
    pyramid: bool = True
    # --- blurred frames: where the "exact" search of a frame (or of a large frame's coarse level or
    # crop) finds no target, it searches again an unsharp-masked copy of it (localizer.image.sharpen:
    # Gaussian sd `sharpen_sigma` px, gain `sharpen_amount`, then twice that: sharpen.GAINS) and
    # measures what that finds on the frame's own pixels (kept if those edges fit a target,
    # detect.SHARPENED_MAX_RMS): steep targets under the envelope's 3 px of blur, whose narrow runs
    # the search loses (19 of the 22 misses of the envelope benchmark's seeds 0-4 found again).
    # 0 (either): no second search
    sharpen_sigma: float = 3.0  # px
    sharpen_amount: float = 1.0
    # --- misc
    max_targets: int = 32  # most targets reported per frame
    max_candidates: int = 256  # most fine searches per frame (bounds the time on hostile frames)
    debug_dir: str | None = None  # write intermediate images here (slow)

    def __post_init__(self) -> None:
        for name, (kind, bounds) in PARAM_RANGES.items():
            v = getattr(self, name)
            where = f"DetectorParams.{name}"
            if kind == "bool":
                if not isinstance(v, (bool, np.bool_)):
                    raise ValueError(f"{where} must be True or False, got {v!r}")
            elif kind == "choice":
                check_choice(where, v, CHOICES[name])
            elif kind == "path":
                if v is not None and not isinstance(v, (str, os.PathLike)):
                    raise ValueError(f"{where} must be a folder path or None, got {v!r}")
            elif not (v is None and kind == "auto"):
                x = check_number(where, v, **bounds)
                if bounds.get("integer") and not isinstance(v, int):
                    object.__setattr__(self, name, x)  # 5.0 -> 5

    @classmethod
    def from_kwargs(cls, **kwargs) -> "DetectorParams":
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(kwargs) - names)
        if unknown:
            raise ValueError(f"unknown detector parameter(s) {unknown}; expected some of {sorted(names)}")
        return cls(**kwargs)

    def resolved(self, height: int, width: int | None = None) -> "DetectorParams":
        """Copy with the resolution-dependent defaults filled in for ``height`` rows
        (and ``width`` columns, default ``height * 512 / 480``)."""
        scale = height / 480.0
        wscale = (width if width is not None else height * 512.0 / 480.0) / 512.0
        return replace(self,
                       coarse_step=max(1, round(10 * scale)) if self.coarse_step is None else self.coarse_step,
                       threshold_window=(2 * max(4, round(16 * wscale)) + 1 if self.threshold_window is None
                                         else self.threshold_window),
                       min_rows=max(3, round(15 * scale)) if self.min_rows is None else self.min_rows)


@dataclass
class DetectionStats:
    """Per-frame statistics, filled in by :func:`localizer.detect_targets` when passed."""

    rows_scanned: int = 0
    runs: int = 0
    seeds: int = 0
    candidates: int = 0
    rejected: dict = field(default_factory=dict)  # reason -> count
    accepted: int = 0
    seconds: float = 0.0

    def reject(self, reason: str) -> None:
        self.rejected[reason] = self.rejected.get(reason, 0) + 1
