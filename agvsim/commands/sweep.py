"""agvsim sweep: a drift study over many settings, on a local process pool or on Ray.

``agvsim sweep SPEC.yaml --out DIR`` runs every point of the spec (a base drive and the axes
to vary: a grid or a seeded random sample; :mod:`agvsim.sweep.spec`) for each of its seeds,
each run the drive of ``agvsim drift``, and writes one row per point and seed to a table
(Parquet, or CSV with ``--format csv``), a summary over seeds per point and a plot of each
figure against each axis. ``agvsim sweep report DIR`` draws the table, summary and plots again
from the rows in DIR.

Each run's row is written the moment it ends, atomically. Ctrl-C stops with one line saying
what finished; the same command resumes, skipping finished runs (failed ones are tried
again); ``--restart`` starts over. A failed run is recorded with its error and the sweep goes
on.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

from agvsim.commands._args import number
from agvsim.commands._output import DistanceBar, add_json_flag, doc_help, emit_json, log, plural
from agvsim.sweep.engines import ENGINES
from agvsim.sweep.report import FORMATS
from agvsim.sweep.spec import AXES

__all__ = ["register", "run"]


def register(sub) -> None:
    axes = "; ".join(f"{a.name}: {a.help}" for a in AXES.values())
    p = sub.add_parser("sweep", help="a drift study over many settings (grid or random sample), local pool or Ray",
                       description=doc_help(__doc__) + f" Axes: {axes}.")
    p.add_argument("spec", metavar="SPEC", help="the sweep's spec (YAML), or 'report' to redraw a results folder")
    p.add_argument("folder", metavar="DIR", nargs="?", help="with 'report': the results folder")
    p.add_argument("--out", type=Path, default=None, help="results folder (default: out/sweep/<spec name>)")
    p.add_argument("--engine", choices=ENGINES, default=ENGINES[0],
                   help="where the runs execute: local (a process pool) or ray (default: %(default)s)")
    p.add_argument("--address", default=None,
                   help="--engine ray: an existing Ray cluster's head, HOST:PORT or auto (default: a local Ray)")
    p.add_argument("--workers", type=number(1, integer=True), default=None,
                   help="parallel workers, at least 1 (default: the local cores)")
    p.add_argument("--format", choices=FORMATS, default=FORMATS[0], help="table format (default: %(default)s)")
    p.add_argument("--restart", action="store_true",
                   help="start over: delete the runs an earlier sweep left in --out")
    p.add_argument("--no-plots", action="store_true", help="skip the plots")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_json_flag(p)
    p.set_defaults(func=run)


def run(args) -> int:
    """``agvsim sweep`` (a Ctrl-C at any moment: one line saying what is saved, exit 130)."""
    if args.spec == "report":
        return _report(args)
    if args.folder is not None:
        raise ValueError(f"unexpected argument {args.folder!r}: a second argument goes with 'report' only "
                         "(agvsim sweep report DIR); the results folder of a sweep is --out")
    if args.address is not None and args.engine != "ray":
        raise ValueError("--address goes with --engine ray")
    where: dict = {}
    try:
        return _run(args, where)
    except KeyboardInterrupt:
        log(f"agvsim sweep: interrupted; {_interrupted(where)}")
        return 130


def _interrupted(where: dict) -> str:
    if "out" not in where:
        return "no run had started, nothing was written"
    n, done = where["runs"], len(where["finished"])
    return (f"{done} of {n} runs finished and saved in {where['out']}; run the same command to resume "
            f"({plural(n - done, 'run')} to go)")


def _report(args) -> int:
    from agvsim.sweep.folder import SweepFolder, read_rows
    from agvsim.sweep.report import write_report

    if args.folder is None:
        raise ValueError("agvsim sweep report DIR: DIR missing (the results folder of a sweep)")
    record = SweepFolder.read_record(args.folder, "report")
    if record is None:
        raise ValueError(f"{args.folder}: no sweep.json there; expected the --out folder of an agvsim sweep")
    rows = read_rows(args.folder)
    if not rows:
        raise ValueError(f"{args.folder}: no finished runs yet (runs/ is empty)")
    files = write_report(args.folder, rows, record, args.format, plots=not args.no_plots)
    result = {"runs": len(rows), "failed": sum(r.get("status") != "ok" for r in rows.values()), **files}
    if args.json:
        emit_json(result)
    else:
        log(f"agvsim sweep report: {plural(len(rows), 'run')} -> {files['results']}, {files['summary']}, "
            f"{plural(len(files['plots']), 'plot')}")
    return 0


def _warm(workers: int) -> float:
    """Load (in a fresh install: compile) the kernels once before the workers fan out, so that
    several processes never write numba's cache at once (numba#4807). Seconds taken."""
    from agvsim.commands.warmup import compile_part, parts
    from agvsim.commands.workers import run_units

    started = time.perf_counter()
    todo = [{"name": name, "spec": spec} for name, spec in parts().items()]
    run_units(compile_part, todo, min(workers, len(todo)), lambda *r: None, lambda _: None)
    return time.perf_counter() - started


