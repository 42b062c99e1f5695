"""``agvsim drift`` and ``agvsim demo`` report time lost and recoveries."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from agvsim.analysis.evaluate import FLOORS, run_metrics, summarize
from agvsim.cli import main
from agvsim.loop.mission import MissionConfig, run_mission
from agvsim.sensors import GeometricSource, VisionConfig
from agvsim.world import load_map


@pytest.fixture(scope="module")
def corridor_log():
    corridor = load_map("corridor")
    vision = VisionConfig().for_map(corridor)
    return run_mission(corridor, GeometricSource(corridor, vision), np.random.default_rng(0),
                       MissionConfig(vision_config=vision, distance=20.0))


def test_time_lost_sums_the_lost_steps(corridor_log):
    log = corridor_log
    assert log.time_lost() == 0.0 and run_metrics(log)["time_lost_s"] == 0.0
    lost = np.zeros(len(log.time), bool)
    lost[10:35] = True  # 25 control steps of 0.1 s
    marked = dataclasses.replace(log, lost=lost, lost_events=1, relocalizations=1)
    assert marked.time_lost() == pytest.approx(2.5)
    m = run_metrics(marked)
    assert m["time_lost_s"] == pytest.approx(2.5) and m["relocalizations"] == 1
    other = dict(m, time_lost_s=1.0)
    assert summarize([m, other])["time_lost_s"] == pytest.approx(3.5)
    assert FLOORS["lost"] == ("<=", 0)  # the drift floor on lost events stays


def test_drift_table_and_json_show_time_lost_and_recoveries(tmp_path, capsys):
    argv = ["drift", "--map", "corridor", "--observations", "geometric", "--distance", "20", "--seeds", "2",
            "--workers", "1", "--no-progress", "--no-plots", "--out", str(tmp_path)]
    assert main(argv) == 0
    out = capsys.readouterr().out
    header = out.splitlines()[0].split()
    assert header[-4:] == ["lost", "lost", "s", "recov"]
    rows = [line.split() for line in out.splitlines()[1:4]]
    assert [r[0] for r in rows] == ["0", "1", "all"]
    assert all(len(r) == 12 and r[-3:] == ["0", "0.0", "0"] for r in rows)  # seed + 11 figures
    assert "lost 0 times for 0.0 s in all, recovered 0 times" in out
    assert main(argv + ["--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["time_lost_s"] == 0.0 and result["relocalizations"] == 0
    assert all("time_lost_s" in m for m in result["per_seed"])
    assert result["floors"]["lost"]["met"]


def test_demo_reports_time_lost_and_recoveries(tmp_path, capsys):
    argv = ["demo", "--map", "corridor", "--observations", "geometric", "--frames", "0", "--no-progress",
            "--out", str(tmp_path)]
    assert main(argv + ["--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["lost_events"] == 0 and result["time_lost_s"] == 0.0 and result["recoveries"] == 0
    assert main(argv) == 0
    assert "Localization: lost 0 times for 0.0 s in all, recovered 0 times" in capsys.readouterr().out
