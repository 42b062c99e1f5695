"""``agvsim warmup``: compile the numba kernels for this machine ahead of their first use.

The localizer's and the raycaster's kernels are compiled the first time they are called and
cached on disk (beside the modules, or in the user's cache directory, ``~/.cache/numba``, when
the package's directory cannot be written); every later process loads them in about a second.
In a fresh install that first call waits: this command does it ahead, in parallel processes
(a part that calls another's kernels starts once that one has cached them), for an installer (``make install`` runs it), a container build or a new worker node. Once
the kernels are cached it finishes in seconds. Interrupted, it keeps what it compiled.
"""
from __future__ import annotations

import os
import time

from agvsim.commands._args import number
from agvsim.commands._output import add_json_flag, doc_help, emit_json, log, plural

#: the simulator's parts to compile, by name: ``"module:function"``
PARTS: dict[str, str] = {"raycaster": "agvsim.sensors.render.warmup:raycaster"}


def parts() -> dict[str, str]:
    """The parts in the order they are started: the localizer's that wait for no other
    (:data:`localizer.warmup.PARTS`), the simulator's (which share no kernel with them), then
    the localizer's that wait (:data:`localizer.warmup.AFTER`)."""
    from localizer.warmup import AFTER, PARTS as LOCALIZER_PARTS

    first = {name: spec for name, spec in LOCALIZER_PARTS.items() if name not in AFTER}
    return {**first, **PARTS, **{name: spec for name, spec in LOCALIZER_PARTS.items() if name in AFTER}}


def waits(names: list[str]) -> list[set[int]]:
    """For each part of ``names``, the indices of the parts it waits for (:data:`localizer.warmup.AFTER`;
    a part not in ``names`` is not waited for)."""
    from localizer.warmup import AFTER

    index = {name: i for i, name in enumerate(names)}
    return [{index[w] for w in AFTER.get(name, ()) if w in index} for name in names]


def register(sub) -> None:
    p = sub.add_parser("warmup", help="compile the numba kernels for this machine ahead of their first use",
                       description=doc_help(__doc__))
    p.add_argument("--jobs", type=number(1, 64, integer=True), default=None, metavar="N",
                   help="processes compiling in parallel (default: one per core, at most one per part)")
    add_json_flag(p)
    p.set_defaults(func=run)


def compile_part(args: dict) -> tuple[str, float, int]:
    """A worker's unit: one part's ``(name, seconds, compiled)`` (:func:`localizer.warmup.compile_part`)."""
    from localizer.warmup import compile_part as compile_spec

    return (args["name"], *compile_spec(args["spec"]))


def run(args) -> int:
    from agvsim.commands.workers import run_after

    todo = parts()
    jobs = min(args.jobs or os.cpu_count() or 1, len(todo))
    log(f"agvsim warmup: {plural(len(todo), 'part')} ({', '.join(todo)}) on {plural(jobs, 'process', 'processes')}; "
        "in a fresh install this compiles the kernels (about a minute on 2 cores), later it only loads them")
    start = time.perf_counter()
    done: dict[str, dict] = {}

    def finished(name: str, seconds: float, compiled: int) -> None:
        done[name] = {"seconds": seconds, "compiled": compiled}
        what = f"{plural(compiled, 'function')} compiled" if compiled else "all from the cache"
        log(f"  {name}: {seconds:.1f} s, {what} ({len(done)}/{len(todo)})")

    units = [{"name": name, "spec": spec} for name, spec in todo.items()]
    try:
        run_after(compile_part, units, waits(list(todo)), jobs, finished)
    except KeyboardInterrupt:
        log(f"agvsim warmup: interrupted after {len(done)}/{len(todo)} parts; what was compiled is cached: "
            "run it again to finish")
        return 130
    total = time.perf_counter() - start
    log(f"agvsim warmup: done in {total:.0f} s")
    if args.json:
        emit_json({"parts": done, "seconds": total, "jobs": jobs,
                   "compiled": sum(d["compiled"] for d in done.values())})
    return 0
