"""``agvsim calibrate IMAGES... --board 9x6 --square 0.025 --out calib.yaml``: the camera file
``agvsim localize --camera`` reads, from photographs of a printed chessboard."""
from __future__ import annotations

import argparse
from typing import NamedTuple

from agvsim.commands._args import number
from agvsim.commands._output import add_json_flag, emit_json, log

#: the suffixes taken from a folder given as IMAGES (the formats localizer.image.io reads)
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm", ".pbm", ".pnm")
#: the suffixes of --out: OpenCV FileStorage formats Camera.from_opencv_yaml reads
OUT_SUFFIXES = (".yaml", ".yml", ".xml")
#: more images than this get a progress bar on stderr
PROGRESS_FROM = 10
#: an RMS reprojection error above this (px) is said to be suspect
RMS_WARN_PX = 1.0
#: a focal length whose standard deviation is above this fraction of it is said to be uncertain
FOCAL_WARN = 0.01


def board_size(text: str) -> tuple[int, int]:
    """``COLSxROWS`` inner corners (``9x6``) -> ``(9, 6)``, each a whole number >= 3."""
    from localizer.tools.calibrate import check_board

    cols, sep, rows = text.lower().partition("x")
    try:
        if not sep:
            raise ValueError(text)
        return check_board(int(cols), int(rows))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected COLSxROWS inner corners, each a whole number from 3 to 1000 "
                                         f"(9x6 for a board of 10 x 7 squares), got {text!r}") from None


def register(sub) -> None:
    p = sub.add_parser(
        "calibrate", help="calibrate a camera from chessboard photographs (writes the --camera file)",
        description="Calibrate a camera from photographs of a flat printed chessboard (OpenCV: "
                    "findChessboardCorners, cornerSubPix, calibrateCamera) and write the OpenCV calibration "
                    "file that 'agvsim localize --camera' and localizer.Camera.from_opencv_yaml read "
                    "(camera_matrix, distortion_coefficients k1 k2 p1 p2 k3, image_width, image_height). "
                    "Take 10 to 20 photographs with the camera's own lens and focus, the whole board in each, "
                    "tilted 20 to 45 degrees about both axes and reaching into the corners of the frame. "
                    "Prints the RMS reprojection error in pixels (well under 1 px for a good set) and each "
                    "image's status; an image without the board is named and skipped. Fewer than 3 usable "
                    "views or images of different sizes: exit status 2 and nothing written. An image that "
                    "cannot be read is reported and the others are used (exit status 2).")
    p.add_argument("images", nargs="+", metavar="IMAGE",
                   help="image files (PNG, JPEG, BMP, TIFF, WebP, PGM) or folders of them (their image files "
                        "by name, not recursing)")
    p.add_argument("--board", type=board_size, required=True, metavar="COLSxROWS",
                   help="the chessboard's inner corners (where four squares meet), along a row x down a column: "
                        "9x6 for a board of 10 x 7 squares (6x9 finds it too)")
    p.add_argument("--square", type=number(0.0, low_open=True, unit="m"), required=True, metavar="M",
                   help="side of one square in metres, as printed (e.g. 0.025); it scales the board poses, "
                        "not the intrinsics")
    p.add_argument("--out", required=True, metavar="CALIB.yaml",
                   help="the calibration file to write (.yaml, .yml or .xml); written to a temporary file and "
                        "renamed, so an earlier file is replaced whole or not at all (the output says when one "
                        "was replaced)")
    p.add_argument("--k3", action="store_true",
                   help="also estimate the third radial distortion coefficient k3 (wide-angle lenses; held at 0 "
                        "by default)")
    add_json_flag(p)
    p.set_defaults(func=run)


