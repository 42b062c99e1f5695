"""agvsim track LOG --map MAP --out DIR: the localizer and the pose filter along a logged drive.

LOG is a log folder (frames/, frames.csv, odometry.csv, optional truth.csv) or a ROS 2 bag
(a .mcap file, or a bag folder with metadata.yaml; topics named by --image-topic and
--odometry-topic). The camera file (--camera) and the vehicle file (--vehicle: track width,
ticks per metre, camera mount) default to the log folder's camera.yaml and vehicle.yaml.
Writes DIR/estimate.csv (t, x, y, theta, the covariance's six entries, status), the top-down
picture and, when the log has the truth, the error against distance.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from agvsim.commands._args import check_pose_on_map, number
from agvsim.commands._output import add_json_flag, emit_json, log, plural
from agvsim.commands.capture import check_extra
from agvsim.files import atomic_write

#: the columns of estimate.csv
ESTIMATE_COLUMNS = ("t", "x", "y", "theta", "cov_xx", "cov_xy", "cov_xtheta", "cov_yy", "cov_ytheta",
                    "cov_thetatheta", "status")


def register(sub) -> None:
    p = sub.add_parser("track", help="the localizer and filter along a logged drive (folder or ROS 2 bag)",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("log", metavar="LOG", type=Path, help="a log folder or a ROS 2 bag (.mcap, or a bag folder)")
    p.add_argument("--map", required=True, help="the plant's map (name or YAML path)")
    p.add_argument("--camera", type=Path, default=None, metavar="CALIB.yaml",
                   help="the camera's OpenCV calibration (default: LOG/camera.yaml)")
    p.add_argument("--vehicle", type=Path, default=None, metavar="VEHICLE.yaml",
                   help="the vehicle file (default: LOG/vehicle.yaml)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="where to write the estimate and pictures")
    p.add_argument("--start", nargs=3, type=number(), default=None, metavar=("X", "Y", "THETA"),
                   help="the start pose (m, m, rad; default: the log's first true pose, else unknown: the "
                        "filter localizes from the targets it sees)")
    p.add_argument("--image-topic", default="/camera/image_raw", help="bag: the camera topic (default: %(default)s)")
    p.add_argument("--odometry-topic", default="/odom", help="bag: the odometry topic (default: %(default)s)")
    p.add_argument("--truth-topic", default="/ground_truth",
                   help="bag: the true pose's topic, if it has one (default: %(default)s)")
    p.add_argument("--record", type=Path, default=None, metavar="FILE.rrd", help="also write a Rerun recording (default: none)")
    p.add_argument("--no-plots", action="store_true", help="no pictures")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_json_flag(p)
    p.set_defaults(func=run)


def _read(args):
    path = args.log
    if path.is_dir() and (path / "frames.csv").is_file():
        from agvsim.replay.folder import read_folder

        return read_folder(path)
    if path.suffix == ".mcap" or (path.is_dir() and (path / "metadata.yaml").is_file()):
        check_extra("rosbags", "a ROS 2 bag")
        from agvsim.replay.bag import read_bag

        return read_bag(path, args.image_topic, args.odometry_topic, args.truth_topic)
    raise ValueError(f"LOG {str(path)!r}: neither a log folder (frames.csv, odometry.csv) nor a ROS 2 bag "
                     "(.mcap, or a folder with metadata.yaml)")


def _setup(args, drive):
    from agvsim.replay.drive import load_vehicle
    from agvsim.replay.track import TrackSetup
    from agvsim.world import load_map
    from localizer import Camera

    folder = args.log if args.log.is_dir() else args.log.parent
    files = {}
    for flag, default in (("camera", "camera.yaml"), ("vehicle", "vehicle.yaml")):
        given = getattr(args, flag)
        files[flag] = given if given is not None else folder / default
        if not files[flag].is_file():
            raise ValueError(f"--{flag} {str(files[flag])!r}: no such file" + (
                "" if given is not None else f" (the default beside LOG; name the {flag} file with --{flag})"))
    world_map = load_map(args.map)
    camera, vehicle = Camera.from_opencv_yaml(files["camera"]), load_vehicle(files["vehicle"])
    start = None
    if args.start is not None:
        start = check_pose_on_map(world_map, args.start, "--start")
    elif drive.truth is not None:
        start = tuple(float(v) for v in drive.truth[0, 1:])
        log(f"agvsim track: starting at the log's first true pose ({start[0]:.2f} m, {start[1]:.2f} m, "
            f"{math.degrees(start[2]):.1f}°)")
    else:
        log("agvsim track: no --start and no truth in the log: the filter starts lost and localizes from the targets")
    return TrackSetup(world_map, camera, vehicle, start)


def write_estimate(path: Path, result) -> Path:
    """``estimate.csv`` (:data:`ESTIMATE_COLUMNS`), atomically."""
    with atomic_write(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(ESTIMATE_COLUMNS)
        c = result.covariance
        for k in range(len(result.time)):
            w.writerow([f"{result.time[k]:.6f}", *(f"{v:.6f}" for v in result.estimate[k]),
                        *(f"{c[k, i, j]:.9g}" for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))),
                        result.status[k]])
    return path


def _pictures(args, setup, drive, result, reckoned) -> dict:
    """The top-down picture and, with truth, the error plot; ``reckoned``: the odometry alone at
    the estimate's stamps (:func:`agvsim.replay.track.dead_reckoned`), or None."""
    from agvsim.analysis.plots import error_vs_distance
    from agvsim.analysis.topdown import TopDownView, Trajectory

    paths = [Trajectory(result.estimate, (40, 90, 220), "estimate")]
    if result.truth is not None:
        paths.insert(0, Trajectory(result.truth, (30, 150, 40), "true"))
    if reckoned is not None:
        paths.insert(0, Trajectory(reckoned[1], (210, 40, 40), "dead reckoning"))
    # (the vehicle drawn at its last true pose, which the legend says: none without truth)
    image = TopDownView(setup.world_map).render(
        tuple(paths), vehicle_pose=None if result.truth is None else tuple(result.truth[-1]))
    files = {"topdown": str(TopDownView.save_png(image, args.out / "topdown.png"))}
    errors = result.errors()
    if errors is not None:
        xy = result.truth[:, :2]
        distance = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
        bound = 2.0 * np.sqrt(np.clip(result.covariance[:, 0, 0] + result.covariance[:, 1, 1], 0, None))
        series = {"estimate": errors}
        if reckoned is not None:
            series = {"dead reckoning": np.linalg.norm(reckoned[1][:, :2] - xy, axis=1), **series}
        files["error_plot"] = str(error_vs_distance(args.out / "error_vs_distance.png", distance, series,
                                                    f"{drive.source}: position error", bound))
    return files