def _run(args, where: dict) -> int:
    from agvsim.sweep.engines import run_local, run_ray
    from agvsim.sweep.folder import SweepFolder, read_rows
    from agvsim.sweep.report import write_report
    from agvsim.sweep.runs import units_of
    from agvsim.sweep.spec import load_spec

    spec = load_spec(args.spec)
    out = args.out if args.out is not None else Path("out/sweep") / Path(args.spec).stem
    folder = SweepFolder(out, spec, restart=args.restart)
    n_runs = len(spec.points) * len(spec.seeds)
    done = folder.finished()
    where.update(out=out, runs=n_runs, finished=set(done))
    units = units_of(spec, todo={u["key"] for u in units_of(spec)} - set(done))
    workers = max(1, min(args.workers or (os.cpu_count() or 1), max(len(units), 1)))
    log(f"agvsim sweep: {plural(len(spec.points), 'point')} ({', '.join(spec.axes)}) x {plural(len(spec.seeds), 'seed')} "
        f"= {plural(n_runs, 'run')}, {plural(len(units), 'run')} to go, engine {args.engine}, "
        f"{plural(workers, 'worker')}; results in {out}")
    if done:
        log(f"resuming: {plural(len(done), 'run')} already finished in {out} (not run again; --restart to start over)")
    failed: list[str] = []
    total_m = sum(u["settings"].distance for u in units)
    bar = DistanceBar(total_m, disable=args.no_progress, desc="sweep")

    def finished(key: str, row: dict) -> None:
        folder.save(key, row)  # (the moment it ends: a run cut short after this keeps it)
        if row["status"] == "ok":
            where["finished"].add(key)
        else:
            failed.append(key)
            log(f"run {key} failed: {row['error']}")
        bar.bar.set_description_str(f"sweep {len(where['finished'])}/{n_runs} runs, {len(failed)} failed")

    started = time.perf_counter()
    engine: dict = {}
    warm_s = 0.0
    try:
        if units and args.engine == "ray":  # (the warm-up while Ray starts)
            engine = run_ray(units, workers, finished, bar.add, address=args.address,
                             meanwhile=lambda: _warm(workers))
        elif units:
            if workers > 1:
                warm_s = _warm(workers)
            engine = run_local(units, workers, finished, bar.add)
    except KeyboardInterrupt:
        bar.close()
        raise
    bar.finish()
    wall = time.perf_counter() - started
    files = write_report(out, read_rows(out), SweepFolder.read_record(out, "--out"), args.format, plots=not args.no_plots)
    result = {"points": len(spec.points), "seeds": len(spec.seeds), "runs": n_runs,
              "finished": len(where["finished"]) - len(done), "failed": len(failed), "skipped": len(done),
              "results": files["results"], "summary": files["summary"], "plots": files["plots"],
              "engine": args.engine, "workers": workers, "wall_time_s": wall, "warmup_s": warm_s,
              "engine_startup_s": engine.get("startup_s", 0.0), "failures": sorted(failed)}
    folder.write_json("sweep_result.json", result)
    if args.json:
        emit_json(result)
    else:
        log(f"agvsim sweep: {result['finished']} runs finished, {len(failed)} failed, {len(done)} skipped "
            f"(finished before) in {wall:.1f} s; table {files['results']}, summary {files['summary']}, "
            f"{plural(len(files['plots']), 'plot')}")
    return 1 if failed else 0
