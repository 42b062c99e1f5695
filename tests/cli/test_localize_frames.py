"""``agvsim localize`` over a video file or a folder of frames: one row per frame and target (CSV,
JSON lines), the same numbers as the detector run on the same frames, failed frames recorded
without stopping the run, annotated videos and folders, frame sizes against the camera, Ctrl-C."""
from __future__ import annotations

import csv
import io
import json
import math
import os
import signal
import subprocess
import sys
import time

import cv2
import numpy as np
import pytest

from agvsim.cli import main
from agvsim.commands.frame_rows import COLUMNS
from localizer import Camera, detect_targets
from localizer.image.io import read_image_grey
from localizer.tools.synthetic import pose_at_column, render_frame

CAM = Camera.thesis(16.0)
FPS = 10.0
#: (distance m, alpha deg, image column) of each frame's targets; an empty frame has none
SCENES = [[(2.4, -20, 150)], [(2.7, -10, 220)], [], [(3.0, 0, 256), (2.2, 15, 420)], [(3.3, 10, 300)],
          [(3.6, 20, 330)], [(2.9, 25, 360)], [(2.5, -25, 120)]]


def _frames(camera=CAM, scenes=SCENES):
    out = []
    for i, scene in enumerate(scenes):
        poses = [pose_at_column(camera, d, math.radians(a), x, 0.05) for d, a, x in scene]
        out.append(render_frame(camera, poses, noise=1.0, rng=np.random.default_rng(i)))
    return out


def _write_video(path, frames, fps=FPS, fourcc="MJPG"):
    h, w = frames[0].shape
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, (w, h), True)
    assert writer.isOpened()
    for f in frames:
        writer.write(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR))
    writer.release()
    return path


def _decoded(path):
    """The video's frames as OpenCV decodes them, in grey (what the command localizes)."""
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, f = cap.read()
        if not ok:
            return out
        out.append(cv2.cvtColor(f, cv2.COLOR_BGR2GRAY))


def _run(argv, capsys):
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    out, err = capsys.readouterr()
    return rc, out, err


def _csv_rows(text):
    rows = list(csv.DictReader(io.StringIO(text)))
    assert rows == [] or tuple(rows[0]) == COLUMNS
    return rows


def _assert_rows_match(rows, expected):
    """``rows`` (dicts of strings or numbers) hold exactly ``expected``: {frame: [observations]}."""
    targets = [r for r in rows if not r["error"]]
    assert len(targets) == sum(len(v) for v in expected.values())
    for r in targets:
        o = expected[int(r["frame"])][int(r["target"]) - 1]
        for key, value in (("d_m", o.distance), ("beta_rad", o.beta), ("alpha_rad", o.alpha),
                           ("sigma_d_m", o.sigma[0]), ("sigma_beta_rad", o.sigma[1]), ("sigma_alpha_rad", o.sigma[2])):
            assert float(r[key]) == pytest.approx(value, rel=1e-11, abs=1e-15), key  # (12 digits written)
        assert r["polarity"] == o.polarity


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    return _write_video(tmp_path_factory.mktemp("video") / "run.avi", _frames())


@pytest.fixture()
def folder(tmp_path):
    d = tmp_path / "frames"
    d.mkdir()
    for i, f in enumerate(_frames()):
        cv2.imwrite(str(d / f"frame_{i}.png"), f)
    return d


def test_video_rows_as_csv_are_the_detectors_on_the_decoded_frames(video, tmp_path, capsys):
    out = tmp_path / "rows.csv"
    rc, stdout, err = _run(["localize", str(video), "--out", str(out), "--no-progress"], capsys)
    assert rc == 0, err
    rows = _csv_rows(out.read_text())
    decoded = _decoded(video)
    assert len(decoded) == len(SCENES)
    expected = {i: detect_targets(f, CAM) for i, f in enumerate(decoded)}
    assert [len(v) for v in expected.values()] == [len(s) for s in SCENES]  # (the scenes are found)
    _assert_rows_match(rows, expected)
    assert {int(r["frame"]) for r in rows} == {i for i, s in enumerate(SCENES) if s}  # no row for an empty frame
    for r in rows:
        assert float(r["time_s"]) == pytest.approx(int(r["frame"]) / FPS, abs=1e-9)
        assert r["source"] == str(video)
    # SI units, near the truth (MJPG's loss aside)
    two = sorted((float(r["d_m"]), float(r["alpha_rad"])) for r in rows if r["frame"] == "3")
    assert [round(d, 1) for d, _ in two] == [2.2, 3.0]
    assert abs(two[0][1] - math.radians(15)) < math.radians(1.5) and abs(two[1][1]) < math.radians(1.5)
    assert f"{len(SCENES)} frames: {len(SCENES)} read, 0 failed, 7 with targets (8 targets)" in err
    assert stdout == ""


