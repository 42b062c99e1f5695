"""Printable two-bar targets at true scale: a vector PDF (matplotlib's PDF backend).

Every length here is in **millimetres** on the paper (the targets' :class:`~localizer.model.target.TargetSpec`
is in metres and is converted once); page coordinates have their origin at the page's bottom-left
corner, x right, y up. A page is a matplotlib figure exactly the paper's size (inches = mm / 25.4)
with one axes covering it whose data coordinates are millimetres, so 1 mm of data is 72 / 25.4 PDF
points on both axes, and every bar is a filled vector rectangle at its exact size.

What a page holds: each target with its blank margin, crop marks just outside the corners of
what is to be cut, the target's id under it (outside the margin: it is cut off), lines of text
under the id (where it hangs, for a map's targets; how to join halves), and at the bottom a
100 mm scale bar ("check your printer's scaling is 100 %") with a note of the target's size and
polarity and the page number. *positive*: black bars, white margin and gap (the paper); *negative*:
white bars in a black field that takes in the margin too (the simulator's texture and
:func:`localizer.tools.synthetic.render_reflectance` draw a negative target the same way).

Paper (:data:`PAPERS`) and the thesis target (300 x 225 mm with its margin): nothing is ever
scaled, and the bars are never cut. A target whose face (margin included) fits the paper inside
its unprintable border (:data:`EDGE`) is printed whole, several to a page when they fit, in the
orientation that fits most (A3 and Tabloid print the thesis target whole). One that does not (the
thesis target on A4 or Letter) is printed in **two halves**, one per page: the cut is the
vertical centre line of the gap between the bars, b/2 from the nearest bar edge, where both
sides are the gap's colour, so the joint crosses no edge the localizer measures. The left half
is cut on its crop marks; the right half carries a strip of gap colour (:data:`FLAP`, at most
b/4) left of its seam marks, which goes under the left half (glue it there). A target that does
not fit even in halves raises :class:`DoesNotFit`; :func:`largest_bar_width` says what does.
Trimming the margin (letting the wall supply it) was rejected: the localizer checks the margin,
and a wall is rarely the margin's colour.
"""
from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from localizer.model.target import POLARITIES, TargetSpec

#: Paper name -> (width, height) in portrait, mm.
PAPERS: dict[str, tuple[float, float]] = {
    "a4": (210.0, 297.0), "letter": (215.9, 279.4), "a3": (297.0, 420.0), "tabloid": (279.4, 431.8),
}
#: Named target sizes -> bar width b (m), the thesis proportions (H = 2b, margin b/2) scaled to it.
SIZES: dict[str, float] = {"thesis": TargetSpec().bar_width}
#: Colour of (the bars, the margin and gap) by polarity.
COLOURS: dict[str, tuple[str, str]] = {"positive": ("black", "white"), "negative": ("white", "black")}
#: What each polarity looks like, for the page's note.
POLARITY_TEXT: dict[str, str] = {"positive": "positive: black bars on white",
                                 "negative": "negative: white bars on black, the margin black too"}

EDGE = 5.0  # mm kept blank at every paper edge (printers cannot print there)
CROP_GAP, CROP_LEN = 2.0, 5.0  # mm: a crop mark starts CROP_GAP beyond a corner and is CROP_LEN long
REACH = CROP_GAP + CROP_LEN  # mm the crop marks reach beyond the cut outline
MARK_PT = 0.4  # pt, line width of the crop marks and the scale bar
FLAP = 10.0  # mm, the right half's strip under the left half (at most b/4)
ID_PT, TEXT_PT = 14.0, 7.0  # pt, font sizes of the id and of the other text
ID_H, LINE_H = 6.0, 3.3  # mm, height of the id's line and of a text line
BAND_H = 12.0  # mm above the bottom EDGE kept for the scale bar and the note
SCALE_MM = 100.0  # mm, length of the scale bar
SCALE_LABEL = "100 mm: check your printer's scaling is 100 %"
FONT = "DejaVu Sans"  # matplotlib's bundled font: the same everywhere
PARTS = ("whole", "left", "right")


class DoesNotFit(ValueError):
    """A target too large for the paper, even in two halves (``target``, ``paper`` as attributes)."""

    def __init__(self, target: "PrintTarget", paper: str) -> None:
        self.target, self.paper = target, paper
        w, h = PAPERS[paper]
        super().__init__(f"target {target.id} ({fmt_mm(target.outer_mm[0])} x {fmt_mm(target.outer_mm[1])} mm with its "
                         f"margin) does not fit {paper} paper ({fmt_mm(w)} x {fmt_mm(h)} mm), whole or in two halves")


