"""agvsim drift: how well vision keeps the AGV's pose, over many seeds.

Drives a route in closed loop (pure pursuit on the EKF's estimate, camera at
its own rate, each frame rendered, localized and fused) for every seed, in
parallel on the local cores, and reports position/heading error, NEES
consistency, dead-reckoning drift, association counts, the filter's losses
(times lost, seconds lost, recoveries by re-localization) and station
arrival errors. Plots (trajectories with covariance ellipses,
error against distance with the 2σ bound) are made for the median seed.

Each seed is saved to ``--out`` the moment it finishes (atomically:
:mod:`agvsim.commands.run_folder`). Ctrl-C stops with one line saying what
finished; the same command resumes, skipping finished seeds; ``--restart``
starts over. A long run prints an estimate of its time first; its memory stays bounded
whatever the distance (the log of a long seed is thinned, its figures kept over every step:
:mod:`agvsim.loop.record`).
"""
from __future__ import annotations

import math
import os
import time
from pathlib import Path
from types import SimpleNamespace

from agvsim.commands._args import add_backend_flag, add_mount_flag, check_route, number
from localizer.numeric import check_number
from agvsim.commands._output import DistanceBar, add_json_flag, emit_json, log, plural
from agvsim.commands.capture import add_capture_flags, check_capture_flags
from agvsim.commands.run_folder import RunFolder, atomic_write
from agvsim.commands.workers import MetreReporter, run_units
from agvsim.sensors.registry import SOURCES
from agvsim.vehicle.encoders import PRESETS

DEFAULT_MAP = "plant_floor"
MAX_CAMERA_RATE = 100.0  # Hz: the physics rate (SimConfig.physics_rate); a faster camera has no new pose to see
MAX_LATENCY = 5.0  # s: capture to fusion; longer and the frames arrive after the motion they describe is long past


