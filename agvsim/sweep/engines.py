"""Where a sweep's runs execute: a local process pool (the default) or Ray.

Both take the same runs (:func:`agvsim.sweep.runs.units_of`) and call ``finished(key, row)``
in this process as each run ends, so the folder writes each row the moment it exists; the
rows depend on the seeds only, not on the engine. Each worker lives for the whole sweep (numba's
kernels are loaded once per worker, not once per run: numba compiles or loads them in every
fresh process) and runs one run at a time with one numba and BLAS thread.

* ``local``: :func:`agvsim.commands.workers.run_units`, spawned processes that do not outlive
  a Ctrl-C or a kill of the command; progress in metres from inside the runs.
* ``ray``: one Ray actor per worker (``num_cpus=1``), on a Ray started here (``address``
  None: a local Ray of ``workers`` CPUs, stopped at the end) or an existing cluster
  (``address``: ``HOST:PORT`` of its head, or ``auto``). The environment the workers need
  (``PYOPENGL_PLATFORM``, one thread each) goes through Ray's ``runtime_env``. Ray is the
  optional extra ``agvsim[ray]``.
"""
from __future__ import annotations

import os
import time
from typing import Callable

from agvsim.sweep.runs import run_unit

__all__ = ["ENGINES", "WORKER_ENV", "run_local", "run_ray", "ray_available"]

#: the engines, in the order the CLI lists them (the first is the default)
ENGINES: tuple[str, ...] = ("local", "ray")
#: environment of every worker: headless OpenGL for the pyrender backend, one thread each
WORKER_ENV: dict[str, str] = {"PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "egl"),
                              "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                              "MKL_NUM_THREADS": "1", "AGVSIM_QUIET_COMPILE": "1"}


def run_local(units: list[dict], workers: int, finished: Callable[[str, dict], None],
              progress: Callable[[float], None]) -> dict:
    """Run ``units`` on ``workers`` local processes (module docstring). Returns ``{"startup_s": 0}``
    (the pool's start is part of the first runs)."""
    from agvsim.commands.workers import run_units

    for key, value in WORKER_ENV.items():  # (inherited by the spawned workers)
        os.environ.setdefault(key, value)
    run_units(run_unit, units, workers, finished, progress)
    return {"startup_s": 0.0}


def ray_available() -> bool:
    """Whether Ray can be imported (the ``ray`` extra is installed)."""
    try:
        import ray  # noqa: F401
    except ImportError:
        return False
    return True


class _Worker:
    """A Ray actor's body: runs one run at a time (made a Ray actor in :func:`run_ray`)."""

    def ready(self) -> int:
        import agvsim.loop.drive  # noqa: F401 - the imports done once, before the first run

        return os.getpid()

    def run(self, unit: dict) -> tuple[str, dict]:
        return run_unit(unit)


def run_ray(units: list[dict], workers: int, finished: Callable[[str, dict], None],
            progress: Callable[[float], None], address: str | None = None,
            meanwhile: Callable[[], object] | None = None) -> dict:
    """Run ``units`` on ``workers`` Ray actors (module docstring); ``progress`` gets each run's
    metres when it ends. ``meanwhile`` (e.g. the kernels' warm-up) runs in a thread while Ray
    starts, and ends before the first run is sent. Returns ``{"startup_s": seconds from
    ray.init to every actor ready (and ``meanwhile`` done), "address": the cluster's address}``.

    Raises:
        ValueError: Ray is not installed, or no cluster answers at ``address``.
    """
    if not ray_available():
        raise ValueError("--engine ray: Ray is not installed; install the extra: pip install 'agvsim[ray]'")
    import concurrent.futures

    import ray
    from ray.util import ActorPool

    started = time.perf_counter()
    side = concurrent.futures.ThreadPoolExecutor(max_workers=1)
    pending = side.submit(meanwhile) if meanwhile is not None else None
    side.shutdown(wait=False)
    env = {"env_vars": dict(WORKER_ENV)}
    try:
        if address is None:
            # ("local": a new instance even where a cluster started by `ray start` runs here)
            # (workers at normal priority, as the local pool's: Ray's default niceness of 15 gives
            # them a fraction of a core whenever anything else runs on the machine)
            info = ray.init(address="local", num_cpus=workers, include_dashboard=False, runtime_env=env,
                            log_to_driver=False, configure_logging=False, _system_config={"worker_niceness": 0})
        else:
            info = ray.init(address=address, runtime_env=env, log_to_driver=False, configure_logging=False)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise ValueError(f"--address {address!r}: no Ray cluster could be reached ({exc})") from None
    try:
        actor = ray.remote(num_cpus=1)(_Worker)
        actors = [actor.remote() for _ in range(max(1, min(workers, len(units))))]
        ray.get([a.ready.remote() for a in actors])
        if pending is not None:
            pending.result()
        startup = time.perf_counter() - started
        pool = ActorPool(actors)
        metres = {u["key"]: u["settings"].distance for u in units}
        for key, row in pool.map_unordered(lambda a, u: a.run.remote(u), units):
            finished(key, row)
            progress(metres[key])
        return {"startup_s": startup, "address": getattr(info, "address_info", {}).get("address")}
    finally:
        ray.shutdown()