def _recorder(recording, drive, reckoned):
    """The ``on_frame`` of :func:`agvsim.replay.track.track` that records each frame: the image and
    what was found in it, the fusion, and the estimate beside the log's truth (when it has one)
    and its odometry alone (``reckoned``, from a known start, or None); the filter's status when
    it changes."""
    from agvsim.replay.track import truth_at

    truth = None  # (the true pose at each frame's stamp, interpolated once)
    if drive.truth is not None and len(drive.truth) > 1:
        truth = dict(zip(drive.frame_times.tolist(), truth_at(drive.truth, drive.frame_times)))
    last = [None]

    def on_frame(t, image, found, ekf, res):
        recording.frame(t, image, found)
        recording.fused(t, res.nis, res.accepted)
        poses = {"estimate": ekf.pose()}
        if truth is not None:
            poses["truth"] = tuple(truth[t])
        if reckoned is not None:
            times, reckoned_poses = reckoned
            poses["dead_reckoning"] = tuple(reckoned_poses[max(int(np.searchsorted(times, t, "right")) - 1, 0)])
        status = ekf.status
        recording.poses(t, poses, ekf.covariance(), status if status != last[0] else None)
        last[0] = status

    return on_frame


def run(args) -> int:
    from tqdm import tqdm

    from agvsim.replay.track import dead_reckoned, track

    if args.record is not None:
        check_extra("rerun", "--record")
    drive = _read(args)
    setup = _setup(args, drive)
    for note in drive.notes:
        log(f"agvsim track: {note}")
    args.out.mkdir(parents=True, exist_ok=True)
    bar = tqdm(total=len(drive.frame_times), unit="frame", disable=args.no_progress, desc="track", leave=False)
    on_frame, recording = None, None
    reckoned = dead_reckoned(drive, setup)  # (the odometry alone, at the estimate's stamps)
    if args.record is not None:
        from agvsim.record import RunRecording

        recording = RunRecording(args.record, "track", setup.world_map)
        on_frame = _recorder(recording, drive, reckoned)
    try:
        result = track(drive, setup, progress=lambda k: bar.update(k - bar.n), on_frame=on_frame)
    finally:
        bar.close()
        if recording is not None:
            recording.close()
    for note in result.notes[len(drive.notes):]:
        log(f"agvsim track: {note}")
    if result.interrupted:
        if not len(result.time):
            log("agvsim track: interrupted before the first odometry stamp: nothing written")
            return 130
        path = write_estimate(args.out / "estimate.csv", result)
        log(f"agvsim track: interrupted after {plural(result.frames_used, 'frame')}: wrote the estimate up to "
            f"t = {result.time[-1]:.2f} s to {path}" + (f" and the recording to {args.record}" if recording else ""))
        return 130
    files = {"estimate": str(write_estimate(args.out / "estimate.csv", result))}
    if not args.no_plots:
        files.update(_pictures(args, setup, drive, result, reckoned))
    summary = {**result.summary(), "files": files}
    if args.json:
        emit_json(summary)
        return 0
    rmse = summary["position_rmse_m"]
    print(f"agvsim track: {plural(result.frames_used, 'frame')} used, {result.frames_refused} refused, "
          f"{plural(result.targets_fused, 'observation')} fused of {result.targets_seen}; "
          f"{plural(result.lost_events, 'lost event')}"
          + (f"; position error RMSE {100 * rmse:.1f} cm, max {100 * summary['position_max_m']:.1f} cm"
             if rmse is not None else "; no truth in the log"))
    print(f"Wrote the estimate to {files['estimate']}")
    return 0