def register(sub) -> None:
    p = sub.add_parser("drift", help="closed-loop drift correction: EKF of odometry + target observations",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("--map", default=DEFAULT_MAP, help="map name or YAML path (default: %(default)s)")
    p.add_argument("--route", default="default", help="route name (default: %(default)s)")
    p.add_argument("--distance", type=number(0.0, low_open=True, unit="m"), default=1000.0, help="metres of route per seed (default: %(default)s)")
    p.add_argument("--seeds", type=number(1, integer=True), default=20, help="number of seeds 0..N-1 (default: %(default)s)")
    p.add_argument("--first-seed", type=number(0, integer=True), default=0, help="first seed (default: %(default)s)")
    p.add_argument("--odometry", default="typical", choices=PRESETS,
                   help="odometry error preset (default: %(default)s)")
    p.add_argument("--camera-rate", type=number(0.0, MAX_CAMERA_RATE, low_open=True, unit="Hz"), default=4.0, help="camera frames per second (default: %(default)s)")
    p.add_argument("--latency", type=number(0.0, MAX_LATENCY, unit="s"), default=0.25, help="capture-to-fusion delay, s (default: %(default)s)")
    p.add_argument("--no-vision", action="store_true", help="dead reckoning only (the contrast run)")
    add_backend_flag(p)
    p.add_argument("--observations", default="rendered", choices=SOURCES,
                   help="observation source: rendered frames + localizer, synthetic "
                        "frames + localizer, or geometric truth + noise (default: %(default)s)")
    p.add_argument("--drop-targets", type=int, default=0, metavar="N",
                   help="remove every N-th target of the map (3: one target in three; default: none)")
    p.add_argument("--false-rate", type=number(0.0), default=0.0,
                   help="geometric source only: mean false detections per frame (default: %(default)s)")
    p.add_argument("--workers", type=number(1, integer=True), default=None,
                   help="parallel worker processes, at least 1 (default: the local cores)")
    p.add_argument("--out", type=Path, default=Path("out/drift"), help="output folder (default: %(default)s)")
    p.add_argument("--no-plots", action="store_true", help="skip the plots")
    p.add_argument("--restart", action="store_true",
                   help="start over: delete the seeds an earlier run left in --out (by default the same "
                        "command resumes, skipping the seeds already finished there)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_mount_flag(p)
    add_capture_flags(p)
    add_json_flag(p)
    p.set_defaults(func=run)


def settings_of(args: dict):
    """The :class:`~agvsim.loop.drive.DriveSettings` of a drift run's settings (``base`` in
    :func:`_run`)."""
    from agvsim.loop.drive import DriveSettings

    return DriveSettings(map=args["map"], route=args["route"], distance=args["distance"], odometry=args["odometry"],
                         camera_rate=args["camera_rate"], latency=args["latency"], vision=not args["no_vision"],
                         observations=args["observations"], backend=args["backend"],
                         drop_targets=args["drop_targets"], false_rate=args["false_rate"],
                         camera_mount=args.get("camera_mount"))


def _job(args: dict):
    """One seed in a worker process: returns (seed, MissionLog). Renderer created lazily in the worker."""
    from agvsim.loop.drive import drive_seed

    progress = MetreReporter(args.get("queue"))
    record = args.get("record")
    if record is None:
        run_log = drive_seed(settings_of(args), args["seed"], progress.to)
    else:
        from agvsim.record import LoopRecorder, RunRecording

        settings = settings_of(args)
        world_map = settings.world()
        with RunRecording(seed_recording(record, args["seed"]), f"seed-{args['seed']}", world_map,
                          args.get("record_every", 1)) as rec:
            run_log = drive_seed(settings, args["seed"], progress.to, world_map, observer=LoopRecorder(rec))
    progress.finish(args["distance"])
    return args["seed"], run_log


def seed_recording(record: str | Path, seed: int) -> Path:
    """The recording of one seed of ``--record FILE.rrd``: ``FILE-seedNNN.rrd`` beside it."""
    record = Path(record)
    return record.with_name(f"{record.stem}-seed{seed:03d}{record.suffix}")


#: m of driving in all (distance x seeds) from which a run first prints an estimate of its time
ESTIMATE_FROM_M = 1000.0
#: m driven by the short drives that time it: a first (the process's one-time loads), then two
#: whose difference is the pace
CALIBRATION_M = (5.0, 10.0, 30.0)


def _estimate(base: dict, seeds: list[int], workers: int) -> str:
    """One line: about how long the run will take, from three short drives of the first seed
    here. The pace (wall seconds per metre at cruising speed) is the difference of the last two
    over the difference of their lengths, which leaves out what they share: a seed's start-up
    (its renderer) and the vehicle's start from rest; the first drive carries what a worker
    process does once (compiled code loaded)."""
    times = []
    for metres in CALIBRATION_M:
        t0 = time.perf_counter()
        _job({**base, "seed": seeds[0], "distance": metres, "queue": None})
        times.append(time.perf_counter() - t0)
    first, short, long = CALIBRATION_M
    pace = max(times[2] - times[1], 0.0) / (long - short)
    per_seed = max(times[1] - short * pace, 0.0)
    once = max(times[0] - first * pace - per_seed, 0.0)
    rounds = -(-len(seeds) // workers)  # seeds per worker, the busiest
    total = once + rounds * (per_seed + base["distance"] * pace)
    return (f"estimate: about {_duration(total)} ({pace * 1000:.0f} ms of wall time per metre per worker, "
            f"timed on short drives here; the host's load changes it)")


def _duration(seconds: float) -> str:
    """``seconds`` for a person: ``40 s``, ``3 min``, ``2.5 h``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def format_table(summary: dict, per_seed: list[dict]) -> str:
    """Per seed and all seeds: errors, consistency, and the filter's losses: ``lost`` (times it
    declared itself lost), ``lost s`` (simulated seconds spent lost), ``recov`` (recoveries:
    re-localizations)."""
    lines = [f"{'seed':>5} {'RMSE cm':>8} {'p95 cm':>7} {'max cm':>7} {'hdg RMSE deg':>13} {'NEES in':>8} "
             f"{'DR final m':>10} {'acc frames':>10} {'rej':>5} {'lost':>4} {'lost s':>7} {'recov':>5}"]

    def row(label: str, m: dict) -> str:
        return (f"{label:>5} {100 * m['position_rmse_m']:8.2f} {100 * m['position_p95_m']:7.2f} "
                f"{100 * m['position_max_m']:7.2f} {math.degrees(m['heading_rmse_rad']):13.3f} "
                f"{100 * m['nees_in_bounds']:7.1f}% {m['dead_reckoning_final_error_m']:10.3f} "
                f"{100 * m['frames_with_accepted_observation']:9.1f}% {m['rejections']:5d} "
                f"{m['lost']:4d} {m['time_lost_s']:7.1f} {m['relocalizations']:5d}")

    lines += [row(str(m["seed"]), m) for m in per_seed]
    lines.append(row("all", summary))
    return "\n".join(lines)


def _plots(world_map, run_log, out: Path, title: str) -> dict:
    import numpy as np

    from agvsim.analysis.plots import error_vs_distance
    from agvsim.analysis.topdown import TopDownView, Trajectory

    view = TopDownView(world_map)
    n = len(run_log.time)
    scale = 20.0  # ellipses magnified so centimetre covariances show
    idx = np.linspace(0, n - 1, min(n, 60)).astype(int)
    ellipses = tuple((run_log.estimate[i, :2], run_log.covariance[i, :2, :2] * scale ** 2, (40, 60, 220))
                     for i in idx)
    image = view.render((Trajectory(run_log.true_pose, (30, 150, 40), "true"),
                         Trajectory(run_log.odometry_pose, (210, 40, 40), "dead reckoning"),
                         Trajectory(run_log.estimate, (40, 60, 220), "estimated")),
                        vehicle_pose=tuple(run_log.true_pose[-1]), ellipses=ellipses,
                        ellipse_label=f"2σ position ellipse (x{scale:g})")
    with atomic_write(out / "trajectories.png") as tmp:
        TopDownView.save_png(image, tmp)
    topdown = out / "trajectories.png"
    err = np.hypot(*(run_log.estimate[:, :2] - run_log.true_pose[:, :2]).T)
    odo = np.hypot(*(run_log.odometry_pose[:, :2] - run_log.true_pose[:, :2]).T)
    bound = 2.0 * np.sqrt(np.linalg.eigvalsh(run_log.covariance[:, :2, :2])[:, -1])
    plot, plot_dr = out / "error_vs_distance.png", out / "error_vs_distance_with_dead_reckoning.png"
    with atomic_write(plot) as tmp:
        error_vs_distance(tmp, run_log.distance, {"estimate (EKF)": err}, title=title, bound=bound)
    with atomic_write(plot_dr) as tmp:
        error_vs_distance(tmp, run_log.distance, {"estimate (EKF)": err, "dead reckoning": odo}, title=title)
    return {"trajectories": str(topdown), "error_plot": str(plot), "error_plot_with_dead_reckoning": str(plot_dr)}


def _ranges(seeds: list[int]) -> str:
    """Sorted seeds as ranges: ``0-3, 5, 7-8``."""
    parts, i = [], 0
    while i < len(seeds):
        j = i
        while j + 1 < len(seeds) and seeds[j + 1] == seeds[j] + 1:
            j += 1
        parts.append(str(seeds[i]) if i == j else f"{seeds[i]}-{seeds[j]}")
        i = j + 1
    return ", ".join(parts)


def _mount_record(mount):
    """A camera mount as JSON-ready data (None: the map's)."""
    from dataclasses import asdict, is_dataclass

    return asdict(mount) if is_dataclass(mount) else (None if mount is None else repr(mount))


def run(args) -> int:
    """``agvsim drift`` (a Ctrl-C at any moment: one line saying what is saved, exit 130)."""
    where: dict = {}  # the run's folder and seeds, as far as they are known
    try:
        return _run(args, where)
    except KeyboardInterrupt:
        log(f"agvsim drift: interrupted; {_interrupted(where)}")
        return 130


def _interrupted(where: dict) -> str:
    """What a Ctrl-C leaves: nothing yet, seeds saved (the same command resumes), or every seed
    saved and the summary to write."""
    if "out" not in where:
        return "no seed had started, nothing was written"
    n, saved = len(where["seeds"]), len(where["saved"])
    if saved < n:
        return (f"{saved} of {n} seeds finished and saved in {where['out']}; run the same command to resume "
                f"({plural(n - saved, 'seed')} to go)")
    return (f"all {plural(n, 'seed')} finished and saved in {where['out']}, the summary not written: run the same "
            "command to write it (no seed is run again)")


def _checked_map(args):
    """The map the flags name, after every flag is checked (one line naming a bad one)."""
    from agvsim.sensors.rendered import RenderedSource
    from agvsim.world import load_map

    check_number("--seeds", args.seeds, low=1, integer=True)
    check_number("--distance", args.distance, low=0.0, low_open=True, unit="m")
    check_number("--camera-rate", args.camera_rate, low=0.0, low_open=True, unit="Hz")
    if args.drop_targets == 1 or args.drop_targets < 0:
        raise ValueError(f"--drop-targets must be 0 (none) or >= 2, got {args.drop_targets}")
    if args.false_rate and args.observations != "geometric":
        raise ValueError("--false-rate applies to --observations geometric only")
    world_map = load_map(args.map)
    check_route(world_map, args.route)
    if args.drop_targets:
        world_map = world_map.without_targets(args.drop_targets)
    if not args.no_vision and args.observations == "rendered" and not RenderedSource.available():
        raise ValueError("the camera renderer (agvsim.sensors.render.CameraRenderer) is not available; "
                         "use --observations synthetic (synthetic frames + localizer) or geometric")
    return world_map


def _run(args, where: dict) -> int:
    from agvsim.analysis.evaluate import floors_met, pooled, run_metrics, summarize

    check_capture_flags(args)
    world_map = _checked_map(args)
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    workers = args.workers or (os.cpu_count() or 1)
    workers = max(1, min(workers, len(seeds)))
    source = "none (dead reckoning)" if args.no_vision else args.observations
    base = {"map": args.map, "route": args.route, "distance": args.distance, "odometry": args.odometry,
            "camera_rate": args.camera_rate, "latency": args.latency, "no_vision": args.no_vision,
            "observations": args.observations, "drop_targets": args.drop_targets, "false_rate": args.false_rate,
            "camera_mount": args.camera_mount, "backend": args.backend}
    folder = RunFolder(args.out, _json_ready({**base, "camera_mount": _mount_record(args.camera_mount)}),
                       restart=args.restart)
    log(f"agvsim drift: map {world_map.name!r} ({len(world_map.targets)} targets), route {args.route!r}, "
        f"{args.distance:g} m x {plural(len(seeds), 'seed')}, odometry {args.odometry!r}, camera {args.camera_rate:g} Hz "
        f"(latency {args.latency:g} s), observations: {source}, {plural(workers, 'worker')}")
    out = folder.out
    done = folder.finished(seeds)
    where.update(out=out, seeds=seeds, saved=set(done))
    pending = [s for s in seeds if s not in done]
    if done:
        log(f"resuming: {plural(len(done), 'seed')} of {len(seeds)} already finished in {out} "
            f"({'seed' if len(done) == 1 else 'seeds'} {_ranges(sorted(done))}: not run again; --restart to start over)")
    if pending and args.distance * len(pending) >= ESTIMATE_FROM_M:
        log(_estimate(base, pending, min(workers, len(pending))))
    bar = DistanceBar(args.distance * len(seeds), disable=args.no_progress)
    bar.add(round(args.distance * len(done)))
    started = time.perf_counter()
    logs = {seed: _saved_log(vars(log_)) for seed, (_, log_) in done.items()}
    metrics = {seed: m for seed, (m, _) in done.items()}

    def finished(seed, run_log) -> None:
        # each seed is saved the moment it finishes (atomically), so a run cut short keeps it
        # and the same command resumes after it
        m = _exact_json({**run_metrics(run_log), "seed": seed})  # (as a resumed run reads it back)
        folder.save_seed(seed, m, _arrays(run_log))
        logs[seed] = _saved_log(_arrays(run_log))  # (what the summary and plots read)
        metrics[seed] = m
        where["saved"].add(seed)

    try:
        extra = {} if args.record is None else {"record": str(args.record), "record_every": args.record_every}
        run_units(_job, [{**base, **extra, "seed": s} for s in pending], workers, finished, bar.add)
    except KeyboardInterrupt:
        bar.close()  # (the bar's line ended before run() says what is saved)
        raise
    bar.finish()
    wall = time.perf_counter() - started
    per_seed = []
    for s in seeds:
        per_seed.append(metrics[s])
    summary = summarize(per_seed, pooled([logs[s] for s in seeds]))
    floors = floors_met(summary)
    order = sorted(per_seed, key=lambda m: m["position_rmse_m"])
    median = order[(len(order) - 1) // 2]["seed"]
    files = {}
    if not args.no_plots:
        files = _plots(world_map, logs[median], out,
                       f"{world_map.name}: {source}, {args.odometry} odometry, seed {median} (median)")
    result = _result(args, world_map, seeds, summary, floors, median, wall, workers, per_seed, files)
    folder.write_json("drift.json", _json_ready(result))
    if args.json:
        emit_json(result)
    else:
        _print_result(args, summary, per_seed, floors, wall, out)
    return 0


def _result(args, world_map, seeds, summary, floors, median, wall, workers, per_seed, files) -> dict:
    """What ``drift.json`` holds (SI units): the settings, the pooled summary and its floors, the
    median seed, the machine and each seed's figures."""
    import platform

    return {
        "map": world_map.name, "route": args.route, "distance_m": args.distance, "seeds": seeds,
        "odometry": args.odometry, "camera_rate_hz": args.camera_rate, "latency_s": args.latency,
        "vision": not args.no_vision, "observations": None if args.no_vision else args.observations,
        "targets": len(world_map.targets), "drop_targets": args.drop_targets,
        **summary,
        "floors": floors,
        "median_seed": median,
        "wall_time_s": wall,
        "machine": {"cpu": _cpu_name(), "cores": os.cpu_count(),
                    "python": platform.python_version(), "workers": workers},
        "per_seed": per_seed,
        "files": files,
    }


def _print_result(args, summary: dict, per_seed: list, floors: dict, wall: float, out) -> None:
    """The table and summary a person reads (centimetres and degrees only here)."""
    print(format_table(summary, per_seed))
    print(f"\nposition RMSE {100 * summary['position_rmse_m']:.2f} cm, p95 {100 * summary['position_p95_m']:.2f} cm, "
          f"max {100 * summary['position_max_m']:.2f} cm; heading RMSE "
          f"{math.degrees(summary['heading_rmse_rad']):.3f} deg; NEES in 95 % bounds "
          f"{100 * summary['nees_in_bounds']:.1f} % of steps; dead reckoning final error "
          f"{summary['dead_reckoning_final_error_m']:.3f} m ({100 * summary['dead_reckoning_drift_per_m']:.2f} % "
          f"of distance); frames with an accepted observation "
          f"{100 * summary['frames_with_accepted_observation']:.1f} %; rejections {summary['rejections']}; "
          f"lost {summary['lost']} times for {summary['time_lost_s']:.1f} s in all, recovered "
          f"{summary['relocalizations']} times (re-localizations); "
          + (f"arrival error mean {100 * summary['arrival_error_mean_m']:.1f} cm"
             if math.isfinite(summary["arrival_error_mean_m"]) else "no station reached"))
    if not args.no_vision:
        print("floors: " + ", ".join(f"{k} {'met' if v['met'] else 'NOT met'}" for k, v in floors.items()))
    print(f"wall time {wall:.1f} s; files in {out}")


def _cpu_name() -> str:
    """The CPU's model name (from /proc/cpuinfo on Linux), else the platform's machine type."""
    import platform

    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _arrays(run_log) -> dict:
    """The per-step arrays of a run worth keeping (for pooling figures over saved seeds): the
    record (every ``stride``-th step of a long run) and the totals over every step."""
    import numpy as np

    totals = run_log.step_totals.to_arrays() if run_log.step_totals is not None else {}
    return {"time": run_log.time, "distance": run_log.distance, "true_pose": run_log.true_pose,
            "odometry_pose": run_log.odometry_pose, "estimate": run_log.estimate,
            "covariance": run_log.covariance, "lost": run_log.lost, "stride": np.asarray(run_log.stride),
            **totals}


def _saved_log(arrays: dict) -> SimpleNamespace:
    """A seed's saved arrays (:func:`_arrays`) as the summary and the plots read them."""
    from agvsim.loop.log import StepTotals

    fields = {k: v for k, v in arrays.items() if not k.startswith("totals_")}
    fields["stride"] = int(fields.get("stride", 1))
    return SimpleNamespace(**fields, step_totals=StepTotals.from_arrays(arrays))


def _exact_json(obj):
    """``obj`` as JSON data with its floats to the bit (NaN and infinities as None): a seed's
    figures as saved, so that a resumed run sums the very figures an uninterrupted one does."""
    import numpy as np

    if isinstance(obj, dict):
        return {str(k): _exact_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_exact_json(v) for v in obj]
    if isinstance(obj, (np.ndarray, np.generic)):
        return _exact_json(obj.tolist())
    return None if isinstance(obj, float) and not math.isfinite(obj) else obj


def _json_ready(obj):
    from agvsim.commands._output import clean_json

    return clean_json(obj)