def _image_list(names: list[str]) -> list[str]:
    """The image files named, a folder replaced by its image files (sorted by name)."""
    from pathlib import Path

    files = []
    for name in names:
        path = Path(name)
        if path.is_dir():
            found = sorted(str(f) for f in path.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES and f.is_file())
            if not found:
                raise ValueError(f"{name}: a folder with no image files; expected files ending in "
                                 f"{', '.join(IMAGE_SUFFIXES)}")
            files += found
        else:
            files.append(name)
    return files


def _check_out(out: str):
    from pathlib import Path

    path = Path(out)
    if path.is_dir():
        raise ValueError(f"--out {out!r}: a folder, expected a calibration file name ending in "
                         f"{', '.join(OUT_SUFFIXES)}")
    if path.suffix.lower() not in OUT_SUFFIXES:
        raise ValueError(f"--out {out!r}: expected a calibration file name ending in {', '.join(OUT_SUFFIXES)} "
                         f"(the OpenCV formats --camera reads)")
    return path


def _write(camera, path) -> None:
    """Write ``camera`` to ``path`` through a temporary file, read back as ``--camera`` reads it."""
    import math

    from agvsim.commands.run_folder import atomic_write
    from localizer import Camera

    with atomic_write(path) as tmp:
        camera.to_opencv_yaml(tmp)
        back = Camera.from_opencv_yaml(tmp)
        same = [math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12) for a, b in
                zip((back.fx, back.fy, back.cx, back.cy, *back.dist), (camera.fx, camera.fy, camera.cx,
                                                                      camera.cy, *camera.dist))]
        if back.size != camera.size or len(back.dist) != len(camera.dist) or not all(same):
            raise OSError(f"--out {str(path)!r}: the file written does not read back as the calibration")


def run(args: argparse.Namespace) -> int:
    from localizer.tools.calibrate import MIN_VIEWS, calibrate_views

    cols, rows = args.board
    out = _check_out(args.out)
    files = _image_list(args.images)
    board = f"{cols}x{rows}"
    views = _find_boards(files, cols, rows)
    if len(views.corners) < MIN_VIEWS:
        raise ValueError(f"a {board} chessboard was found in {len(views.corners)} of {len(files)} images; calibration "
                         f"needs at least {MIN_VIEWS} (check --board: inner corners, 9x6 for 10 x 7 squares); "
                         "nothing written")
    result = calibrate_views(views.corners, views.size, cols, rows, args.square, k3=args.k3)
    for k, i in enumerate(views.used):
        views.rows[i]["rms_px"] = float(result.view_rms[k])
    replaced = out.exists()
    _write(result.camera, out)
    _warn_if_weak(result)
    status = 2 if views.failed else 0
    if args.json:
        _emit(args, out, replaced, views, result)
        return status
    _print_result(args, out, replaced, views, result)
    if views.failed:
        log(f"agvsim calibrate: {views.failed} of {len(files)} images could not be read")
    return status


class _Views(NamedTuple):
    """The chessboards found in the images: per image a row (``image``, ``status``: used, no
    board or error), the corners of the boards found (``(N, 1, 2)`` float32 px each), the rows of
    the images used, how many images could not be read, and the image size ``(width, height)``."""

    rows: list
    corners: list
    used: list
    failed: int
    size: tuple | None