def test_folder_rows_as_jsonl_in_name_order_with_failed_and_skipped_files(folder, tmp_path, capsys):
    (folder / "notes.txt").write_text("not a frame\n")
    (folder / "frame_10.png").write_text("not a PNG either\n")  # after frame_7 (numbers compared as numbers)
    cv2.imwrite(str(folder / "frame_11.png"), np.zeros((240, 320), np.uint8))  # the wrong size
    out = tmp_path / "out" / "rows.jsonl"
    rc, stdout, err = _run(["localize", str(folder), "--out", str(out), "--fps", "5", "--json", "--no-progress"],
                           capsys)
    assert rc == 2  # frames failed
    summary = json.loads(stdout)
    assert (summary["frames"], summary["read"], summary["failed"], summary["with_targets"]) == (10, 8, 2, 7)
    assert summary["inputs"][0]["skipped"] == 1 and "1 entry skipped" in err
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert all(tuple(r) == COLUMNS for r in rows) and summary["rows"] == len(rows)
    errors = {r["frame"]: r for r in rows if r["error"]}
    assert sorted(errors) == [8, 9] and errors[8]["source"].endswith("frame_10.png")
    assert "expected one of PNG" in errors[8]["error"] and errors[8]["d_m"] is None
    assert "320x240" in errors[9]["error"] and "512x480" in errors[9]["error"]
    files = [folder / f"frame_{i}.png" for i in range(len(SCENES))]
    _assert_rows_match(rows, {i: detect_targets(read_image_grey(p), CAM) for i, p in enumerate(files)})
    assert all(r["time_s"] == pytest.approx(r["frame"] / 5.0) for r in rows)
    assert all(r["source"] == str(files[r["frame"]]) for r in rows if not r["error"])


def test_many_failed_frames_are_told_ten_times_and_all_written(tmp_path, capsys):
    d = tmp_path / "small"
    d.mkdir()
    for i in range(13):
        cv2.imwrite(str(d / f"f{i:02d}.png"), np.full((240, 320), 128, np.uint8))
    rc, stdout, err = _run(["localize", str(d), "--format", "csv", "--no-progress"], capsys)
    rows = _csv_rows(stdout)
    assert rc == 2 and [r["frame"] for r in rows] == [str(i) for i in range(13)] and all(r["error"] for r in rows)
    lines = err.strip().splitlines()
    assert sum("error:" in ln for ln in lines) == 10 and "further failed frames are counted" in lines[10]
    assert lines[-1].endswith("13 frames: 0 read, 13 failed, 0 with targets (0 targets)")


def test_a_frame_the_decoder_cannot_read_and_a_video_cut_short_are_failed_frames(tmp_path, capsys):
    good = _write_video(tmp_path / "good.avi", _frames())
    data = bytearray(good.read_bytes())
    starts = [i for i in range(len(data) - 2) if data[i:i + 3] == b"\xff\xd8\xff"]  # each frame's JPEG
    assert len(starts) == len(SCENES)
    broken = bytearray(data)
    broken[starts[1]:starts[1] + 2000] = bytes(2000)  # frame 1's JPEG header and more
    (tmp_path / "broken.avi").write_bytes(broken)
    (tmp_path / "short.avi").write_bytes(data[:starts[6] - 8])  # frames 6 and 7 cut off (at 6's chunk header)
    rc, stdout, err = _run(["localize", str(tmp_path / "broken.avi"), str(tmp_path / "short.avi"), "--format",
                            "csv", "--no-progress"], capsys)
    assert rc == 2 and "Traceback" not in err
    rows = _csv_rows(stdout)
    broken_rows = [r for r in rows if r["source"].endswith("broken.avi")]
    failed = [r for r in broken_rows if r["error"]]
    assert [r["frame"] for r in failed] == ["1"] and "could not read" in failed[0]["error"]
    assert {int(r["frame"]) for r in broken_rows if not r["error"]} == {i for i, s in enumerate(SCENES) if s} - {1}
    short = [r for r in rows if r["source"].endswith("short.avi")]
    assert [r["frame"] for r in short if r["error"]] == ["6"]
    assert "2 missing or unreadable" in [r for r in short if r["error"]][0]["error"]
    assert max(int(r["frame"]) for r in short if not r["error"]) == 5
    assert "16 frames: 13 read, 3 failed" in err


