"""`agvsim bench availability`: the figures from hand-made step records, and one tiny real run."""
from __future__ import annotations

import argparse

import pytest

from agvsim.bench import availability as bench
from agvsim.bench.availability import StepRecord

MACHINE = {"cpu_model": "test", "cpu_count": 2, "python": "3"}


def _r(status="tracking", error=0.01, m2=1.0, sigma=0.02, measured=False, reason=None):
    return StepRecord(status, error, m2, sigma, measured, reason)


def test_figures_of_a_hand_made_episode():
    records = [
        _r(),  # the reset: not a step
        _r(measured=True),
        _r(error=0.05, sigma=0.05),  # the last tracking step before a false loss
        _r("lost", error=0.05, m2=50.0, sigma=100.0, measured=True, reason="misfits"),  # loss 1: false
        _r("lost", error=0.3, m2=0.0, sigma=100.0, measured=True),  # measured: 1
        _r("relocalizing", error=0.3, m2=0.0, sigma=100.0),  # not measured
        _r(error=0.2, m2=3.0, measured=True),  # tracking but 20 cm off: 2, not yet recovered
        _r(error=0.6, m2=20.0, sigma=0.3),  # confident and wrong (> 0.5 m, outside 3 sigma), dishonest
        _r(error=0.08, m2=2.0, measured=True),  # recovered after 3 measured steps
        _r(error=0.4, m2=2.0, sigma=0.4),
        _r("lost", error=0.4, sigma=100.0, reason="heading sigma 21.3 deg > 20 deg"),  # loss 2: not false (40 cm)
        _r("lost", error=0.4, sigma=100.0, measured=True),  # unrecovered at the episode's end
    ]
    f = bench.episode_figures(records)
    assert f["steps"] == 11 and f["tracking_steps"] == 6 and f["not_tracking_steps"] == 5 and f["episodes"] == 1
    assert f["honest_steps"] == 10 and f["confident_wrong"] == 1
    assert f["lost_events"] == 2 and f["false_lost_events"] == 1 and f["false_lost_reasons"] == {"misfits": 1}
    assert f["lost_reasons"] == {"misfits": 1, "heading sigma N deg > N deg": 1}
    assert f["recoveries"] == [3] and f["unrecovered"] == 1 and f["unrecovered_measured"] == [1]
    g = bench.summarize(bench.merge_figures(bench.merge_figures(bench.empty_figures(), f), f))
    assert g["steps"] == 22 and g["tracking_pct"] == pytest.approx(100 * 6 / 11)
    assert g["honest_pct"] == pytest.approx(100 * 10 / 11) and g["false_lost_reasons"] == {"misfits": 2}
    assert g["recovery_median"] == 3.0 and g["recovery_max"] == 3 and g["unrecovered"] == 2
    met = {k: v["met"] for k, v in g["floors"].items()}
    assert met == {"false lost events": False, "tracking": False, "honest": False, "recovery median": True,
                   "recovery max": True, "confident-wrong steps": False}


def test_no_loss_meets_the_recovery_floors_and_the_table_says_so():
    f = bench.episode_figures([_r(), _r(), _r(measured=True)])
    g = bench.summarize(f)
    assert g["lost_events"] == 0 and g["recovery_median"] is None
    assert g["floors"]["recovery median"]["met"] and g["floors"]["recovery max"]["met"]
    res = {"machine": MACHINE, "wide": False, "seeds": 1, "steps": 2, "workers": 1, "wall_s": 1.0,
           "results": {"agvsim/Corridor-v2": {"wall": g}}}
    res["floors"] = bench.worst_floors(res["results"])
    table = bench.format_table(res)
    assert "all floors met" in table and "floor: tracking >= 90 %: met (100.00 %; worst: Corridor-v2 wall)" in table


def test_bad_flag_is_one_clear_error():
    args = argparse.Namespace(seeds=1, steps=0, envs=list(bench.ENVS), policies=["wall"], workers=1, wide=False)
    with pytest.raises(ValueError, match="--steps must be >= 1, got 0"):
        bench.run(args)


def test_one_tiny_run_on_rendered_frames():
    args = argparse.Namespace(seeds=1, steps=60, envs=["agvsim/Corridor-v2"], policies=["forward"], workers=1,
                              wide=True)  # the wide belief reaches the env's filter through filter_config
    res = bench.run(args)
    g = res["results"]["agvsim/Corridor-v2"]["forward"]
    assert g["steps"] == 60 and g["episodes"] == 1
    assert g["tracking_steps"] + g["not_tracking_steps"] == g["steps"] and g["honest_steps"] <= g["steps"]
    for key in ("tracking_pct", "honest_pct"):
        assert 0.0 <= g[key] <= 100.0
    for key in ("tracking_steps", "not_tracking_steps", "confident_wrong", "lost_events", "false_lost_events",
                "unrecovered", "filter_lost_events"):
        assert g[key] >= 0
    assert g["false_lost_events"] <= g["lost_events"] and g["recovered"] + g["unrecovered"] == g["lost_events"]
    assert set(res["floors"]) == set(bench.FLOORS) and "machine:" in bench.format_table({"machine": MACHINE, **res})