@dataclass(frozen=True)
class PrintTarget:
    """A target to print: ``id``, geometry (m), polarity, and ``info`` lines printed under the id."""

    id: str
    spec: TargetSpec = field(default_factory=TargetSpec)
    polarity: str = "positive"
    info: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.polarity not in POLARITIES:
            raise ValueError(f"polarity must be one of {', '.join(POLARITIES)}, got {self.polarity!r}")

    @property
    def outer_mm(self) -> tuple[float, float]:
        """(width, height) of the face with its margin, mm."""
        return 1000.0 * self.spec.outer_width, 1000.0 * self.spec.outer_height


@dataclass(frozen=True)
class Piece:
    """What one cut-out holds: the strip ``u0 .. u1`` (mm from the face's left outer edge) of a
    target's face, full height; ``part`` is ``whole``, ``left`` or ``right`` (a half)."""

    target: PrintTarget
    part: str
    u0: float
    u1: float

    @property
    def width(self) -> float:
        return self.u1 - self.u0

    @property
    def height(self) -> float:
        return self.target.outer_mm[1]

    @property
    def lines(self) -> tuple[str, ...]:
        """Text under the id: the target's info, then how to join a half."""
        how = {"whole": (),
               "left": ("left half (1 of 2): cut on the crop marks; its right edge goes on the right half's "
                        "seam marks",),
               "right": ("right half (2 of 2): cut on the crop marks; the strip left of the seam marks "
                         "goes under the left half",)}
        return self.target.info + how[self.part]


@dataclass(frozen=True)
class Placement:
    """A piece on a page: ``x`` is the page x of its left cut edge (``u0``), ``y`` the page y of
    the face's bottom outer edge (mm)."""

    piece: Piece
    x: float
    y: float

    @property
    def face_x(self) -> float:
        """Page x of the face's left outer edge (``u = 0``; off the piece for a right half), mm."""
        return self.x - self.piece.u0


@dataclass(frozen=True)
class Page:
    """One sheet: ``size`` (width, height) mm as oriented, the pieces on it, the left end of the
    scale bar (mm) and the note's lines."""

    paper: str
    size: tuple[float, float]
    placements: tuple[Placement, ...]
    scale_bar: tuple[float, float]
    note: tuple[str, ...]

    @property
    def orientation(self) -> str:
        return "landscape" if self.size[0] > self.size[1] else "portrait"


def fmt_mm(value: float) -> str:
    """``300``, ``112.5``: a length in mm without trailing zeros."""
    return f"{value:.1f}".rstrip("0").rstrip(".")


