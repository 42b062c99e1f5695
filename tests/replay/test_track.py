"""A drive written as a log (folder and ROS 2 bag) and tracked back, its recording, and the
messy logs a real vehicle leaves: each one line, never a traceback."""
from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from agvsim.cli import main

pytest.importorskip("rerun")
pytest.importorskip("rosbags")


def _run(argv, capfd):
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    out, err = capfd.readouterr()
    return rc, out, err


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """The demo on the corridor, its drive exported in both formats and recorded."""
    root = tmp_path_factory.mktemp("drive")
    argv = ["demo", "--map", "corridor", "--out", str(root / "demo"), "--frames", "0", "--no-progress", "--json",
            "--export-log", str(root / "log"), "--export-bag", str(root / "bag" / "drive.mcap"),
            "--record", str(root / "run.rrd")]
    rc = main(argv)
    assert rc == 0
    return root


def _track(capfd, log, out, *extra):
    rc, text, err = _run(["track", str(log), "--map", "corridor", "--out", str(out), "--no-progress", "--json",
                          *extra], capfd)
    assert rc == 0, err
    return json.loads(text)


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["log", "bag"])
def test_a_tracked_export_reproduces_the_closed_loop(drive, tmp_path, capfd, fmt):
    log = drive / "log" if fmt == "log" else drive / "bag" / "drive.mcap"
    summary = _track(capfd, log, tmp_path / "track")
    assert summary["position_rmse_m"] <= 0.02 and summary["position_max_m"] <= 0.10, summary
    assert summary["frames_refused"] == 0 and summary["frames_used"] > 100 and summary["lost_events"] == 0
    with open(tmp_path / "track" / "estimate.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0][:4] == ["t", "x", "y", "theta"] and rows[0][-1] == "status" and len(rows) > 500
    assert (tmp_path / "track" / "topdown.png").is_file() and (tmp_path / "track" / "error_vs_distance.png").is_file()


@pytest.mark.slow
def test_the_two_formats_give_one_estimate(drive, tmp_path, capfd):
    a = _track(capfd, drive / "log", tmp_path / "a")
    b = _track(capfd, drive / "bag" / "drive.mcap", tmp_path / "b")
    assert a["position_rmse_m"] == pytest.approx(b["position_rmse_m"], rel=1e-9)
    ea = np.loadtxt(tmp_path / "a" / "estimate.csv", delimiter=",", skiprows=1, usecols=(0, 1, 2, 3))
    eb = np.loadtxt(tmp_path / "b" / "estimate.csv", delimiter=",", skiprows=1, usecols=(0, 1, 2, 3))
    np.testing.assert_allclose(ea, eb, atol=2e-6)


@pytest.mark.slow
def test_without_truth_the_figures_are_null(drive, tmp_path, capfd):
    log = tmp_path / "log"
    shutil.copytree(drive / "log", log)
    (log / "truth.csv").unlink()
    first = np.loadtxt(drive / "log" / "truth.csv", delimiter=",", skiprows=1, max_rows=1)
    summary = _track(capfd, log, tmp_path / "track", "--start", *(repr(float(v)) for v in first[1:]))
    assert summary["position_rmse_m"] is None and summary["position_max_m"] is None
    assert not (tmp_path / "track" / "error_vs_distance.png").exists()


@pytest.mark.slow
def test_the_recording_holds_every_entity_path_on_sim_time(drive):
    from rerun.chunk import RrdReader

    from agvsim.record import ENTITY_PATHS, TIMELINE

    reader = RrdReader(str(drive / "run.rrd"))
    (entry,) = reader.recordings()
    assert entry.recording_id == "seed-0"
    paths, timed = set(), set()
    for chunk in reader.stream():
        path = str(chunk.entity_path).lstrip("/")
        paths.add(path)
        if TIMELINE in chunk.timeline_names:
            timed.add(path)
    for path in ENTITY_PATHS:
        if "<" in path:
            assert any(p.startswith("world/estimate/trail/") for p in paths), sorted(paths)
        else:
            assert path in paths, (path, sorted(paths))
    assert {"world/truth", "world/estimate", "camera/image", "metrics/position_error"} <= timed


@pytest.mark.slow
def test_a_tracked_log_recording_holds_truth_dead_reckoning_and_the_error(drive, tmp_path, capfd):
    from rerun.chunk import RrdReader

    _track(capfd, drive / "log", tmp_path / "track", "--record", str(tmp_path / "track.rrd"), "--no-plots")
    rows: dict[str, int] = {}
    for chunk in RrdReader(str(tmp_path / "track.rrd")).stream():
        path = str(chunk.entity_path).lstrip("/")
        rows[path] = rows.get(path, 0) + chunk.num_rows
    frames = rows["camera/image"]
    assert frames > 100
    for path in ("world/truth", "world/dead_reckoning", "world/estimate", "metrics/position_error",
                 "camera/detections", "metrics/nis"):
        assert rows.get(path) == frames, (path, rows)
    assert rows["filter/status"] < frames  # (said when it changes)


@pytest.mark.slow
def test_ctrl_c_keeps_the_estimate_and_the_recording_so_far(drive, tmp_path, capfd, monkeypatch, python_sigint):
    import os
    import signal

    import localizer
    from rerun.chunk import RrdReader

    real, calls = localizer.detect_targets, []

    def signalled(image, *args, **kw):
        calls.append(1)
        if len(calls) == 40:
            os.kill(os.getpid(), signal.SIGINT)
        return real(image, *args, **kw)

    monkeypatch.setattr(localizer, "detect_targets", signalled)
    rc, _, err = _run(["track", str(drive / "log"), "--map", "corridor", "--out", str(tmp_path / "t"), "--no-progress",
                       "--record", str(tmp_path / "t.rrd")], capfd)
    # (the signal is held back to the end of the 40th frame's search, which is then not fused)
    assert rc == 130 and "interrupted after 39 frames: wrote the estimate up to t = " in err, err
    rows = np.loadtxt(tmp_path / "t" / "estimate.csv", delimiter=",", skiprows=1, usecols=(0, 1, 2, 3))
    frames = np.loadtxt(drive / "log" / "frames.csv", delimiter=",", skiprows=1, usecols=(0,))
    assert len(rows) > 40 and rows[-1, 0] <= frames[39] + 1e-6 and np.isfinite(rows).all()
    images = sum(c.num_rows for c in RrdReader(str(tmp_path / "t.rrd")).stream()
                 if str(c.entity_path) == "/camera/image")
    assert images == 39


# ------------------------------------------------------------------ messy logs
def _copy(drive, tmp_path) -> Path:
    log = tmp_path / "log"
    shutil.copytree(drive / "log", log)
    return log


def _rewrite(path: Path, edit) -> None:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    with open(path, "w", newline="") as f:
        csv.writer(f).writerows(edit(rows))


@pytest.mark.slow
def test_duplicated_and_out_of_order_stamps_are_said_and_sorted(drive, tmp_path, capfd):
    log = _copy(drive, tmp_path)
    _rewrite(log / "frames.csv", lambda r: [r[0], r[2], r[1], r[3], r[3]] + r[4:])
    rc, out, err = _run(["track", str(log), "--map", "corridor", "--out", str(tmp_path / "t"), "--no-progress"], capfd)
    assert rc == 0 and "Traceback" not in err
    assert "out of order" in err and "duplicated stamp" in err, err


@pytest.mark.slow
def test_missing_and_wrong_size_frames_are_refused_and_counted(drive, tmp_path, capfd):
    log = _copy(drive, tmp_path)
    (log / "frames" / "000003.png").unlink()
    cv2.imwrite(str(log / "frames" / "000005.png"), np.zeros((100, 120), np.uint8))
    summary = _track(capfd, log, tmp_path / "t")
    assert summary["frames_refused"] == 2
    notes = " ".join(summary["notes"])
    assert "000003.png" in notes and "120 x 100 px" in notes, notes


@pytest.mark.parametrize("share", [0.3, 0.6, 0.9])
@pytest.mark.parametrize("name", ["odometry.csv", "frames.csv", "truth.csv", "vehicle.yaml"])
def test_a_cut_off_file_is_one_line(drive, tmp_path, capfd, name, share):
    log = _copy(drive, tmp_path)
    data = (log / name).read_bytes()
    cut = data[:int(share * len(data))]
    if name.endswith(".csv"):
        cut = cut.rstrip(b"\n").rsplit(b",", 1)[0]  # (the last row ends inside a value)
    else:
        cut = cut.rstrip(b"\n").rsplit(b":", 1)[0]  # (inside a key)
    (log / name).write_bytes(cut)
    rc, _, err = _run(["track", str(log), "--map", "corridor", "--out", str(tmp_path / "t"), "--no-progress"], capfd)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and "Traceback" not in err, err
    assert len(lines) == 1 and name in lines[0], err
    assert not (tmp_path / "t" / "estimate.csv").exists()


@pytest.mark.slow
def test_a_bag_without_the_topic_names_what_it_has(drive, tmp_path, capfd):
    rc, _, err = _run(["track", str(drive / "bag" / "drive.mcap"), "--map", "corridor", "--out", str(tmp_path / "t"),
                       "--image-topic", "/front/image", "--no-progress"], capfd)
    assert rc == 2 and "Traceback" not in err
    assert "'/front/image'" in err and "/camera/image_raw (sensor_msgs/msg/Image)" in err, err


@pytest.mark.slow
def test_a_cut_off_bag_is_one_line(drive, tmp_path, capfd):
    bag = tmp_path / "cut.mcap"
    data = (drive / "bag" / "drive.mcap").read_bytes()
    bag.write_bytes(data[:len(data) // 2])
    shutil.copy(drive / "bag" / "vehicle.yaml", tmp_path)
    shutil.copy(drive / "bag" / "camera.yaml", tmp_path)
    rc, _, err = _run(["track", str(bag), "--map", "corridor", "--out", str(tmp_path / "t"), "--no-progress"], capfd)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc != 0 and "Traceback" not in err, err
    assert str(bag) in lines[-1], err


def test_an_export_into_a_log_folder_is_refused(tmp_path):
    from agvsim.replay.folder import FolderWriter

    (tmp_path / "frames.csv").write_text("t,file\n")
    with pytest.raises(ValueError, match="holds a logged drive already"):
        FolderWriter(tmp_path)


@pytest.mark.slow
def test_a_sqlite3_bag_of_compressed_frames_and_wheel_joints(drive, tmp_path, capfd):
    """The other message types: CompressedImage frames and JointState wheel positions (ticks), in
    a sqlite3 bag, made here from the exported folder's first 30 s."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    from agvsim.replay.drive import load_vehicle

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    log = drive / "log"
    vehicle = load_vehicle(log / "vehicle.yaml")
    per_metre = 1.0 / 0.1  # wheel angle (rad) per metre of a 0.1 m wheel
    odo = np.loadtxt(log / "odometry.csv", delimiter=",", skiprows=1)
    odo = odo[odo[:, 0] <= 30.0]
    dt = np.diff(odo[:, 0], prepend=odo[0, 0])
    left = np.cumsum((odo[:, 1] - 0.5 * vehicle.track_width * odo[:, 2]) * dt) * per_metre
    right = np.cumsum((odo[:, 1] + 0.5 * vehicle.track_width * odo[:, 2]) * dt) * per_metre
    truth = np.loadtxt(log / "truth.csv", delimiter=",", skiprows=1)
    with open(log / "frames.csv", newline="") as f:
        frames = [(float(t), name) for t, name in list(csv.reader(f))[1:] if float(t) <= 30.0]

    def header(t):
        ns = int(round(t * 1e9))
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9),
                                        frame_id="x"), ns

    bag = tmp_path / "bag"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        cams = w.add_connection("/front/compressed", "sensor_msgs/msg/CompressedImage", typestore=ts)
        wheels = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
        gt = w.add_connection("/ground_truth", "nav_msgs/msg/Odometry", typestore=ts)
        for t, name in frames:
            h, ns = header(t)
            png = np.frombuffer(cv2.imencode(".png", cv2.imread(str(log / "frames" / name), cv2.IMREAD_UNCHANGED))[1],
                                np.uint8)
            msg = T["sensor_msgs/msg/CompressedImage"](header=h, format="png", data=png)
            w.write(cams, ns, ts.serialize_cdr(msg, msg.__msgtype__))
        for k in range(len(odo)):
            h, ns = header(odo[k, 0])
            msg = T["sensor_msgs/msg/JointState"](header=h, name=["wheel_left_joint", "wheel_right_joint"],
                                                  position=np.array([left[k], right[k]]), velocity=np.zeros(2),
                                                  effort=np.zeros(2))
            w.write(wheels, ns, ts.serialize_cdr(msg, msg.__msgtype__))
        for row in truth[truth[:, 0] <= 30.0]:
            h, ns = header(row[0])
            q = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=float(np.sin(row[3] / 2)), w=float(np.cos(row[3] / 2)))
            pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=row[1], y=row[2], z=0.0),
                                               orientation=q)
            zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
            msg = T["nav_msgs/msg/Odometry"](
                header=h, child_frame_id="base", pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero),
                                                                 covariance=np.zeros(36)))
            w.write(gt, ns, ts.serialize_cdr(msg, msg.__msgtype__))
    ticks = tmp_path / "vehicle.yaml"
    from dataclasses import replace

    replace(vehicle, ticks_per_metre=per_metre).to_yaml(ticks)
    summary = _track(capfd, bag, tmp_path / "t", "--camera", str(log / "camera.yaml"), "--vehicle", str(ticks),
                     "--image-topic", "/front/compressed", "--odometry-topic", "/joint_states")
    assert summary["frames_used"] == len(frames) and summary["frames_refused"] == 0
    assert summary["position_rmse_m"] <= 0.02 and summary["position_max_m"] <= 0.10, summary
