"""``agvsim bench env``: the breakdown of the wall time adds up (a short geometric run, in process);
the peak RSS is the env process's own; the floor is stated from one place."""
from __future__ import annotations

import math

import pytest

from agvsim.bench.env import (
    FLOOR_PEAK_RSS_MB,
    PARTS,
    format_table,
    kernels_compiled,
    measure,
    peak_rss_mb,
)


@pytest.fixture(scope="module")
def result():
    # max_episode_steps 40: the run crosses episode ends, whose loops' timings must be kept
    return measure("agvsim/PlantFloor-v2", {"observations": "geometric", "max_episode_steps": 40}, steps=120,
                   warmup=5)


def test_the_breakdown_parts_are_non_negative_and_sum_to_the_total(result):
    b = result["breakdown"]
    assert set(b) == {*PARTS, "total"}
    for part in PARTS:
        assert b[part]["seconds"] >= 0.0 and b[part]["ms_per_sim_second"] >= 0.0, part
    assert b["render"]["seconds"] == 0.0  # geometric draws no frames
    assert b["physics"]["seconds"] > 0.0 and b["filter"]["seconds"] > 0.0 and b["localize"]["seconds"] > 0.0
    assert math.isclose(sum(b[p]["seconds"] for p in PARTS), b["total"]["seconds"], rel_tol=1e-9)
    assert math.isclose(sum(b[p]["ms_per_sim_second"] for p in PARTS), b["total"]["ms_per_sim_second"],
                        rel_tol=1e-9)
    assert math.isclose(sum(b[p]["percent_of_wall"] for p in PARTS), 100.0, rel_tol=1e-9)
    assert math.isclose(b["total"]["seconds"], result["wall_seconds"])
    # 120 policy steps at 10 Hz: 12 simulated seconds
    assert math.isclose(b["total"]["ms_per_sim_second"], 1e3 * result["wall_seconds"] / 12.0)
    assert math.isclose(result["real_time_factor"] * result["wall_seconds"], 12.0)


def test_the_table_shows_the_breakdown(result):
    table = format_table({"env_id": "agvsim/PlantFloor-v2", "machine": {"cpu_model": "test"}, "skipped": ["image"],
                          "configs": {"state": {**result, "localization": "ekf", "peak_rss_mb": 100.0,
                                                "rss_end_mb": {"anon": 60.0, "file": 40.0}}},
                          "floor_peak_rss_mb": FLOOR_PEAK_RSS_MB})
    assert "geometric" in table and "skipped" in table
    assert "state 60 + 40" in table
    assert "floor: peak RSS per env process <= 300 MB: met (100 MB" in table
    assert f"floor: speed >= 500 steps/s: {'met' if result['steps_per_second'] >= 500 else 'NOT met'}" \
        in table
    assert "compiled" not in table
    cold = format_table({"env_id": "x", "skipped": [], "floor_peak_rss_mb": FLOOR_PEAK_RSS_MB,
                         "configs": {"state": {**result, "localization": "ekf", "peak_rss_mb": 900.0,
                                               "kernels_compiled": 12}}})
    assert "compiled 12 kernels" in cold
    assert "floor: peak RSS per env process <= 300 MB: NOT met (900 MB" in cold
    assert "issue" not in table + cold
    for part in (*PARTS, "total"):
        assert part in table


def test_kernels_compiled_counts_this_processs_compilations():
    import gc

    numba = pytest.importorskip("numba")
    gc.collect()  # the count is over live dispatchers: other tests' unreferenced kernels go first
    before = kernels_compiled()

    @numba.njit  # no cache: compiled at its first call
    def twice(x):
        return 2.0 * x

    assert twice(1.5) == 3.0
    assert kernels_compiled() == before + 1


def test_observations_choices_are_the_registry(capsys):
    from agvsim.cli import main
    from agvsim.sensors.registry import SOURCES

    with pytest.raises(SystemExit):
        main(["bench", "env", "--observations", "nonsense"])
    err = capsys.readouterr().err
    assert all(name in err for name in SOURCES)


def test_a_spawned_child_reports_its_own_peak_not_its_parents():
    """``ru_maxrss`` of a spawned child includes its parent's peak on Linux; ``peak_rss_mb`` does not."""
    import multiprocessing as mp
    import sys

    import numpy as np

    if not sys.platform.startswith("linux"):
        pytest.skip("VmHWM is Linux's")
    big = np.ones(200 * 2 ** 20 // 8)  # 200 MB resident in the parent
    assert peak_rss_mb() > 200.0
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=_child_peak, args=(queue,))
    proc.start()
    own, inherited = queue.get(timeout=120)
    proc.join()
    del big
    assert inherited > 200.0  # what the bench used to report for an idle child
    assert own < 100.0  # an interpreter, numpy, pytest and this module: about 30 MB


def _child_peak(queue) -> None:
    import resource

    queue.put((peak_rss_mb(), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0))


def test_every_floor_has_a_verdict_in_the_json():
    from agvsim.bench.env import FLOOR_STEPS_PER_SECOND, config_floors

    floors = config_floors({"steps_per_second": 499.0, "peak_rss_mb": 250.0})
    assert floors["steps_per_second"] == {"value": 499.0, "op": ">=", "limit": FLOOR_STEPS_PER_SECOND,
                                          "unit": "steps/s", "met": False}
    assert floors["peak_rss_mb"]["met"] and floors["peak_rss_mb"]["limit"] == FLOOR_PEAK_RSS_MB