@functools.lru_cache(maxsize=4096)
def _text_mm(text: str, points: float, bold: bool = False) -> float:
    """Width (mm) of ``text`` set in :data:`FONT` at ``points``."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    prop = FontProperties(family=FONT, weight="bold" if bold else "normal")
    return TextPath((0, 0), text, size=points, prop=prop).get_extents().width * 25.4 / 72.0


def pieces(target: PrintTarget, paper: str) -> tuple[Piece, ...]:
    """The target whole if its face fits ``paper`` (either way round), else its two halves;
    :class:`DoesNotFit` if the halves do not fit either."""
    w, _ = target.outer_mm
    whole = (Piece(target, "whole", 0.0, w),)
    if _fits(whole, paper):
        return whole
    flap = min(FLAP, 250.0 * target.spec.bar_width)  # b/4 in mm
    halves = (Piece(target, "left", 0.0, w / 2), Piece(target, "right", w / 2 - flap, w))
    if _fits(halves, paper):
        return halves
    raise DoesNotFit(target, paper)


def _cell(piece: Piece) -> tuple[float, float]:
    """(width, height) mm a piece needs with its crop marks and text (text over 150 mm may overhang)."""
    id_w = _text_mm(piece.target.id, ID_PT, True)
    text_w = max([id_w] + [_text_mm(line, TEXT_PT) for line in piece.lines])
    below = _id_drop(piece) + ID_H + LINE_H * len(piece.lines)
    return max(piece.width + 2 * REACH, min(text_w, 150.0)), REACH + piece.height + max(below, REACH)


def _id_drop(piece: Piece) -> float:
    """How far below the face the id's line starts: between the crop marks' legs if it fits there."""
    return CROP_GAP if _text_mm(piece.target.id, ID_PT, True) <= piece.width - 4.0 else REACH + 1.0


def _grid(cell: tuple[float, float], size: tuple[float, float]) -> tuple[int, int]:
    """(columns, rows) of ``cell`` that fit a page of ``size`` inside its border and above the band."""
    cols = math.floor((size[0] - 2 * EDGE) / cell[0] + 1e-9)
    rows = math.floor((size[1] - 2 * EDGE - BAND_H) / cell[1] + 1e-9)
    return max(cols, 0), max(rows, 0)


def _orientations(paper: str) -> tuple[tuple[float, float], tuple[float, float]]:
    w, h = PAPERS[paper]
    return (w, h), (h, w)


def _best(cell: tuple[float, float], paper: str) -> tuple[tuple[float, float], int, int]:
    """(page size, columns, rows) of the orientation holding most cells (portrait on a tie)."""
    options = [(size, *_grid(cell, size)) for size in _orientations(paper)]
    return max(options, key=lambda o: o[1] * o[2])  # max keeps the first (portrait) on a tie


def _fits(group: Sequence[Piece], paper: str) -> bool:
    return all(cols * rows >= 1 for _, cols, rows in (_best(_cell(p), paper) for p in group))


def largest_bar_width(paper: str, step: float = 0.0005) -> float:
    """The largest bar width (m, a multiple of ``step``) of a thesis-proportioned target that
    fits ``paper`` (whole or in halves)."""
    lo, hi = 0, int(2.0 / step)
    while hi - lo > 1:  # fits(lo * step) and not fits(hi * step)
        mid = (lo + hi) // 2
        try:
            pieces(PrintTarget("T00", TargetSpec.from_bar_width(mid * step)), paper)
            lo = mid
        except DoesNotFit:
            hi = mid
    return lo * step


def plan_pages(targets: Sequence[PrintTarget], paper: str, one_per_page: bool = False) -> list[Page]:
    """Lay ``targets`` out on pages of ``paper``: as many to a page as fit (all pieces in cells
    of the largest piece's size, rows top to bottom), or each piece on a page of its own.

    Raises:
        DoesNotFit: a target too large for ``paper`` even in halves.
    """
    if paper not in PAPERS:
        raise ValueError(f"paper must be one of {', '.join(PAPERS)}, got {paper!r}")
    all_pieces = [p for t in targets for p in pieces(t, paper)]
    groups: list[tuple[list[Piece], tuple[float, float], tuple[float, float], int, int]] = []
    if one_per_page:
        for p in all_pieces:
            cell = _cell(p)
            groups.append(([p], cell, *_best(cell, paper)))
    elif all_pieces:
        cell = tuple(max(c) for c in zip(*(_cell(p) for p in all_pieces)))
        size, cols, rows = _best(cell, paper)
        per_page = cols * rows
        groups = [(all_pieces[k:k + per_page], cell, size, cols, rows)
                  for k in range(0, len(all_pieces), per_page)]
    pages = []
    for n, (group, cell, size, cols, rows) in enumerate(groups, 1):
        cols, rows = min(cols, len(group)), min(rows, math.ceil(len(group) / min(cols, len(group))))
        left = (size[0] - cols * cell[0]) / 2
        top = size[1] - EDGE - (size[1] - 2 * EDGE - BAND_H - rows * cell[1]) / 2
        placed = []
        for k, piece in enumerate(group):
            cx, cy = left + (k % cols) * cell[0], top - (k // cols) * cell[1]
            placed.append(Placement(piece, cx + (cell[0] - piece.width) / 2, cy - REACH - piece.height))
        t = group[0].target
        w_mm, h_mm = t.outer_mm
        name = " (the thesis target)" if t.spec == TargetSpec() else ""
        note = (f"bar width {fmt_mm(1000 * t.spec.bar_width)} mm{name}: {fmt_mm(w_mm)} x {fmt_mm(h_mm)} mm "
                "with its margin",
                f"{POLARITY_TEXT[t.polarity]}; page {n} of {len(groups)}")
        pages.append(Page(paper, size, tuple(placed), (EDGE, EDGE + 1.0), note))
    return pages


# ---------------------------------------------------------------- drawing

def draw_page(page: Page):
    """A matplotlib :class:`~matplotlib.figure.Figure` of ``page`` (the paper's size; data in mm)."""
    from matplotlib.figure import Figure

    w, h = page.size
    fig = Figure(figsize=(w / 25.4, h / 25.4), facecolor="white")
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_axis_off()
    ax.set_xlim(0.0, w)
    ax.set_ylim(0.0, h)
    ax.set_autoscale_on(False)
    ax.margins(0.0)
    ax.set_aspect("equal", adjustable="box")  # (the figure's shape already makes it 1:1)
    for placement in page.placements:
        _draw_piece(ax, placement)
    _draw_scale_bar(ax, *page.scale_bar)
    for k, line in enumerate(reversed(page.note)):
        ax.text(w - EDGE, page.scale_bar[1] + k * LINE_H, line, fontsize=TEXT_PT, ha="right", va="bottom")
    return fig


def _rect(ax, x: float, y: float, w: float, h: float, colour: str) -> None:
    from matplotlib.patches import Rectangle

    ax.add_patch(Rectangle((x, y), w, h, facecolor=colour, edgecolor="none", linewidth=0.0, snap=False))


def _line(ax, xs, ys, **kw) -> None:
    from matplotlib.lines import Line2D

    ax.add_line(Line2D(xs, ys, color="black", linewidth=MARK_PT, solid_capstyle="butt", snap=False, **kw))


def _draw_piece(ax, placement: Placement) -> None:
    """The piece's face (bars and, for a negative target, the black field), crop marks, seam marks,
    id and text lines."""
    piece, t = placement.piece, placement.piece.target
    b, bh, s = (1000.0 * v for v in (t.spec.bar_width, t.spec.bar_height, t.spec.margin))
    bar, field_colour = COLOURS[t.polarity]
    x0, y0, height = placement.face_x, placement.y, piece.height
    if field_colour != "white":
        _rect(ax, placement.x, y0, piece.width, height, field_colour)
    for ua, ub in ((s, s + b), (s + 2 * b, s + 3 * b)):
        ua, ub = max(ua, piece.u0), min(ub, piece.u1)
        if ub > ua:
            _rect(ax, x0 + ua, y0 + s, ub - ua, bh, bar)
    xl, xr, yt = placement.x, placement.x + piece.width, y0 + height
    for x, sx in ((xl, -1.0), (xr, 1.0)):
        for y, sy in ((y0, -1.0), (yt, 1.0)):
            _line(ax, [x + sx * CROP_GAP, x + sx * REACH], [y, y])
            _line(ax, [x, x], [y + sy * CROP_GAP, y + sy * REACH])
    if piece.part == "right":  # where the left half's edge goes
        seam = x0 + piece.target.outer_mm[0] / 2
        for ya, yb in ((yt + CROP_GAP, yt + REACH), (y0 - CROP_GAP, y0 - REACH)):
            _line(ax, [seam, seam], [ya, yb])
        ax.text(seam + 1.0, yt + REACH, "seam", fontsize=TEXT_PT - 1, ha="left", va="top")
    xc = (xl + xr) / 2
    top = y0 - _id_drop(piece)
    ax.text(xc, top, t.id, fontsize=ID_PT, fontweight="bold", ha="center", va="top")
    for k, line in enumerate(piece.lines):
        ax.text(xc, top - ID_H - k * LINE_H, line, fontsize=TEXT_PT, ha="center", va="top")


def _draw_scale_bar(ax, x: float, y: float) -> None:
    """A :data:`SCALE_MM` bar from ``(x, y)`` rightwards, ticks every 10 mm, the label above."""
    _line(ax, [x, x + SCALE_MM], [y, y])
    for k in range(int(SCALE_MM // 10) + 1):
        _line(ax, [x + 10 * k, x + 10 * k], [y, y + (3.5 if k % 5 == 0 else 2.0)])
    ax.text(x, y + 4.5, SCALE_LABEL, fontsize=TEXT_PT, ha="left", va="bottom")


def write_pdf(pages: Sequence[Page], path: str | os.PathLike, title: str = "Two-bar targets") -> Path:
    """Write ``pages`` to the PDF ``path`` (vector, one PDF page per page, fonts embedded as
    TrueType so the text can be searched and copied); written whole or not at all."""
    import matplotlib
    from matplotlib.backends.backend_pdf import PdfPages

    from agvsim.files import atomic_write

    path = Path(path)
    rc = {"pdf.fonttype": 42, "font.family": FONT, "path.snap": False, "savefig.bbox": "standard",
          "savefig.pad_inches": 0.0, "text.usetex": False}
    with atomic_write(path) as part, matplotlib.rc_context(rc):
        with PdfPages(part, metadata={"Title": title, "Creator": "agvsim target print",
                                      "CreationDate": None}) as pdf:
            for page in pages:
                pdf.savefig(draw_page(page))
    return path


def print_targets(targets: Sequence[PrintTarget], paper: str, path: str | os.PathLike,
                  one_per_page: bool = False) -> list[Page]:
    """:func:`plan_pages` then :func:`write_pdf`; returns the pages."""
    pages = plan_pages(targets, paper, one_per_page)
    write_pdf(pages, path)
    return pages
