"""A user's mistakes on the command line: one line on stderr naming the flag or file, the value
and what was expected, exit status 2, no traceback (``--debug`` shows one); writes that are
reported happened; one unreadable image among several does not stop the others."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from agvsim.cli import main
from localizer import Camera
from localizer.tools.synthetic import pose_at_column, render_frame


def _run(argv, capfd):
    """``(exit status, stdout, stderr)`` of ``agvsim ARGV`` in this process (OpenCV's own writes to
    the stderr descriptor included)."""
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse's errors
        rc = exc.code
    out, err = capfd.readouterr()
    return rc, out, err


def _one_line_error(rc, err, *needles):
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in lines[0], (n, lines[0])


@pytest.fixture(scope="module")
def target_png(tmp_path_factory):
    cam = Camera.thesis(16.0)
    img = render_frame(cam, pose_at_column(cam, 3.2, 0.4, 300, 0.05), noise=1.0, rng=np.random.default_rng(0))
    path = tmp_path_factory.mktemp("frames") / "target.png"
    cv2.imwrite(str(path), img)
    return path


@pytest.mark.parametrize("argv, needles", [
    (["render", "--pose", "-100", "8.5", "0", "--out", "x.png"], ["--pose", "-100", "outside map", "expected x in"]),
    (["render", "--pose", "30", "4", "0", "--lens", "0", "--out", "x.png"], ["--lens", "'0'", "> 0 (mm)"]),
    (["render", "--pose", "30", "4", "0", "--out", "frame.xyz"], ["--out", "frame.xyz", "expected a .png"]),
    (["demo", "--frames", "-1"], ["--frames", "'-1'", ">= 0"]),
    (["demo", "--route", "nope"], ["--route", "'nope'", "default"]),
    (["drift", "--route", "defualt", "--distance", "5", "--seeds", "1"], ["--route", "did you mean 'default'"]),
    (["drift", "--workers", "0"], ["--workers", "'0'", ">= 1"]),
    (["reproduce", "thesis", "--noise", "-1"], ["--noise", "'-1'", ">= 0"]),
    (["localize", "x.png", "--lens", "0"], ["--lens", "> 0 (mm)"]),
    (["map", "mounts", "plant_floor", "--route", "nope"], ["--route", "'nope'"]),
    (["drift", "--camera-rate", "1e6"], ["--camera-rate", "<= 100 (Hz)"]),
    (["drift", "--latency", "1e9"], ["--latency", "<= 5 (s)"]),
    (["render", "--pose", "30", "4", "0", "--defocus", "1e6", "--out", "x.png"], ["--defocus", "<= 50 (px)"]),
    (["bench", "render", "--frames", "-1"], ["--frames", "'-1'", ">= 1"]),
    (["bench", "localizer", "--repeats", "0"], ["--repeats", "'0'", ">= 1"]),
    (["bench", "env", "--steps", "1.5"], ["--steps", "whole number"]),
    (["render", "--map", "plant_flor", "--pose", "1", "1", "0", "--out", "x.png"], ["did you mean 'plant_floor'"]),
])
def test_a_bad_value_is_one_line_naming_the_flag(argv, needles, capfd, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rc, _, err = _run(argv, capfd)
    _one_line_error(rc, err, *needles)
    assert not list(tmp_path.iterdir())  # nothing written


def test_debug_shows_the_traceback(capfd, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rc, _, err = _run(["render", "--pose", "30", "4", "0", "--out", "frame.xyz", "--debug"], capfd)
    assert rc == 2 and "Traceback" in err and err.strip().splitlines()[-1].startswith("agvsim render: error:")


def test_a_file_that_is_not_a_calibration(tmp_path, target_png, capfd):
    bad = tmp_path / "bad.yaml"
    bad.write_text("camera_matrix: [1, 2, 3]\nfoo: bar\n")
    rc, _, err = _run(["localize", str(target_png), "--camera", str(bad)], capfd)
    _one_line_error(rc, err, "--camera", "bad.yaml", "not an OpenCV calibration file", "camera_matrix")


def test_annotate_into_a_new_folder_writes_the_file(tmp_path, target_png, capfd):
    out = tmp_path / "some" / "new" / "folder" / "a.png"
    rc, _, err = _run(["localize", str(target_png), "--annotate", str(out)], capfd)
    assert rc == 0 and f"wrote {out}" in err
    assert cv2.imread(str(out)) is not None


def test_annotate_with_a_name_opencv_cannot_write(tmp_path, target_png, capfd):
    rc, out, err = _run(["localize", str(target_png), "--annotate", str(tmp_path / "a.xyz")], capfd)
    _one_line_error(rc, err, "--annotate", "a.xyz", "expected a .png")
    assert out == "" and not list(tmp_path.iterdir())


def test_unreadable_images_are_reported_one_by_one_and_the_others_localized(tmp_path, target_png, capfd):
    folder = tmp_path / "a_folder"
    folder.mkdir()
    text = tmp_path / "notes.png"
    text.write_text("not an image\n")
    missing = tmp_path / "missing.png"
    rc, out, err = _run(["localize", str(missing), str(folder), str(text), str(target_png), "--json"], capfd)
    assert rc == 2
    assert "WARN" not in err and "Traceback" not in err  # OpenCV is not asked to open what is not there
    res = json.loads(out)
    assert res["ok"] is False and [r["image"] for r in res["results"]] == [str(missing), str(folder), str(text),
                                                                          str(target_png)]
    errors = [r.get("error", "") for r in res["results"]]
    assert "no such file" in errors[0] and "a folder" in errors[1] and "expected one of PNG" in errors[2]
    assert errors[3] == "" and len(res["results"][3]["targets"]) == 1  # the good image still localized
    assert len(set(errors[:3])) == 3  # three different reasons
    # the table says the same, and the exit status is not 0
    rc, out, err = _run(["localize", str(missing), str(target_png)], capfd)
    assert rc == 2 and "no such file" in out and "positive" in out and "1 of 2 images could not be read" in err


def test_render_writes_into_a_new_folder(tmp_path, capfd):
    out = tmp_path / "new" / "frame.png"
    rc, _, err = _run(["render", "--pose", "30", "4", "-1.5708", "--out", str(out), "--no-noise"], capfd)
    assert rc == 0 and out.is_file() and np.asarray(cv2.imread(str(out))).shape[:2] == (480, 512)


def test_a_closed_pipe_ends_quietly(monkeypatch, capfd):
    """``agvsim ... | head``: the reader goes away; no error line, no traceback."""
    import agvsim.commands.reproduce as rep

    def run(args):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(rep, "run", run)
    try:
        rc = main(["reproduce", "thesis"])
    finally:
        import sys
        sys.stdout = sys.__stdout__
    _, err = capfd.readouterr()
    assert rc == 1 and "error" not in err and "Traceback" not in err


def test_a_pose_inside_an_obstacle_is_warned_about(tmp_path, capfd):
    from agvsim.world import load_map

    m = load_map("plant_floor")
    ob = m.obstacles[0]
    x, y = (float(v) for v in np.mean(np.asarray(ob.polygon), axis=0))
    assert not m.is_free(x, y)
    rc, _, err = _run(["render", "--pose", str(x), str(y), "0", "--no-noise", "--out", str(tmp_path / "f.png")], capfd)
    assert rc == 0 and "warning: --pose" in err and "inside a wall or an obstacle" in err


def test_writes_into_a_folder_or_a_full_device_are_errors(tmp_path, capfd):
    folder = tmp_path / "frames.png"
    folder.mkdir()
    rc, _, err = _run(["render", "--pose", "30", "4", "0", "--out", str(folder)], capfd)
    _one_line_error(rc, err, "--out", "a folder, expected an image file name")
    rc, _, err = _run(["drift", "--out", "/dev/null/x", "--distance", "10", "--seeds", "1", "--observations",
                       "geometric", "--no-progress"], capfd)
    assert rc == 2 and "Traceback" not in err and err.strip().splitlines()[-1].startswith("agvsim drift: error:")
