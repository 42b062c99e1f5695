"""`agvsim bench localization-integrity`: the figures and floors from trial records, and one real run."""
from __future__ import annotations

import argparse

import pytest

from agvsim.bench import localization_integrity as bench


def _trial(experiment, honest, steps, errors, wrong=(), detect=None, recover=None, saw_two=True, **kw):
    return {"experiment": experiment, "steps": steps, "honest": honest, "lost_steps": 0,
            "tracking_errors": list(errors), "relocalizations": 1, "wrong": list(wrong), "lost_ms": [1.0, 3.0],
            "detect_s": detect, "recover_s": recover, "refused": detect is not None, "declared_lost": detect is not None,
            "saw_two": saw_two, **kw}


def test_floors_follow_the_figures():
    rs = [_trial("random", 995, 1000, [0.01] * 100), _trial("random", 1000, 1000, [0.02] * 100)]
    g = bench.summarize(rs)["random"]
    assert g["honest_share"] == pytest.approx(0.9975)
    assert g["floors"] == {"no_wrong_relocalization": True, "honest_share": True, "tracking_p95": True}
    bad = bench.summarize([_trial("random", 900, 1000, [0.5] * 10, wrong=[3.0])])["random"]["floors"]
    assert bad == {"no_wrong_relocalization": False, "honest_share": False, "tracking_p95": False}


def test_kidnap_detection_and_recovery_shares():
    rs = [_trial("kidnap", 1, 1, [0.0], detect=1.0, recover=3.0, map="plant_floor") for _ in range(19)]
    rs.append(_trial("kidnap", 1, 1, [0.0], detect=6.0, recover=20.0, map="plant_floor"))
    g = bench.summarize(rs)["kidnap"]
    assert g["detect_within_5s_share"] == pytest.approx(0.95) and g["recovered_share"] == pytest.approx(0.95)
    assert g["floors"]["detect_within_5s"] and g["floors"]["recovered_95"]
    rs.append(_trial("kidnap", 1, 1, [0.0], detect=7.0, recover=None, map="plant_floor"))
    g = bench.summarize(rs)["kidnap"]
    assert not g["floors"]["detect_within_5s"] and not g["floors"]["recovered_95"]
    assert "NOT met" in bench.format_table({"machine": {}, "workers": 1, "wall_s": 1.0,
                                            "summary": bench.summarize(rs)})


def test_bad_flag_is_one_clear_error():
    args = argparse.Namespace(experiments=["random"], seeds=1, steps=0, kidnaps=0, unknown=0, walls=0, settle=1.0,
                              after=1.0, push=1.0, workers=1)
    with pytest.raises(ValueError, match="--steps must be >= 1, got 0"):
        bench.run(args)


@pytest.mark.slow
def test_one_kidnap_on_rendered_frames():
    args = argparse.Namespace(experiments=["kidnap"], seeds=0, steps=1, kidnaps=1, unknown=0, walls=0, settle=15.0,
                              after=30.0, push=1.0, workers=1)
    res = bench.run(args)
    g = res["summary"]["kidnap"]
    assert g["trials"] == 1 and g["wrong_relocalizations"] == 0
    (trial,) = res["trials"]
    assert trial["declared_lost"] and trial["relocalizations"] >= 1
