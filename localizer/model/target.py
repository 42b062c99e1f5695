"""Geometry of the thesis's two-bar target (thesis §3.4, Fig. 3.2).

The target is planar and hangs vertically. Its *active area* is three
equal vertical strips of width ``b``: bar, gap, bar (``W = 3b`` wide,
``H = 2b`` tall). A margin ``s = b/2`` surrounds the active area so the
bars never merge with the background. A *positive* target has black bars
on white, a *negative* one white bars on black.

All lengths are metres.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Literal

from localizer._kernels.records import TargetConstants, as_record
from localizer.numeric import check_number

Polarity = Literal["positive", "negative"]
POLARITIES: tuple[str, ...] = ("positive", "negative")


@dataclass(frozen=True)
class TargetSpec:
    """Target geometry. ``TargetSpec()`` is the thesis target.

    Attributes:
        bar_width: width b of each bar and of the gap between them (m).
        bar_height: height H of the bars (m); the thesis uses H = 2b.
        margin: blank margin s around the active area (m); thesis s = b/2.
    """

    bar_width: float = 0.075  # m, b
    bar_height: float = 0.150  # m, H = 2b
    margin: float = 0.0375  # m, s = b/2

    def __post_init__(self) -> None:
        for name in ("bar_width", "bar_height", "margin"):
            check_number(f"TargetSpec.{name}", getattr(self, name), low=0.0, low_open=name != "margin", unit="m")

    @classmethod
    def from_bar_width(cls, bar_width: float) -> "TargetSpec":
        """The thesis proportions (H = 2b, s = b/2) scaled to ``bar_width`` (m)."""
        return cls(bar_width=bar_width, bar_height=2.0 * bar_width, margin=0.5 * bar_width)

    @functools.cached_property
    def constants(self) -> TargetConstants:
        """``(bar_width, bar_height, margin)`` (m) as the compiled kernels take them (computed once)."""
        return TargetConstants(float(self.bar_width), float(self.bar_height), float(self.margin))

    @functools.cached_property
    def constants_record(self):
        """:attr:`constants` as a ``(1,)`` record array, the form of the per-frame kernels'
        arguments (computed once; do not change it)."""
        return as_record(self.constants)

    @property
    def active_width(self) -> float:
        """W = 3b, width of the active area (m)."""
        return 3.0 * self.bar_width

    @property
    def active_height(self) -> float:
        """Height of the active area (m), equal to the bar height H."""
        return self.bar_height

    @property
    def outer_width(self) -> float:
        """Width of the whole printed target including margins (m)."""
        return self.active_width + 2.0 * self.margin

    @property
    def outer_height(self) -> float:
        """Height of the whole printed target including margins (m)."""
        return self.active_height + 2.0 * self.margin
