"""``agvsim bench env``: the breakdown of the wall time adds up (a short geometric run, in process)."""
from __future__ import annotations

import math

import pytest

from agvsim.bench.env import PARTS, format_table, measure


@pytest.fixture(scope="module")
def result():
    # max_episode_steps 40: the run crosses episode ends, whose loops' timings must be kept
    return measure("agvsim/PlantFloor-v0", {"observations": "geometric", "max_episode_steps": 40}, steps=120,
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
    table = format_table({"env_id": "agvsim/PlantFloor-v0", "machine": {"cpu_model": "test"}, "skipped": ["image"],
                          "configs": {"state": {**result, "localization": "ekf", "peak_rss_mb": 100.0}},
                          "floor_peak_rss_mb_with_images": 500.0})
    assert "geometric" in table and "skipped" in table
    for part in (*PARTS, "total"):
        assert part in table


def test_observations_choices_are_the_registry(capsys):
    from agvsim.cli import main
    from agvsim.sensors.registry import SOURCES

    with pytest.raises(SystemExit):
        main(["bench", "env", "--observations", "nonsense"])
    err = capsys.readouterr().err
    assert all(name in err for name in SOURCES)