def test_an_exception_in_the_detector_fails_that_frame_only(video, tmp_path, capsys, monkeypatch):
    import localizer

    real, calls = localizer.detect_targets, []

    def flaky(image, *args, **kw):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("boom\non two lines")
        return real(image, *args, **kw)

    monkeypatch.setattr(localizer, "detect_targets", flaky)
    ann = tmp_path / "ann.avi"
    rc, stdout, err = _run(["localize", str(video), "--format", "jsonl", "--annotate", str(ann), "--no-progress"],
                           capsys)
    assert rc == 2
    rows = [json.loads(line) for line in stdout.splitlines()]
    failed = [r for r in rows if r["error"]]
    assert len(failed) == 1 and failed[0]["frame"] == 1
    assert failed[0]["error"].endswith("the detector failed (RuntimeError: boom on two lines)")
    assert len(rows) - 1 == sum(len(s) for s in SCENES) - 1  # frame 1's target missing, the rest there
    assert "1 failed" in err
    assert len(_decoded(ann)) == len(SCENES)  # the failed frame is in the annotated video, unmarked


def test_annotate_a_video_and_a_folder(video, folder, tmp_path, capsys):
    ann = tmp_path / "ann" / "run_annotated.avi"
    rc, _, err = _run(["localize", str(video), "--annotate", str(ann), "--no-progress"], capsys)
    assert rc == 0, err
    frames = []
    cap = cv2.VideoCapture(str(ann))
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(FPS)
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    assert len(frames) == len(SCENES) and frames[0].shape == (480, 512, 3)
    marked = [int((np.abs(f[:, :, 1].astype(int) - f[:, :, 0]) > 80).sum()) for f in frames]  # green, red, yellow
    assert [m > 200 for m in marked] == [bool(s) for s in SCENES]  # marks where targets are, none elsewhere
    out = tmp_path / "ann_frames"
    rc, _, err = _run(["localize", str(folder), "--annotate", str(out), "--fps", "10", "--no-progress"], capsys)
    assert rc == 0, err
    assert sorted(p.name for p in out.iterdir()) == sorted(f"frame_{i}.png" for i in range(len(SCENES)))
    img = cv2.imread(str(out / "frame_3.png"))
    assert img.shape == (480, 512, 3) and (img[:, :, 1].astype(int) - img[:, :, 0] > 80).sum() > 200


def test_the_table_and_json_list_every_frame(video, folder, capsys):
    rc, out, err = _run(["localize", str(video)], capsys)
    assert rc == 0 and f"/{len(SCENES)} [" in err and "frame/s" in err  # the progress bar, on stderr
    lines = out.splitlines()
    assert lines[0].startswith("image") and len(lines) == 1 + 1 + sum(len(s) for s in SCENES)  # + empty frame
    assert f"{video}#2"[-28:] in out and "no target" in out and "positive" in out
    rc, out, _ = _run(["localize", str(folder), "--fps", "4", "--json"], capsys)
    data = json.loads(out)
    assert rc == 0 and data["ok"] and [r["frame"] for r in data["results"]] == list(range(len(SCENES)))
    assert data["results"][4]["time_s"] == 1.0 and len(data["results"][3]["targets"]) == 2
    assert data["summary"]["with_targets"] == 7


def test_a_video_of_another_size_is_one_line_before_any_work_and_a_calibration_of_its_size_works(tmp_path,
                                                                                                   capsys):
    cam = Camera.from_intrinsics(400.0, 400.0, 159.5, 119.5, 320, 240)
    small = _write_video(tmp_path / "small.avi", _frames(cam, [[(2.0, 10, 160)], [(2.2, -10, 140)]]))
    out = tmp_path / "rows.csv"
    rc, stdout, err = _run(["localize", str(small), "--out", str(out)], capsys)
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err
    assert str(small) in lines[0] and "320x240" in lines[0] and "512x480" in lines[0] and "--camera" in lines[0]
    assert not out.exists() and stdout == ""
    cam.to_opencv_yaml(tmp_path / "calib.yaml")
    rc, _, err = _run(["localize", str(small), "--camera", str(tmp_path / "calib.yaml"), "--out", str(out),
                       "--no-progress"], capsys)
    assert rc == 0, err
    rows = _csv_rows(out.read_text())
    assert [round(float(r["d_m"]), 1) for r in rows] == [2.0, 2.2]


@pytest.mark.parametrize("argv, needles", [
    (["notes.txt", "--out", "rows.csv"], ["notes.txt", "not an image file", "a folder of frames", ".mp4"]),
    (["missing.avi", "--out", "rows.csv"], ["missing.avi", "no such file"]),
    (["VIDEO", "--out", "rows.txt"], ["--out", "rows.txt", ".csv or .jsonl"]),
    (["VIDEO", "--format", "csv", "--json"], ["--json", "--format", "--out FILE"]),
    (["VIDEO", "VIDEO", "--annotate", "a.avi"], ["--annotate", "that one input", "got 2"]),
    (["VIDEO", "--annotate", "a.png"], ["--annotate", "a.png", "video file name", ".avi"]),
    (["VIDEO", "--out", "rows.csv", "--annotate", "a.png"], ["--annotate", "a.png", "video file name"]),
    (["VIDEO", "--fps", "0"], ["--fps", "> 0 (Hz)"]),
    (["VIDEO", "--annotate", "VIDEO"], ["--annotate", "the input itself"]),
    (["FOLDER", "--annotate", "FOLDER/"], ["--annotate", "the input itself"]),
])
def test_bad_input_is_one_line_and_nothing_written(argv, needles, video, folder, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "notes.txt").write_text("hello\n")
    frames = sorted(p.name for p in folder.iterdir())
    argv = [a.replace("VIDEO", str(video)).replace("FOLDER", folder.name) for a in argv]
    rc, out, err = _run(["localize"] + argv, capsys)
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err and out == "", err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == [folder.name, "notes.txt"]
    assert sorted(p.name for p in folder.iterdir()) == frames