def _find_boards(files: list, cols: int, rows: int) -> _Views:
    """The chessboard of ``cols x rows`` inner corners in each image (a progress bar over many); an
    unreadable image is counted and reported, one of another size stops the run (nothing written)."""
    import sys

    from tqdm import tqdm

    from localizer.tools.calibrate import find_chessboard
    from localizer.image.io import read_image_grey

    board = f"{cols}x{rows}"
    rows_out, corners, used, failed = [], [], [], 0
    size = first = None
    bar = tqdm(total=len(files), desc="calibrate", unit=" image", file=sys.stderr, leave=False,
               disable=len(files) < PROGRESS_FROM)

    def say(message: str) -> None:
        bar.write(message, file=sys.stderr) if not bar.disable else log(message)

    try:
        for name in files:
            bar.update(1)
            try:
                img = read_image_grey(name)
            except ValueError as exc:  # this image only
                failed += 1
                say(f"agvsim calibrate: error: {exc}")
                rows_out.append({"image": name, "status": "error", "error": str(exc)})
                continue
            shape = (img.shape[1], img.shape[0])
            if size is None:
                size, first = shape, name
            elif shape != size:
                raise ValueError(f"{name}: image is {shape[0]}x{shape[1]} but {first} is {size[0]}x{size[1]}; "
                                 "expected photographs of one camera at one resolution (nothing written)")
            found = find_chessboard(img, cols, rows)
            if found is None:
                say(f"no {board} chessboard found in {name}; skipped")
                rows_out.append({"image": name, "status": "no board"})
                continue
            corners.append(found)
            used.append(len(rows_out))
            rows_out.append({"image": name, "status": "used"})
    finally:
        bar.close()
    return _Views(rows_out, corners, used, failed, size)


def _warn_if_weak(result) -> None:
    """A line on stderr when the fit is poor or the focal length uncertain (what to do about it)."""
    import math

    cam = result.camera
    if result.rms > RMS_WARN_PX:
        log(f"agvsim calibrate: the RMS reprojection error is {result.rms:.2f} px (a good set is well under "
            f"{RMS_WARN_PX:g} px): check --board and that the board is flat and sharp in every image")
    uncertain = max(result.sigma["fx"] / cam.fx, result.sigma["fy"] / cam.fy)
    if uncertain > FOCAL_WARN:
        log(f"agvsim calibrate: the focal length is uncertain to {100 * uncertain:.1f} % (one standard deviation; "
            f"the views' boards differ by at most {math.degrees(result.tilt_spread):.0f} degrees): add views "
            "tilted 20 to 45 degrees in different directions")


def _distortion(cam) -> dict:
    from localizer.tools.calibrate import DIST_NAMES

    return dict(zip(DIST_NAMES, cam.dist or (0.0,) * len(DIST_NAMES)))


def _emit(args, out, replaced: bool, views: _Views, result) -> None:
    """The ``--json`` object (SI units; degrees only in ``tilt_spread_deg``)."""
    import math

    cols, rows = args.board
    cam = result.camera
    emit_json({"ok": not views.failed, "out": str(out), "replaced": replaced,
               "board": {"cols": cols, "rows": rows, "square_m": args.square},
               "views": len(views.corners), "rms_px": result.rms,
               "tilt_spread_deg": math.degrees(result.tilt_spread),
               "camera": {"fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy, "width": cam.width,
                          "height": cam.height, "dist": list(cam.dist)},
               "distortion": _distortion(cam), "sigma": result.sigma, "images": views.rows})


def _print_result(args, out, replaced: bool, views: _Views, result) -> None:
    """The table of images and the camera found, for a person."""
    cols, rows = args.board
    cam = result.camera
    print(f"{'image':<40} {'status':<9} {'rms (px)':>8}")
    for r in views.rows:
        rms = f"{r['rms_px']:8.3f}" if "rms_px" in r else f"{'-':>8}"
        print(f"{r['image'][-40:]:<40} {r['status']:<9} {rms}" + (f"  {r['error']}" if "error" in r else ""))
    s = result.sigma
    print(f"\nRMS reprojection error {result.rms:.3f} px over {len(views.corners)} views "
          f"({cols}x{rows} inner corners, {1000 * args.square:g} mm squares)")
    print(f"fx {cam.fx:.2f}  fy {cam.fy:.2f}  cx {cam.cx:.2f}  cy {cam.cy:.2f}  (px, {cam.width}x{cam.height}; "
          f"standard deviations {s['fx']:.2f} {s['fy']:.2f} {s['cx']:.2f} {s['cy']:.2f})")
    print("distortion " + "  ".join(f"{k} {v:.5f}" for k, v in _distortion(cam).items()))
    print(f"wrote {out}" + (" (replaced the earlier file)" if replaced else ""))
