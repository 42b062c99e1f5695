"""``agvsim target``: printable two-bar targets at true scale (a vector PDF).

    agvsim target print --out FILE.pdf [--paper a4] [--polarity P] [--size thesis | --bar-width M]
                        [--ids ID ...] [--json]
    agvsim target print --map PATH_OR_NAME --out FILE.pdf [--paper a4] [--ids ID ...] [--json]

Each target is printed at its true size with its blank margin, crop marks outside the corners,
its id under it and a 100 mm scale bar on every page to check the printer did not scale it. Without
``--map`` the targets (``--ids``, default one, ``T01``) share one size and polarity and are packed
several to a page when they fit. With ``--map`` each of the map's targets (or those named by
``--ids``) gets a page of its own with its size and polarity from the map and a line saying where
it hangs (wall, distance along it, side, centre height).

A target whose face (margin included) does not fit the paper is printed in two halves, one per
page, cut down the middle of the gap between the bars (no bar edge is cut) and joined with the
right half's strip under the left half: the thesis target (300 x 225 mm) on A4 or Letter. A3 and
Tabloid print it whole. Nothing is ever scaled; a target that does not fit even in halves is an
error naming the largest bar width that does (see :mod:`agvsim.deploy.printing`).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from agvsim.commands._args import number
from agvsim.commands._output import add_json_flag, emit_json
from agvsim.deploy.printing import PAPERS, POLARITY_TEXT, SIZES
from localizer.model.target import POLARITIES

#: the paper of ``--paper``'s default
DEFAULT_PAPER = "a4"

#: The id of the one target printed when neither --ids nor --map is given.
DEFAULT_ID = "T01"


def register(sub) -> None:
    """Add the ``target`` command and its ``print`` subcommand."""
    parser = sub.add_parser("target", help="printable two-bar targets at true scale (vector PDF)",
                            description="Printable two-bar targets.")
    target_sub = parser.add_subparsers(dest="target_command", metavar="ACTION", required=True)
    papers = ", ".join(f"{k} {w:g} x {h:g} mm" for k, (w, h) in PAPERS.items())
    p = target_sub.add_parser(
        "print", help="a PDF of targets at true scale, with crop marks and a 100 mm scale bar",
        description="Write a vector PDF of two-bar targets at true scale: each with its blank margin, crop "
                    "marks outside its corners, its id below it and a 100 mm scale bar on every page (print "
                    "at 100 %, 'actual size'). A target larger than the paper (the thesis target, 300 x 225 mm "
                    "with its margin, on a4 or letter) is printed in two halves cut down the middle of the gap "
                    "between the bars, to be joined with the right half's strip under the left half; a3 and "
                    "tabloid print it whole. Nothing is scaled. With --map: one page per target of the map, "
                    "with its size and polarity from the map and where it hangs.")
    p.add_argument("--paper", default=None, choices=tuple(PAPERS),
                   help=f"paper size ({papers}; default: {DEFAULT_PAPER}); the orientation that fits most targets is chosen")
    p.add_argument("--out", required=True, type=Path, metavar="FILE.pdf", help="the PDF to write")
    p.add_argument("--polarity", choices=POLARITIES, default=None,
                   help="positive: black bars on white; negative: white bars on black, the margin black too "
                        "(default: positive; with --map each target's own)")
    size = p.add_mutually_exclusive_group()
    size.add_argument("--size", choices=tuple(SIZES), default=None,
                      help="a named size: " + ", ".join(f"{k} (bar width {1000 * v:g} mm)" for k, v in SIZES.items())
                           + " (default: thesis; with --map each target's own)")
    size.add_argument("--bar-width", type=number(0.0, low_open=True, unit="m"), default=None, metavar="M",
                      help="bar width b in m; the target keeps the thesis proportions (bars 2b tall, margin b/2: "
                           "4b x 3b with its margin)")
    p.add_argument("--ids", nargs="+", metavar="ID", default=None,
                   help=f"the targets' ids, one target each (default: {DEFAULT_ID}); with --map, which of the "
                        "map's targets to print (default: all)")
    p.add_argument("--map", default=None, metavar="PATH_OR_NAME",
                   help="print the targets of this map (a shipped name or a .yaml file), one per page")
    add_json_flag(p)
    p.set_defaults(func=run_print)


def run_print(args: argparse.Namespace) -> int:
    from agvsim.deploy.printing import DoesNotFit, largest_bar_width, plan_pages, write_pdf

    out = _check_out(args.out)
    defaulted = args.paper is None
    if defaulted:
        args.paper = DEFAULT_PAPER
    targets, title = _map_targets(args) if args.map is not None else _plain_targets(args)
    try:
        pages = plan_pages(targets, args.paper, one_per_page=args.map is not None)
    except DoesNotFit as exc:
        raise ValueError(_too_large(args, exc, largest_bar_width(args.paper))) from None
    out.parent.mkdir(parents=True, exist_ok=True)
    write_pdf(pages, out, title=f"Two-bar targets of map {title}" if title else "Two-bar targets")
    halves = sorted({pl.piece.target.id for pg in pages for pl in pg.placements if pl.piece.part != "whole"})
    summary = {
        "out": str(out), "paper": args.paper, "pages": len(pages),
        "orientations": sorted({pg.orientation for pg in pages}),
        "targets": [{"id": t.id, "polarity": t.polarity, "bar_width_m": t.spec.bar_width,
                     "face_mm": list(t.outer_mm), "in_halves": t.id in halves} for t in targets],
        "map": title,
    }
    if args.json:
        emit_json(summary)
        return 0
    orient = " and ".join(summary["orientations"])
    default = " (the default paper; --paper letter, a3, ... for another)" if defaulted else ""
    print(f"wrote {out}: {len(targets)} target{'s' if len(targets) != 1 else ''} on {len(pages)} "
          f"page{'s' if len(pages) != 1 else ''} of {args.paper}{default} ({orient}); print at 100 % (actual size) and "
          "check the 100 mm scale bar")
    if halves:
        print(f"  in two halves (larger than {args.paper} with the margin): {', '.join(halves)}; cut on the crop "
              "marks and glue the right half's strip under the left half (a3 or tabloid prints it whole)")
    return 0


def _check_out(path: Path) -> Path:
    if path.suffix.lower() != ".pdf":
        raise ValueError(f"--out {str(path)!r}: expected a .pdf file name")
    if path.is_dir():
        raise ValueError(f"--out {str(path)!r}: a folder, expected a .pdf file name")
    return path


def _plain_targets(args: argparse.Namespace):
    from agvsim.deploy.printing import PrintTarget
    from localizer.model.target import TargetSpec

    ids = args.ids or [DEFAULT_ID]
    _check_unique(ids)
    bar_width = args.bar_width if args.bar_width is not None else SIZES[args.size or "thesis"]
    spec = TargetSpec() if bar_width == TargetSpec().bar_width else TargetSpec.from_bar_width(bar_width)
    polarity = args.polarity or "positive"
    return [PrintTarget(i, spec, polarity) for i in ids], None


def _map_targets(args: argparse.Namespace):
    from agvsim.deploy.printing import PrintTarget
    import difflib

    from agvsim.world import MapError, load_map

    for flag, value in (("--polarity", args.polarity), ("--size", args.size), ("--bar-width", args.bar_width)):
        if value is not None:
            raise ValueError(f"{flag} {value}: with --map each target's {flag[2:].replace('-', ' ')} comes from the "
                             "map; expected no " + flag)
    try:
        world = load_map(args.map)
    except (MapError, FileNotFoundError) as exc:
        raise ValueError(f"--map {args.map!r}: {exc}") from None
    known = [t.id for t in world.targets]
    if not known:
        raise ValueError(f"--map {args.map!r}: the map has no targets; expected a map with targets")
    ids = args.ids or known
    _check_unique(ids)
    for i in ids:
        if i not in known:
            close = difflib.get_close_matches(i, known, n=1)
            hint = f"did you mean {close[0]!r}? " if close else ""
            shown = ", ".join(known[:8]) + (f", ... ({len(known)} targets)" if len(known) > 8 else "")
            raise ValueError(f"--ids {i}: map {world.name!r} has no target {i!r}; {hint}expected one of {shown}")
    chosen = [world.target(i) for i in ids]
    return [PrintTarget(t.id, t.spec, t.polarity, hang_lines(world.name, t)) for t in chosen], world.name


def hang_lines(map_name: str, t) -> tuple[str, ...]:
    """Where a map's target hangs, for its page: wall, distance along it, side, centre height, polarity."""
    return (f"map {map_name}, wall {t.wall}: {t.at:.2f} m along the wall from its first point, on its {t.side} side",
            f"centre {t.height:.2f} m above the floor; {POLARITY_TEXT[t.polarity]}")


def _check_unique(ids) -> None:
    seen = set()
    for i in ids:
        if not i.strip():
            raise ValueError(f"--ids {i!r}: an empty id; expected a name such as {DEFAULT_ID}")
        if i in seen:
            raise ValueError(f"--ids {i}: given twice; expected each id once")
        seen.add(i)


def _too_large(args, exc, largest: float) -> str:
    from agvsim.deploy.printing import fmt_mm

    w, h = PAPERS[args.paper]
    t = exc.target
    face = f"{fmt_mm(t.outer_mm[0])} x {fmt_mm(t.outer_mm[1])} mm with its margin"
    what = (f"--map {args.map!r}: target {t.id} ({face})" if args.map is not None
            else f"--bar-width {t.spec.bar_width:g}: the target ({face})" if args.bar_width is not None
            else f"--size {args.size or 'thesis'}: the target ({face})")
    larger = [k for k, (pw, ph) in PAPERS.items() if pw * ph > w * h]
    bigger = f", or a larger --paper ({', '.join(larger)})" if larger else ""
    return (f"{what} does not fit {args.paper} paper ({w:g} x {h:g} mm), whole or in two halves; expected a bar "
            f"width <= {largest:g} m on {args.paper}{bigger}")
