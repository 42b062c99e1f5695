"""Every file a user hands a command, cut off at three places (a copy stopped half-way, a download
cut short): one line on stderr naming the file, exit status 2, no traceback, and nothing written
under the command's output name.

The cuts fall inside a line: in a YAML file in the middle of a key (the text before its ``:``),
so that what is left is never a well-formed file of other values; in JSON and images anywhere.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from agvsim.cli import main
from localizer import Camera
from localizer.tools.synthetic import pose_at_column, render_frame

ROOT = Path(__file__).resolve().parents[2]
#: where the three cuts fall, as shares of the file's length
SHARES = (0.25, 0.5, 0.8)


def _run(argv, capfd):
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    out, err = capfd.readouterr()
    return rc, out, err


def _yaml_cut(text: str, share: float) -> str:
    """``text`` cut inside the key of the first ``key: value`` line at or after ``share`` of it."""
    start = int(share * len(text))
    offset = text.rfind("\n", 0, start) + 1
    for line in text[offset:].splitlines(keepends=True):
        body = line.split("#", 1)[0]
        key = body.lstrip(" -")
        if ":" in key and key.index(":") >= 2 and not key.startswith(("%", "!")):
            indent = len(body) - len(key)
            return text[:offset + indent + key.index(":") // 2 + 1]
        offset += len(line)
    raise AssertionError("no key to cut after that share")


def _cut_bytes(data: bytes, share: float) -> bytes:
    return data[:int(share * len(data))]


def _check(rc: int, err: str, name: str, *unwritten: Path) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    assert name in lines[0], lines[0]
    for path in unwritten:
        assert not path.exists(), f"{path} was written"


MAP_COMMANDS = {
    "map check": lambda m, out: ["map", "check", m],
    "map mounts": lambda m, out: ["map", "mounts", m],
    "render": lambda m, out: ["render", "--map", m, "--pose", "2", "2", "0", "--out", str(out / "frame.png")],
    "demo": lambda m, out: ["demo", "--map", m, "--out", str(out / "demo"), "--no-progress"],
    "drift": lambda m, out: ["drift", "--map", m, "--out", str(out / "drift"), "--seeds", "1", "--no-progress"],
    "plan": lambda m, out: ["plan", m, "--out", str(out / "plan.yaml")],
    "target print": lambda m, out: ["target", "print", "--map", m, "--out", str(out / "targets.pdf")],
}


@pytest.mark.parametrize("share", SHARES)
@pytest.mark.parametrize("command", sorted(MAP_COMMANDS))
def test_a_map_cut_off(tmp_path, capfd, command, share):
    bad = tmp_path / "cut.yaml"
    bad.write_text(_yaml_cut((ROOT / "maps" / "corridor.yaml").read_text(), share))
    out = tmp_path / "out"
    rc, _, err = _run(MAP_COMMANDS[command](str(bad), out), capfd)
    _check(rc, err, str(bad), out / "frame.png", out / "plan.yaml", out / "targets.pdf", out / "demo" / "topdown.png")


@pytest.mark.parametrize("share", SHARES)
def test_a_sweep_spec_cut_off(tmp_path, capfd, share):
    bad = tmp_path / "cut.yaml"
    bad.write_text(_yaml_cut((ROOT / "examples" / "sweep_small.yaml").read_text(), share))
    rc, _, err = _run(["sweep", str(bad), "--out", str(tmp_path / "sweep")], capfd)
    _check(rc, err, str(bad), tmp_path / "sweep" / "results.csv")


@pytest.fixture(scope="module")
def frame_png(tmp_path_factory) -> Path:
    cam = Camera.thesis(16.0)
    img = render_frame(cam, pose_at_column(cam, 3.2, 0.4, 300, 0.05), noise=1.0, rng=np.random.default_rng(0))
    path = tmp_path_factory.mktemp("frames") / "target.png"
    cv2.imwrite(str(path), img)
    return path


@pytest.mark.parametrize("share", SHARES)
@pytest.mark.parametrize("suffix", [".yaml", ".xml"])
def test_a_camera_file_cut_off(tmp_path, capfd, frame_png, suffix, share):
    whole = tmp_path / f"whole{suffix}"
    Camera.from_intrinsics(800.0, 805.0, 256.0, 240.0, 512, 480, (0.1, -0.05, 0.0, 0.0, 0.0)).to_opencv_yaml(whole)
    bad = tmp_path / f"cut{suffix}"
    text = whole.read_text()
    bad.write_text(_yaml_cut(text, share) if suffix == ".yaml" else text[:int(share * len(text))])
    rc, _, err = _run(["localize", str(frame_png), "--camera", str(bad), "--annotate", str(tmp_path / "ann")], capfd)
    _check(rc, err, str(bad), tmp_path / "ann")


@pytest.mark.parametrize("share", SHARES)
@pytest.mark.parametrize("suffix", [".png", ".jpg"])
def test_an_image_cut_off(tmp_path, capfd, frame_png, suffix, share):
    image = cv2.imread(str(frame_png))
    whole = tmp_path / f"whole{suffix}"
    cv2.imwrite(str(whole), image)
    bad = tmp_path / f"cut{suffix}"
    bad.write_bytes(_cut_bytes(whole.read_bytes(), share))
    rc, out, err = _run(["localize", str(bad)], capfd)
    assert rc != 0 and "Traceback" not in out + err
    # (each image's error in the table and on stderr, and nothing else: no decoder's own complaint)
    assert [ln for ln in err.splitlines() if ln.strip()] == [f"agvsim localize: error: {ln.split(' error: ', 1)[1]}"
                                                          for ln in out.splitlines() if " error: " in ln] + [
        "agvsim localize: 1 of 1 images could not be read"], err
    assert str(bad) in err and ("cut off" in err if suffix == ".png" else "not an image OpenCV can decode" in err)
    rc, _, err = _run(["calibrate", str(bad), str(bad), str(bad), "--board", "9x6", "--square", "0.025",
                       "--out", str(tmp_path / "calib.yaml")], capfd)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and "Traceback" not in err and not (tmp_path / "calib.yaml").exists(), err
    assert lines[:3] == [lines[0]] * 3 and str(bad) in lines[0] and "nothing written" in lines[3], err


@pytest.mark.parametrize("share", SHARES)
def test_a_run_folder_whose_record_is_cut_off(tmp_path, capfd, share):
    out = tmp_path / "drift"
    argv = ["drift", "--map", "corridor", "--seeds", "1", "--distance", "5", "--observations", "geometric",
            "--no-plots", "--no-progress", "--out", str(out)]
    rc, _, err = _run(argv, capfd)
    assert rc == 0, err
    record = out / "run.json"
    record.write_bytes(_cut_bytes(record.read_bytes(), share))
    seeds = sorted(p.name for p in (out / "seeds").iterdir())
    rc, _, err = _run(argv, capfd)
    _check(rc, err, "run.json")
    assert sorted(p.name for p in (out / "seeds").iterdir()) == seeds  # nothing lost
    with pytest.raises(json.JSONDecodeError):
        json.loads(record.read_text())  # (left as it was for the user to look at)
    shutil.rmtree(out)


@pytest.mark.parametrize("share", SHARES)
def test_a_sweep_folder_whose_record_is_cut_off(tmp_path, capfd, share):
    spec = ROOT / "examples" / "sweep_small.yaml"
    out = tmp_path / "sweep"
    (out / "runs").mkdir(parents=True)
    whole = json.dumps({"identity": {"base": {}, "points": [], "seeds": [0]}, "spec": {}, "spec_file": str(spec)})
    record = out / "sweep.json"
    record.write_text(whole[:int(share * len(whole))])
    rc, _, err = _run(["sweep", str(spec), "--out", str(out), "--no-progress"], capfd)
    _check(rc, err, "sweep.json", out / "results.parquet", out / "spec.yaml")
    assert str(out) in err and "cut off" in err and "--restart" in err, err
    rc, _, err = _run(["sweep", "report", str(out)], capfd)
    _check(rc, err, "sweep.json", out / "results.parquet")
    assert "cut off" in err, err
    assert record.read_text() == whole[:int(share * len(whole))]  # (left for the user to look at)