def test_ctrl_c_keeps_the_rows_of_the_frames_done(video, tmp_path, capsys, monkeypatch):
    import localizer

    real, calls = localizer.detect_targets, []

    def interrupted(image, *args, **kw):
        calls.append(1)
        if len(calls) == 5:
            raise KeyboardInterrupt
        return real(image, *args, **kw)

    monkeypatch.setattr(localizer, "detect_targets", interrupted)
    out = tmp_path / "rows.csv"
    rc, _, err = _run(["localize", str(video), "--out", str(out), "--no-progress"], capsys)
    assert rc == 130
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "interrupted after 4 frames" in lines[0] and "rows in" in lines[0]
    rows = _csv_rows(out.read_text())
    assert [r["frame"] for r in rows] == ["0", "1", "3", "3"]  # frames 0-3 whole (frame 2 has no target)
    assert f"the {len(rows)} rows in {out} are complete" in lines[0]
    calls.clear()  # the table: printed frame by frame, so the frames done are there
    rc, table, err = _run(["localize", str(video), "--no-progress"], capsys)
    assert rc == 130 and "interrupted after 4 frames" in err
    assert [ln.split()[0][-2:] for ln in table.splitlines()[1:]] == ["#0", "#1", "#2", "#3", "#3"]


@pytest.mark.skipif(not hasattr(signal, "pthread_sigmask"), reason="SIGINT held back by the thread's signal mask")
def test_a_ctrl_c_while_a_frame_is_localized_stops_the_run_after_that_frame(video, tmp_path, capsys, monkeypatch,
                                                                            python_sigint):
    # the signal, not an exception: held back until the frame is written, so that no KeyboardInterrupt
    # is raised inside a compiled call (numba returns a kernel's results through Python code, where one
    # crashed the interpreter: test_ctrl_c_on_a_long_video_leaves_whole_lines, 1 run in ~40)
    import localizer

    real, calls = localizer.detect_targets, []

    def signalled(image, *args, **kw):
        calls.append(1)
        if len(calls) == 3:
            os.kill(os.getpid(), signal.SIGINT)
            sum(range(1000))  # (Python code after the signal: a KeyboardInterrupt would be raised here)
        return real(image, *args, **kw)

    monkeypatch.setattr(localizer, "detect_targets", signalled)
    out = tmp_path / "rows.csv"
    rc, _, err = _run(["localize", str(video), "--out", str(out), "--no-progress"], capsys)
    assert rc == 130 and "interrupted after 3 frames" in err, err
    assert [r["frame"] for r in _csv_rows(out.read_text())] == ["0", "1"]  # frames 0-2 whole (2 has no target)


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals as a terminal sends them")
def test_ctrl_c_on_a_long_video_leaves_whole_lines(tmp_path):
    frames = _frames()
    long = _write_video(tmp_path / "long.avi", [frames[i % len(frames)] for i in range(1600)], fps=25.0)
    out = tmp_path / "rows.csv"
    p = subprocess.Popen([sys.executable, "-m", "agvsim", "localize", str(long), "--out", str(out), "--annotate",
                          str(tmp_path / "ann.mp4")], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    t0 = time.time()
    while not out.exists() or out.read_text().count("\n") < 30:
        assert p.poll() is None, p.communicate()
        assert time.time() - t0 < 120
        time.sleep(0.02)
    os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and "Traceback" not in err, err
    told = [ln for ln in err.replace("\r", "\n").splitlines() if "interrupted" in ln]
    assert len(told) == 1
    assert out.read_bytes().endswith(b"\r\n")
    text = out.read_text()
    rows = _csv_rows(text)
    assert all(len(r) == len(COLUMNS) and None not in r.values() for r in rows)
    done = int(told[0].split("interrupted after ")[1].split()[0])
    assert done < 1600 and f"the {len(rows)} rows" in told[0]
    assert len(rows) == sum(len(SCENES[i % len(SCENES)]) for i in range(done))
    assert len(_decoded(tmp_path / "ann.mp4")) == done  # the annotated video is whole, up to there
