"""``agvsim target print``: the PDF, rasterized at 300 dpi with PyMuPDF, holds targets at true size
(bars, gap, margin and crop marks within 0.2 mm, a 100 mm scale bar), the localizer finds a target
in a camera frame rendered from that raster, a map's targets get a page each saying where they
hang, and bad input is one line."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from agvsim.cli import main
from agvsim.deploy.printing import CROP_GAP, PAPERS, PrintTarget, largest_bar_width, pieces, plan_pages, write_pdf
from localizer import Camera, TargetPose, TargetSpec, detect_targets
from localizer.tools.synthetic import BLACK_REFLECTANCE, WHITE_REFLECTANCE, expose

pymupdf = pytest.importorskip("pymupdf")

DPI = 300
PX = 25.4 / DPI  # mm per raster pixel
TOL = 0.2  # mm


def _print(tmp_path, paper, bar_width=0.075, polarity="positive", ids=("T01",), name="t.pdf"):
    spec = TargetSpec.from_bar_width(bar_width)
    pages = plan_pages([PrintTarget(i, spec, polarity) for i in ids], paper)
    path = write_pdf(pages, tmp_path / name)
    return pages, pymupdf.open(path)


def _raster(doc, k):
    """Page ``k`` at 300 dpi: grey uint8, pixel (i, j) covering [j, j+1] x [i, i+1] * PX mm from the top left."""
    pix = doc[k].get_pixmap(dpi=DPI, colorspace=pymupdf.csGRAY, alpha=False)
    return np.frombuffer(pix.samples, np.uint8).reshape(pix.height, pix.stride)[:, :pix.width]


def _run_edges(f, a, b):
    """Subpixel (left, right) edges (px) of the run ``a..b`` (inclusive) of ``f`` >= 0.5, ``f`` the
    covered share of each pixel (antialiased edge pixels hold the share)."""
    return a + (1.0 - f[a]) - f[a - 1], b + f[b] + f[b + 1]


def _runs(f):
    """Subpixel (left, right) edges (px) of every run of ``f`` >= 0.5 (``f`` padded with 0 at both ends)."""
    f = np.concatenate([[0.0], f, [0.0]])
    d = np.diff((f >= 0.5).astype(int))
    return [(left - 1, right - 1) for left, right in
            (_run_edges(f, a + 1, b) for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))]


def _bars(gray, polarity):
    """Each bar's (left, right, top, bottom) in mm from the page's top-left, left to right, measured
    across its middle row and down its middle column."""
    ink = 1.0 - gray.astype(float) / 255.0
    bar = ink if polarity == "positive" else 1.0 - ink
    n, _, stats, _ = cv2.connectedComponentsWithStats((bar >= 0.5).astype(np.uint8), connectivity=4)
    h, w = gray.shape
    out = []
    for x, y, bw, bh, _ in stats[1:]:
        if bw * PX < 8 or bh * PX < 8 or x == 0 or y == 0 or x + bw == w or y + bh == h:
            continue  # text, marks, the page's white around a negative target
        row, col = bar[y + bh // 2], bar[:, x + bw // 2]
        (left, right), = [r for r in _runs(row) if r[0] <= x + 1 and r[1] >= x + bw - 1]
        (top, bottom), = [r for r in _runs(col) if r[0] <= y + 1 and r[1] >= y + bh - 1]
        out.append((left * PX, right * PX, top * PX, bottom * PX))
    return sorted(out)


def _mark_x(gray, x_mm, y_mm):
    """Centre (mm) of the thin vertical line crossing row ``y_mm`` within 2 mm of ``x_mm``."""
    ink = 1.0 - gray[int(y_mm / PX)].astype(float) / 255.0
    j = np.arange(int((x_mm - 2) / PX), int((x_mm + 2) / PX))
    assert ink[j].sum() > 0.5, f"no mark near x = {x_mm:.1f} mm"
    return float(((j + 0.5) * ink[j]).sum() / ink[j].sum() * PX)


# ------------------------------------------------------------ geometry from the raster

@pytest.mark.parametrize("paper", sorted(PAPERS))
def test_pages_are_the_paper_in_points(tmp_path, paper):
    pages, doc = _print(tmp_path, paper)
    w, h = PAPERS[paper]
    for k, page in enumerate(pages):
        r = doc[k].rect
        size = (r.width, r.height) if page.orientation == "portrait" else (r.height, r.width)
        assert size == pytest.approx((w * 72 / 25.4, h * 72 / 25.4), abs=0.01)
        assert (r.width > r.height) == (page.orientation == "landscape")


@pytest.mark.parametrize("paper, bar_width, halves", [("a4", 0.075, True), ("letter", 0.075, True),
                                                      ("a3", 0.075, False), ("a4", 0.04, False)])
@pytest.mark.parametrize("polarity", ["positive", "negative"])
def test_bars_gap_margin_and_crop_marks_are_true_size(tmp_path, paper, bar_width, halves, polarity):
    b, hb, s = 1000 * bar_width, 2000 * bar_width, 500 * bar_width
    pages, doc = _print(tmp_path, paper, bar_width, polarity)
    placements = [(k, pl) for k, pg in enumerate(pages) for pl in pg.placements]
    assert [pl.piece.part for _, pl in placements] == (["left", "right"] if halves else ["whole"])
    errors = []
    bars_found = 0
    for k, pl in placements:
        gray = _raster(doc, k)
        page_h = pages[k].size[1]
        bars = _bars(gray, polarity)
        assert len(bars) == (1 if halves else 2)
        bars_found += len(bars)
        for left, right, top, bottom in bars:
            errors += [right - left - b, bottom - top - hb]
        face_left, face_top = pl.face_x, page_h - (pl.y + pl.piece.height)
        cut_left, cut_right = pl.x, pl.x + pl.piece.width
        left, right, top, bottom = bars[0]
        # where the bars are on the face: margin s, (bar, gap, bar), from the face's corner
        errors += [top - face_top - s, left - face_left - (s if pl.piece.part != "right" else s + 2 * b)]
        if not halves:
            errors.append(bars[1][0] - right - b)  # the gap
        # crop marks on the cut outline, above the face (they start CROP_GAP beyond the corner)
        above = face_top - CROP_GAP - 2.0
        errors += [_mark_x(gray, cut_left, above) - cut_left, _mark_x(gray, cut_right, above) - cut_right]
        if pl.piece.part == "left":
            errors.append(cut_right - right - b / 2)  # the seam: the middle of the gap
        if pl.piece.part == "right":
            seam = face_left + s + 1.5 * b  # the middle of the gap
            errors.append(_mark_x(gray, seam, above) - seam)
            assert left - seam == pytest.approx(b / 2, abs=TOL)
        if polarity == "negative":  # the margin is black up to the cut
            ink = 1.0 - gray[int((top + bottom) / 2 / PX)].astype(float) / 255.0
            field = [r for r in _runs(ink) if r[1] * PX - r[0] * PX > b / 4]
            errors += [field[0][0] * PX - cut_left, field[-1][1] * PX - cut_right]
    assert bars_found == 2
    worst = max(abs(e) for e in errors)
    print(f"{paper} b={b:g} mm {polarity}: {len(errors)} lengths, worst error {worst:.3f} mm")
    assert worst <= TOL, errors


@pytest.mark.parametrize("paper", ["a4", "letter"])
def test_the_scale_bar_is_100_mm(tmp_path, paper):
    pages, doc = _print(tmp_path, paper, 0.04)
    x, y = pages[0].scale_bar
    gray = _raster(doc, 0)
    row = pages[0].size[1] - y - 1.0  # 1 mm above the bar: every tick, not the bar
    ink = 1.0 - gray[int(row / PX)].astype(float) / 255.0
    lo, hi = int((x - 3) / PX), int((x + 103) / PX)
    ticks = [(a + bb) / 2 * PX + lo * PX for a, bb in _runs(np.clip(ink[lo:hi] * 3, 0, 1))]
    assert len(ticks) == 11
    assert ticks[-1] - ticks[0] == pytest.approx(100.0, abs=TOL)
    assert np.diff(ticks) == pytest.approx([10.0] * 10, abs=TOL)
    assert "100 mm: check your printer's scaling is 100 %" in doc[0].get_text()


# ------------------------------------------------------------ the localizer sees the printed target

def _face(pages, doc):
    """The printed face (margin included) cut from the rasters and the halves joined: grey, with
    its size in mm."""
    parts = []
    for k, pg in enumerate(pages):
        gray = _raster(doc, k)
        for pl in pg.placements:
            w, h = pl.piece.target.outer_mm
            x0 = pl.face_x + (w / 2 if pl.piece.part == "right" else 0.0)
            x1 = pl.face_x + (w / 2 if pl.piece.part == "left" else w)
            top = pg.size[1] - pl.y - h
            parts.append(gray[round(top / PX):round((top + h) / PX), round(x0 / PX):round(x1 / PX)])
    face = np.hstack(parts)
    return face, pages[0].placements[0].piece.target.outer_mm


def _frame(face, size_mm, cam, pose, rng):
    """A camera frame of the face at ``pose`` (8 x 8 point samples per pixel, grey wall behind)."""
    k = 8
    w, h = size_mm
    refl = (BLACK_REFLECTANCE + (WHITE_REFLECTANCE - BLACK_REFLECTANCE) * face / 255.0).astype(np.float32)
    u = np.array([-w, w, w, -w]) / 2000.0
    v = np.array([-h, -h, h, h]) / 2000.0
    img = cam.project(pose.points(u, v))
    src = np.stack([(u * 1000 + w / 2) / w * face.shape[1] - 0.5, (v * 1000 + h / 2) / h * face.shape[0] - 0.5], 1)
    dst = (img + 0.5) * k - 0.5
    m = cv2.getPerspectiveTransform(src.astype(np.float32), dst.astype(np.float32))
    big = cv2.warpPerspective(refl, m, (cam.width * k, cam.height * k), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0.5)
    small = cv2.resize(big, (cam.width, cam.height), interpolation=cv2.INTER_AREA)
    return expose(small, "normal", blur=0.5, noise=1.0, rng=rng)


@pytest.mark.parametrize("paper, bar_width, polarity, distance, alpha", [
    ("a4", 0.075, "positive", 2.5, 0.0), ("a4", 0.075, "negative", 2.5, 0.0),
    ("a3", 0.075, "negative", 2.5, 0.0), ("a4", 0.04, "positive", 1.5, math.radians(25))])
def test_detect_targets_finds_the_printed_target(tmp_path, paper, bar_width, polarity, distance, alpha):
    pages, doc = _print(tmp_path, paper, bar_width, polarity)
    face, size_mm = _face(pages, doc)
    assert face.shape[1] * PX == pytest.approx(size_mm[0], abs=0.2)
    cam = Camera.thesis(16.0)
    spec = TargetSpec.from_bar_width(bar_width)
    frame = _frame(face, size_mm, cam, TargetPose(distance, 0.0, alpha, 0.0), np.random.default_rng(1))
    found = detect_targets(frame, cam, spec)
    assert len(found) == 1, found
    print(f"{paper} b={bar_width} {polarity}: detected at {found[0].distance:.4f} m (true {distance} m), "
          f"alpha {math.degrees(found[0].alpha):.1f} deg")
    assert found[0].polarity == polarity
    assert found[0].distance == pytest.approx(distance, rel=0.02)
    assert found[0].alpha == pytest.approx(alpha, abs=math.radians(3))


# ------------------------------------------------------------ the command

def _run(argv, capfd):
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    out, err = capfd.readouterr()
    return rc, out, err


def test_ids_print_one_target_each_several_to_a_page(tmp_path, capfd):
    out = tmp_path / "ids.pdf"
    rc, stdout, err = _run(["target", "print", "--paper", "a4", "--bar-width", "0.04", "--ids", "A1", "B2", "C3",
                            "--polarity", "negative", "--out", str(out)], capfd)
    assert rc == 0, err
    doc = pymupdf.open(out)
    assert len(doc) == 2  # two 160 x 120 mm targets to an A4 page
    text = [doc[k].get_text().split() for k in range(len(doc))]
    assert "A1" in text[0] and "B2" in text[0] and "C3" in text[1]
    assert sum(len(_bars(_raster(doc, k), "negative")) for k in range(len(doc))) == 6
    assert "3 targets on 2 pages of a4" in stdout


def test_the_thesis_target_is_whole_on_a3_and_tabloid_and_in_halves_on_a4_and_letter():
    t = PrintTarget("T01")
    assert [p.part for p in pieces(t, "a3")] == [p.part for p in pieces(t, "tabloid")] == ["whole"]
    assert [p.part for p in pieces(t, "a4")] == [p.part for p in pieces(t, "letter")] == ["left", "right"]
    largest = largest_bar_width("a4")
    pieces(PrintTarget("T01", TargetSpec.from_bar_width(largest)), "a4")
    with pytest.raises(ValueError, match="does not fit a4"):
        pieces(PrintTarget("T01", TargetSpec.from_bar_width(largest + 0.001)), "a4")


@pytest.mark.parametrize("paper, pages_per_target", [("a3", 1), ("a4", 2)])
def test_a_map_prints_a_page_per_target_with_where_it_hangs(tmp_path, capfd, paper, pages_per_target):
    from agvsim.world import load_map

    out = tmp_path / "map.pdf"
    ids = ["T01", "T05", "T12"]
    rc, _, err = _run(["target", "print", "--map", "plant_floor", "--ids", *ids, "--paper", paper,
                       "--out", str(out)], capfd)
    assert rc == 0, err
    doc = pymupdf.open(out)
    assert len(doc) == len(ids) * pages_per_target
    world = load_map("plant_floor")
    for n, i in enumerate(ids):
        t = world.target(i)
        for k in range(n * pages_per_target, (n + 1) * pages_per_target):
            text = " ".join(doc[k].get_text().split())
            assert i in text.split()
            assert f"wall {t.wall}: {t.at:.2f} m along the wall" in text and f"{t.side} side" in text
            assert f"centre {t.height:.2f} m above the floor" in text and t.polarity in text
            assert len(_bars(_raster(doc, k), t.polarity)) == 2 // pages_per_target


def test_a_whole_map_and_json(tmp_path, capfd):
    import json

    out = tmp_path / "corridor.pdf"
    rc, stdout, err = _run(["target", "print", "--map", "corridor", "--paper", "tabloid", "--out", str(out),
                            "--json"], capfd)
    assert rc == 0, err
    summary = json.loads(stdout)
    assert summary["pages"] == 12 == len(pymupdf.open(out)) == len(summary["targets"])
    assert {t["polarity"] for t in summary["targets"]} == {"positive", "negative"}
    assert not any(t["in_halves"] for t in summary["targets"])


@pytest.mark.parametrize("argv, needles", [
    (["--bar-width", "-0.05"], ["--bar-width", "'-0.05'", "> 0 (m)"]),
    (["--bar-width", "0.3"], ["--bar-width 0.3", "does not fit a4", "expected a bar width <=", "a3"]),
    (["--paper", "a5"], ["--paper", "'a5'", "a4", "letter"]),
    (["--map", "plant_floor", "--ids", "T01", "T99"], ["--ids T99", "no target 'T99'", "did you mean"]),
    (["--map", "plant_flor"], ["--map 'plant_flor'", "did you mean 'plant_floor'"]),
    (["--map", "corridor", "--polarity", "negative"], ["--polarity negative", "from the map"]),
    (["--ids", "A", "A"], ["--ids A", "twice"]),
    (["--out", "targets.png"], ["--out 'targets.png'", "expected a .pdf"]),
])
def test_bad_input_is_one_line(tmp_path, capfd, monkeypatch, argv, needles):
    monkeypatch.chdir(tmp_path)
    base = {"--paper": "a4", "--out": "sub/targets.pdf"}
    for flag in ("--paper", "--out"):
        if flag in argv:
            base.pop(flag)
    rc, _, err = _run(["target", "print", *argv, *[x for kv in base.items() for x in kv]], capfd)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert not list(tmp_path.iterdir())  # nothing written, no folder made


def test_without_paper_it_prints_on_a4_and_says_so(tmp_path, capfd):
    out = tmp_path / "default.pdf"
    rc, stdout, err = _run(["target", "print", "--bar-width", "0.04", "--out", str(out)], capfd)
    assert rc == 0, err
    page = pymupdf.open(out)[0].rect
    assert (round(page.width / 72 * 25.4), round(page.height / 72 * 25.4)) in ((210, 297), (297, 210))
    assert "of a4 (the default paper; --paper letter" in stdout
    rc, stdout, err = _run(["target", "print", "--bar-width", "0.04", "--paper", "letter", "--out", str(out)], capfd)
    assert rc == 0 and "of letter (" in stdout and "default paper" not in stdout
