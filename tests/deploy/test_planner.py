"""The target layout planner: its prediction is the filter's own covariance, its layouts meet
the budget with targets only where they may hang, and its failures say what went wrong.

* the batched prediction (:func:`agvsim.deploy.predict.propagate`) gives, frame by frame, the
  covariance filterpy's EKF (the filter's one predict and update path) reaches on the same lap
  and the same sightings;
* on the corridor with a 5 cm budget: every placement on an allowed face, spaced, polarities
  alternating along the route, the new map loads with the placed targets marked ``# planned``,
  the predicted worst 3σ within the budget; ``--keep-targets`` keeps the map's own;
* an impossible budget ends (exit 1) saying how close it came and with how many targets; a
  forbidden face gets no target; a route that sees no wall is named; bad flags are one line.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agvsim.cli import main
from agvsim.deploy.candidates import candidate_targets, parse_faces
from agvsim.deploy.planner import plan_targets
from agvsim.deploy.predict import RouteModel, propagate, steady_start
from agvsim.world import load_map
from localizer.filter.measurement import Measurement, predict_measurement
from localizer.filter.update import PoseKF, position_sigma, update_pose


@pytest.fixture(scope="module")
def corridor():
    m = load_map("corridor")
    return m, RouteModel(m)


def test_prediction_is_the_filters_covariance(corridor):
    m, model = corridor
    targets = list(m.targets)
    sights = model.sightings(targets)
    assert len(sights.frame) > 50
    P0 = steady_start(model, sights)
    _, sigma = propagate(model, P0[None], sights)
    kf = PoseKF(x=model.poses[-1], P=P0)
    mount = model.vision.mount
    starts = np.searchsorted(sights.frame, np.arange(model.frames + 1))
    reference = []
    for i in range(model.frames):
        kf.F, kf.Q = model.F[i], model.GQG[i]  # (the lap's motion, linearised on its poses)
        kf.predict(u=np.zeros(3))  # filterpy: P <- F P Fᵀ + Q
        kf.x = model.poses[i].reshape(3, 1).copy()
        for k in range(starts[i], starts[i + 1]):
            t = targets[sights.target[k]]
            z = predict_measurement(model.poses[i], t.position, t.yaw, mount)
            update_pose(kf, Measurement(z, sights.R[k]), t.position, t.yaw, mount)  # filterpy's update
        reference.append(position_sigma(kf.P))
    np.testing.assert_allclose(sigma[0], reference, rtol=1e-6)
    assert np.ptp(reference) > 0.5 * max(reference)  # (sightings pull it down, blind stretches let it grow)


def _plan(capsys, *args) -> tuple[int, dict]:
    code = main(["plan", *map(str, args), "--json"])
    out = capsys.readouterr()
    return code, (json.loads(out.out) if out.out.strip() else {"stderr": out.err})


def test_corridor_layout_meets_the_budget_where_targets_may_hang(tmp_path, capsys):
    out = tmp_path / "corridor_planned.yaml"
    code, report = _plan(capsys, "corridor", "--max-error", 0.05, "--out", out)
    assert code == 0 and report["met"] and report["predicted_worst_3sigma_m"] <= 0.05
    new = load_map(str(out))
    placed = [t for t in new.targets if t.id in report["placed_ids"]]
    assert len(placed) == report["placed"] == len(new.targets) >= 4
    walls = {w.id: w for w in new.walls}
    assert all(walls[t.wall].surface not in ("door", "glass", "poster") for t in placed)
    pos = np.array([t.position for t in placed])
    gaps = np.hypot(*(pos[:, None] - pos[None]).transpose(2, 0, 1))
    assert gaps[~np.eye(len(pos), dtype=bool)].min() >= 2.0 - 1e-9
    assert [t.polarity for t in placed] == ["positive", "negative"] * (len(placed) // 2) + ["positive"] * (len(placed) % 2)
    text = out.read_text()
    assert text.count("# planned") == len(placed) and "agvsim plan" in text.splitlines()[0]
    assert Path(report["picture"]).stat().st_size > 30_000
    assert report["longest_blind_m"] > 0 and report["planning_s"] < 60


def test_keep_targets_keeps_the_maps_own(tmp_path, capsys):
    code, report = _plan(capsys, "corridor", "--max-error", 0.04, "--keep-targets", "--out", tmp_path / "k.yaml")
    new = load_map(str(tmp_path / "k.yaml"))
    original = {t.id for t in load_map("corridor").targets}
    assert original <= {t.id for t in new.targets} and report["kept"] == len(original)
    assert code == (0 if report["met"] else 1)


def test_impossible_budget_says_how_close_it_came(tmp_path, capsys):
    code = main(["plan", "corridor", "--max-error", "0.001", "--out", str(tmp_path / "x.yaml")])
    err = capsys.readouterr().err
    assert code == 1
    line = [ln for ln in err.splitlines() if "out of reach" in ln]
    assert len(line) == 1 and "the closest is a predicted worst 3σ of" in line[0] and "targets" in line[0]
    assert load_map(str(tmp_path / "x.yaml")).targets  # the closest layout is written


def test_forbidden_faces_get_no_target(corridor):
    m, model = corridor
    faces = parse_faces([m.walls[0].id, f"{m.walls[1].id}:left"], m)
    cands = candidate_targets(m, height=1.2, forbid=faces)
    assert not any(t.wall == m.walls[0].id for t in cands)
    assert not any(t.wall == m.walls[1].id and t.side == "left" for t in cands)
    assert any(t.wall == m.walls[1].id for t in cands) or all(w.surface == "door" for w in m.walls[1:2])
    with pytest.raises(ValueError, match=r"--forbid 'no_such_wall': wall must be one of"):
        parse_faces(["no_such_wall"], m)


def test_a_route_that_sees_no_wall_is_named(corridor):
    m, model = corridor
    with pytest.raises(ValueError, match=r"route 'default' of map 'corridor': the camera sees no place"):
        plan_targets(model, [], budget=0.05)


@pytest.mark.parametrize("args, expected", [
    (["corridor", "--max-error", "-1", "--out", "x.yaml"], "--max-error"),
    (["corridor", "--out", "x.txt"], "expected a .yaml file name"),
    (["corridor", "--route", "nowhere", "--out", "x.yaml"], "--route (map 'corridor') must be one of"),
    (["corridor", "--forbid", "wall9", "--out", "x.yaml"], "--forbid 'wall9': wall must be one of"),
])
def test_bad_flags_are_one_line(tmp_path, capsys, monkeypatch, args, expected):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) if args[1] == "--max-error" else _nothing():
        code = main(["plan", *args])
        assert code == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err and err.strip().count("\n") == 0, err


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def test_a_batch_is_each_member_on_its_own(corridor):
    m, model = corridor
    cands = candidate_targets(m, height=model.vision.mount.height, step=1.0)
    sights = model.sightings(cands)
    counts = np.bincount(sights.frame * len(cands) + sights.target)
    assert counts.max() == 1  # (one sighting of a target per frame)
    seen = np.unique(sights.target)[:40]
    assert np.bincount(sights.of(seen).frame).max() > 1  # frames where several members are seen at once
    common = model.sightings(list(m.targets)[:3])
    P0 = np.repeat(steady_start(model, common)[None], len(seen), axis=0)
    batch_of = np.full(len(cands), -1)
    batch_of[seen] = np.arange(len(seen))
    _, batch = propagate(model, P0, common, sights.of(seen), batch_of)
    for j in (0, len(seen) // 2, len(seen) - 1):
        both = sights.of([seen[j]])
        merged = type(both)(*(np.concatenate([getattr(common, f), getattr(both, f)])[np.argsort(
            np.concatenate([common.frame, both.frame]), kind="stable")]
            for f in ("frame", "target", "H", "R", "distance")))
        _, alone = propagate(model, P0[:1], merged)
        np.testing.assert_allclose(batch[j], alone[0], rtol=1e-9)
