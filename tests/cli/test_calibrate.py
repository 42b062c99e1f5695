"""``agvsim calibrate``: synthetic chessboard views through a known camera come back as that
camera, in the file ``agvsim localize --camera`` reads; boards not found are named and skipped;
a user's mistakes are one line and exit status 2, with nothing written."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from agvsim.cli import main
from localizer import Camera
from localizer.tools.synthetic import pose_at_column, render_frame
from tests.cli.chessboard_views import TRUE_CAMERA, write_views

BOARD = ["--board", "9x6", "--square", "0.025"]


@pytest.fixture(scope="module")
def views(tmp_path_factory):
    """A folder of 8 views of a 9x6 board (25 mm squares) through TRUE_CAMERA, and a board-free image."""
    root = tmp_path_factory.mktemp("calib")
    paths = write_views(root / "views")
    blank = root / "blank.png"
    rng = np.random.default_rng(3)
    cv2.imwrite(str(blank), cv2.GaussianBlur(rng.integers(0, 256, (480, 640), dtype=np.uint8), (0, 0), 2))
    return paths, blank


def _run(argv, capfd):
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse's errors
        rc = exc.code
    out, err = capfd.readouterr()
    return rc, out, err


def _lines(err):
    return [ln for ln in err.splitlines() if ln.strip()]


def test_calibration_recovers_the_camera_and_writes_the_camera_file(views, tmp_path, capfd):
    paths, blank = views
    out = tmp_path / "calib.yaml"
    rc, stdout, err = _run(["calibrate", str(paths[0].parent), str(blank), *BOARD, "--out", str(out), "--json"], capfd)
    assert rc == 0, err
    data = json.loads(stdout)  # exactly one JSON object
    cam = data["camera"]
    assert abs(cam["fx"] / TRUE_CAMERA.fx - 1) < 0.01 and abs(cam["fy"] / TRUE_CAMERA.fy - 1) < 0.01
    assert abs(cam["cx"] - TRUE_CAMERA.cx) < 3 and abs(cam["cy"] - TRUE_CAMERA.cy) < 3
    assert abs(data["distortion"]["k1"] - TRUE_CAMERA.dist[0]) < 0.01
    assert data["rms_px"] < 0.1 and data["views"] == len(paths) and data["ok"] and not data["replaced"]
    statuses = {r["image"]: r["status"] for r in data["images"]}
    assert statuses == {**{str(p): "used" for p in paths}, str(blank): "no board"}
    assert all(r["rms_px"] < 0.1 for r in data["images"] if r["status"] == "used")
    # the board-free image: one line naming it; the others used
    assert _lines(err) == [f"no 9x6 chessboard found in {blank}; skipped"]
    # the file loads through the loader --camera uses and is the camera reported
    loaded = Camera.from_opencv_yaml(out)
    assert loaded.size == (640, 480)
    assert np.allclose([loaded.fx, loaded.fy, loaded.cx, loaded.cy], [cam["fx"], cam["fy"], cam["cx"], cam["cy"]],
                       rtol=1e-10)
    assert np.allclose(loaded.dist, cam["dist"], rtol=1e-9, atol=1e-12) and len(loaded.dist) == 5
    assert not list(tmp_path.glob(".tmp-*"))
    # ... and `agvsim localize --camera` takes it unchanged
    pinhole = Camera.from_intrinsics(loaded.fx, loaded.fy, loaded.cx, loaded.cy, 640, 480)
    frame = tmp_path / "frame.png"
    cv2.imwrite(str(frame), render_frame(pinhole, pose_at_column(pinhole, 2.0, 0.0), noise=0.0))
    rc, stdout, err = _run(["localize", str(frame), "--camera", str(out), "--json"], capfd)
    assert rc == 0, err
    located = json.loads(stdout)
    assert located["camera"]["fx"] == pytest.approx(loaded.fx, rel=1e-9)
    assert abs(located["results"][0]["targets"][0]["distance_m"] - 2.0) < 0.05


def test_human_output_and_a_replaced_file(views, tmp_path, capfd):
    paths, _ = views
    out = tmp_path / "sub" / "calib.xml"  # the folder is made; XML as OpenCV writes it
    rc, stdout, err = _run(["calibrate", *map(str, paths[:4]), *BOARD, "--out", str(out)], capfd)
    assert rc == 0 and err == "", err
    assert "RMS reprojection error 0.0" in stdout and "over 4 views" in stdout and f"wrote {out}\n" in stdout
    assert stdout.count(" used ") == 4 and ("fx 79" in stdout or "fx 80" in stdout)
    first = Camera.from_opencv_yaml(out)
    rc, stdout, err = _run(["calibrate", *map(str, paths), *BOARD, "--out", str(out), "--k3"], capfd)
    assert rc == 0 and f"wrote {out} (replaced the earlier file)" in stdout
    second = Camera.from_opencv_yaml(out)
    assert second.dist[4] != 0.0 and first.dist[4] == 0.0  # --k3 estimated k3


def test_many_images_show_progress_on_stderr_only(views, tmp_path, capfd):
    paths, _ = views
    many = [str(p) for p in paths] * 2  # 16 images
    rc, stdout, err = _run(["calibrate", *many, *BOARD, "--out", str(tmp_path / "c.yaml"), "--json"], capfd)
    assert rc == 0
    assert json.loads(stdout)["views"] == 16
    assert "calibrate:" in err and "/16 [" in err  # the bar (tqdm, redrawn at most every 0.1 s)


def test_too_few_views_write_nothing(views, tmp_path, capfd):
    paths, blank = views
    out = tmp_path / "calib.yaml"
    rc, _, err = _run(["calibrate", *map(str, paths[:2]), *BOARD, "--out", str(out)], capfd)
    assert rc == 2 and len(_lines(err)) == 1 and "Traceback" not in err
    assert "found in 2 of 2 images" in err and "at least 3" in err and "nothing written" in err
    assert not out.exists()
    # the wrong board: every image named, then the one error line
    rc, _, err = _run(["calibrate", *map(str, paths[:3]), "--board", "8x6", "--square", "0.025", "--out", str(out)],
                      capfd)
    lines = _lines(err)
    assert rc == 2 and lines[:3] == [f"no 8x6 chessboard found in {p}; skipped" for p in paths[:3]]
    assert len(lines) == 4 and "found in 0 of 3 images" in lines[3] and not out.exists()


def test_views_that_do_not_determine_the_focal_length(tmp_path, capfd):
    out = tmp_path / "calib.yaml"
    square_on = write_views(tmp_path / "flat", poses=[((0, 0, roll), c) for roll, c in
                                                     ((0, (0, 0, 0.55)), (0, (0.05, 0, 0.6)), (10, (-0.05, 0.02, 0.5)))])
    rc, stdout, err = _run(["calibrate", *map(str, square_on), *BOARD, "--out", str(out)], capfd)
    assert rc == 2 and len(_lines(err)) == 1 and stdout == "" and not out.exists()
    assert "do not determine the focal length" in err and "tilted 20 to 45 degrees" in err
    # boards a few degrees apart: a focal length, said to be uncertain
    few = write_views(tmp_path / "few", poses=[((0, 0, 0), (0, 0, 0.55)), ((5, 0, 0), (0.05, 0, 0.6)),
                                               ((0, 5, 10), (-0.05, 0.02, 0.5))])
    rc, stdout, err = _run(["calibrate", *map(str, few), *BOARD, "--out", str(out), "--json"], capfd)
    data = json.loads(stdout)
    assert rc == 0 and abs(data["camera"]["fx"] / TRUE_CAMERA.fx - 1) < 0.05 and data["sigma"]["fx"] > 8
    assert "focal length is uncertain to 1." in err and "add views" in err and out.exists()


def test_images_of_different_sizes_write_nothing_and_keep_the_old_file(views, tmp_path, capfd):
    paths, _ = views
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), cv2.resize(cv2.imread(str(paths[3]), cv2.IMREAD_GRAYSCALE), (320, 240)))
    out = tmp_path / "calib.yaml"
    out.write_text("earlier\n")
    rc, stdout, err = _run(["calibrate", *map(str, paths[:3]), str(small), *BOARD, "--out", str(out)], capfd)
    assert rc == 2 and len(_lines(err)) == 1 and stdout == ""
    assert str(small) in err and "320x240" in err and "640x480" in err and "nothing written" in err
    assert out.read_text() == "earlier\n"


def test_a_failed_write_leaves_the_old_file(views, tmp_path, capfd, monkeypatch):
    paths, _ = views
    out = tmp_path / "calib.yaml"
    out.write_text("earlier\n")

    def broken(self, path):
        with open(path, "w") as f:
            f.write("%YAML 1.2\n---\nimage_wi")
        raise OSError(f"{path}: disk full")

    monkeypatch.setattr(Camera, "to_opencv_yaml", broken)
    rc, _, err = _run(["calibrate", *map(str, paths[:3]), *BOARD, "--out", str(out)], capfd)
    assert rc == 2 and "disk full" in err and len(_lines(err)) == 1
    assert out.read_text() == "earlier\n" and sorted(p.name for p in tmp_path.iterdir()) == ["calib.yaml"]


def test_an_unreadable_image_is_reported_and_the_others_used(views, tmp_path, capfd):
    paths, _ = views
    text = tmp_path / "notes.png"
    text.write_text("not an image")
    out = tmp_path / "calib.yaml"
    rc, stdout, err = _run(["calibrate", str(text), *map(str, paths[:3]), *BOARD, "--out", str(out), "--json"], capfd)
    data = json.loads(stdout)
    assert rc == 2 and not data["ok"] and data["views"] == 3 and out.exists()
    assert data["images"][0]["status"] == "error" and str(text) in data["images"][0]["error"]
    assert str(text) in _lines(err)[0] and "Traceback" not in err


@pytest.mark.parametrize("args, needles", [
    (["--board", "9", "--square", "0.025"], ["--board", "'9'", "COLSxROWS"]),
    (["--board", "9x", "--square", "0.025"], ["--board", "'9x'", "COLSxROWS"]),
    (["--board", "2x6", "--square", "0.025"], ["--board", "'2x6'", "from 3"]),
    (["--board", "9x6x2", "--square", "0.025"], ["--board", "'9x6x2'"]),
    (["--board", "axb", "--square", "0.025"], ["--board", "'axb'"]),
    (["--board", "9x6", "--square", "0"], ["--square", "'0'", "> 0 (m)"]),
    (["--board", "9x6", "--square", "-0.02"], ["--square", "'-0.02'", "> 0 (m)"]),
    (["--board", "9x6", "--square", "nan"], ["--square", "'nan'", "finite"]),
    (["--board", "9x6", "--square", "25mm"], ["--square", "'25mm'"]),
    (["--square", "0.025"], ["--board", "required"]),
    (["--board", "9x6", "--square", "0.025", "--out", "calib.txt"], ["--out", "calib.txt", ".yaml, .yml, .xml"]),
])
def test_bad_flags_are_one_line(views, tmp_path, capfd, args, needles):
    paths, _ = views
    argv = ["calibrate", *map(str, paths[:3]), *args]
    if "--out" not in args:
        argv += ["--out", str(tmp_path / "calib.yaml")]
    rc, stdout, err = _run(argv, capfd)
    lines = _lines(err)
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err and stdout == "", err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    assert not (tmp_path / "calib.yaml").exists()


def test_bad_files_are_one_line(views, tmp_path, capfd):
    paths, _ = views
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "readme.txt").write_text("no images here")
    rc, _, err = _run(["calibrate", str(empty), *BOARD, "--out", str(tmp_path / "c.yaml")], capfd)
    assert rc == 2 and len(_lines(err)) == 1 and str(empty) in err and "no image files" in err
    rc, _, err = _run(["calibrate", *map(str, paths[:3]), *BOARD, "--out", str(empty)], capfd)
    assert rc == 2 and len(_lines(err)) == 1 and "--out" in err and "a folder" in err
    missing = tmp_path / "missing.png"
    rc, _, err = _run(["calibrate", str(missing), *map(str, paths[:3]), *BOARD, "--out", str(tmp_path / "c.yaml")],
                      capfd)
    assert rc == 2 and f"{missing}: no such file" in _lines(err)[0]
