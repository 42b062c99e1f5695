"""The filter soak (``agvsim bench filter-soak``) on a short run, and what the long one found.

The short run (2 x 10^4 increments, 800 frames) meets the floors of the 10^6 one: P finite,
symmetric and positive definite after every frame, its position σ within
``MAX_POSITION_SIGMA``, no wrong confirmed re-localization, every refusal counted by the filter,
nothing half-applied, no crash. The tests below it pin what the long runs found wrong.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from agvsim.bench import filter_soak
from agvsim.bench.soak_inputs import FRAME_KINDS, ODOMETRY_GARBAGE
from agvsim.cli import main
from localizer.filter import (FilterConfig, GateConfig, Hypothesis, Measurement, PoseEKF, RelocalizeConfig,
                              Relocalizer, TargetMap, predict_all)
from localizer.filter.limits import MAX_POSITION_SIGMA, UNINFORMATIVE
from tests.filter.conftest import LIMITS, MOUNT, NOISE, corridor_targets, measure

CONFIG = FilterConfig(noise=NOISE, gate=GateConfig(view=LIMITS))
BOUNDARY = ("odometry_time", "odometry_increment", "odometry_contact", "frame_time", "measurement_invalid",
            "measurement_uninformative")


@pytest.fixture(scope="module")
def short_soak():
    return filter_soak.measure(increments=20_000, frames=800, kidnaps=4, seed=0, progress=False)


def test_the_short_soak_meets_the_floors(short_soak):
    r = short_soak
    assert r["increments"] == 20_000 and not r["interrupted"]
    assert {k: v for k, v in r["floors"].items() if not v["met"]} == {}
    assert r["P_not_finite"] == r["P_not_symmetric"] == r["P_not_positive_definite"] == 0
    assert 0 < r["P_min_eigenvalue"] and r["P_max_eigenvalue"] <= MAX_POSITION_SIGMA ** 2
    assert r["max_position_sigma_m"] <= MAX_POSITION_SIGMA
    assert r["wrong_relocalizations"] == 0 and r["crashes"] == 0 and r["half_applied"] == 0
    assert r["uncounted_refusals"] == 0 and r["not_refused"] == 0
    assert r["max_error_tracking_m"] < 0.5


def test_the_short_soak_covers_every_input(short_soak):
    """The floors above say something only if every kind of input was offered and refused."""
    r = short_soak
    assert all(n > 0 for n in r["frame_kinds"].values()) and set(r["frame_kinds"]) == set(FRAME_KINDS)
    assert all(r["odometry_garbage"][name] > 0 for name, _ in ODOMETRY_GARBAGE)
    for reason in BOUNDARY:  # the filter's own counts, equal to what was offered
        assert r["refusals"][reason] == r["refusals_expected"][reason] > 0, reason
    assert r["kidnaps_told"] >= 1 and r["kidnaps_silent"] >= 1 and r["silent_found"] >= 1
    assert r["relocalizations"] >= 3 and r["contact_steps"] > 0
    assert 2.0 < r["mean_nis"] < 4.5


def test_the_bench_command(capsys):
    assert main(["bench", "filter-soak", "--increments", "3000", "--frames", "120", "--kidnaps", "1",
                 "--seed", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["increments"] == 3000 and "machine" in out
    assert all(v["met"] for v in out["floors"].values())
    table = filter_soak.format_table(out)
    assert "floor: wrong confirmed relocalizations <= 0: met (0)" in table


# ------------------------------------------------------------------ what the long runs found
def test_while_lost_only_the_refused_observations_are_marked_uninformative():
    """A frame's kept observations go to re-localization while lost: they were reported refused
    as uninformative beside the one that was (and the filter counted one)."""
    targets = corridor_targets()
    ekf = PoseEKF(np.array([8.0, 0.0, 0.0]), np.eye(3) * 1e-4, targets, MOUNT, CONFIG)
    ekf.declare_lost("test")
    ms = [m for _, m in measure(np.array([8.0, 0.0, 0.0]), targets, np.random.default_rng(3))]
    assert ms
    loose = Measurement(ms[0].z, ms[0].R * 1e10, ms[0].polarity)
    res = ekf.process_frame(0.0, ms + [loose])
    assert [(a.observation, a.status) for a in res.associations] == [(len(ms), UNINFORMATIVE)]
    assert ekf.diagnostics()["refusals"]["measurement_uninformative"] == 1


def alias_world():
    """Two pairs of targets 10 m apart, alike (polarities too): from x = 6.5 the camera sees
    B0, B1, from x = -3.5 A0, A1, the same way."""
    xs = [10.0, 11.5, 20.0, 21.5]
    return TargetMap(("A0", "A1", "B0", "B1"), [[x, -4.0] for x in xs], [math.pi / 2] * 4,
                     ("positive", "negative", "positive", "negative"))


def test_a_rival_that_fits_as_much_blocks_a_confirmation():
    """The right hypothesis is too loose for its matches to count as evidence, but it fits what
    is seen as well as a precise wrong one 10 m away does: the wrong one is not confirmed. (The
    soak confirmed one 10.5 m off this way; the fresh seeds at the right place, merged into one,
    keep what the loose one explained.)"""
    targets = alias_world()
    truth = np.array([16.5, 0.0, 0.0])
    Z, vis = predict_all(truth, targets, MOUNT, LIMITS)
    assert list(np.nonzero(vis)[0]) == [2, 3]
    ms = [Measurement(Z[j], np.diag([1e-6, 1e-8, 1e-6]), targets.polarities[j]) for j in (2, 3)]
    reloc = Relocalizer(targets, MOUNT, GateConfig(view=LIMITS))
    right = Hypothesis(truth + [0.05, 0.05, 0.0], np.diag([0.3, 0.3, 0.005]) ** 2, explained={"B0": 1, "B1": 1})
    wrong = Hypothesis(truth - [10.0, 0.0, 0.0], np.diag([0.05, 0.05, 0.002]) ** 2, matched={"A0", "A1"})
    reloc.hypotheses = [right, wrong]
    assert reloc.process(ms) is None
    assert wrong.explained == {"A0": 2, "A1": 2} and wrong.misses == 0  # it would be confirmed on its own
    at_truth = [h for h in reloc.hypotheses if math.hypot(*(h.x[:2] - truth[:2])) < 0.3]
    assert len(at_truth) == 1 and at_truth[0].explained == {"B0": 2, "B1": 2}
    assert wrong in reloc.hypotheses and reloc.confirmed() is None
    # alone (no rival), the same evidence confirms it
    alone = Relocalizer(targets, MOUNT, GateConfig(view=LIMITS))
    alone.hypotheses = [Hypothesis(truth - [10.0, 0.0, 0.0], np.diag([0.05, 0.05, 0.002]) ** 2,
                                   matched={"A0", "A1"})]
    assert alone.update(ms) is None and alone.update(ms) is alone.hypotheses[0]  # two frames in a row


def test_a_target_matched_once_does_not_confirm():
    """A hypothesis seeded by a false detection that happens to fit one target, then matching a
    real target frame after frame, has two distinct targets, one of them seen once: the soak
    confirmed poses 25-29 m off so. Each must be explained ``confirm_sightings`` times."""
    targets = alias_world().subset([2, 3])  # B0, B1: no alias
    truth = np.array([16.5, 0.0, 0.0])
    Z, _ = predict_all(truth, targets, MOUNT, LIMITS)
    m0, m1 = (Measurement(Z[j], np.diag([1e-6, 1e-8, 1e-6]), targets.polarities[j]) for j in (0, 1))
    cfg = RelocalizeConfig()
    assert cfg.confirm_sightings == 2
    reloc = Relocalizer(targets, MOUNT, GateConfig(view=LIMITS), cfg)
    reloc.hypotheses = [Hypothesis(truth, np.diag([0.05, 0.05, 0.002]) ** 2, matched={"B0"})]  # the chance fit
    for _ in range(3):
        assert reloc.update([m1]) is None
    (h,) = reloc.hypotheses
    assert h.explained == {"B0": 1, "B1": 3} and h.matched == {"B0", "B1"}
    assert reloc.update([m0]) is None  # B0 seen again: it leads ...
    assert reloc.update([m1]) is h  # ... two frames in a row: confirmed
    with pytest.raises(ValueError, match="confirm_sightings"):
        RelocalizeConfig(confirm_sightings=0)


def test_a_seed_too_loose_to_survive_is_not_made():
    """An observation whose σ_α places the vehicle only within metres (α on a far target) seeds
    no hypothesis: the next frame would drop it, and merging it could displace a sound one."""
    targets = corridor_targets()
    reloc = Relocalizer(targets, MOUNT, GateConfig(view=LIMITS))
    x = np.array([8.0, 0.0, 0.0])
    Z, vis = predict_all(x, targets, MOUNT, LIMITS)
    j = int(np.nonzero(vis)[0][0])
    loose = Measurement(Z[j], np.diag([0.01, 1e-8, 1.0]) ** 2, targets.polarities[j])
    precise = Measurement(Z[j], np.diag([0.01, 1e-4, 0.01]) ** 2, targets.polarities[j])
    assert reloc.seed([loose]) == 0
    assert reloc.refusals["uninformative_match"] > 0 and reloc.hypotheses == []
    assert reloc.seed([precise]) > 0


def precise(targets, truth, j) -> Measurement:
    Z, _ = predict_all(truth, targets, MOUNT, LIMITS)
    return Measurement(Z[j], np.diag([1e-6, 1e-8, 1e-6]), targets.polarities[j])


def test_a_loose_observation_neither_kills_nor_supports_a_hypothesis():
    """A hypothesis two misses from being dropped sees a loose observation (one that alone places
    the vehicle only within metres): it stays, its misses and what it explained unchanged. (The
    soak's right hypothesis died so, by false detections and one loose one, and a wrong one 16 m
    off was confirmed unopposed.)"""
    targets = alias_world()
    truth = np.array([16.5, 0.0, 0.0])
    reloc = Relocalizer(targets, MOUNT, GateConfig(view=LIMITS))
    h = Hypothesis(truth, np.diag([0.05, 0.05, 0.002]) ** 2, matched={"B0"}, misses=2)
    reloc.hypotheses = [h]
    for polarity in ("positive", "negative"):  # one it fits (B0 / B1 in view), one it does not
        loose = Measurement([5.0, 0.3, 0.2], np.diag([0.9, 0.4, 3.0]) ** 2, polarity)
        assert not reloc.is_evidence(loose)
        reloc.process([loose])
        assert h in reloc.hypotheses and h.misses == 2
        assert h.explained == {"B0": 1} and h.matched == {"B0"}
    reloc.process([precise(targets, truth, 3)])  # an informative observation it explains: misses cleared
    assert h in reloc.hypotheses and h.misses == 0 and h.matched == {"B0", "B1"}


def test_not_confirmed_on_a_frame_it_did_not_explain_whole():
    """Enough evidence, but the confirming frame holds an observation the hypothesis refuses:
    confirmed on the next frame it explains whole, not on that one."""
    targets = alias_world().subset([2, 3])  # B0, B1: no alias
    truth = np.array([16.5, 0.0, 0.0])
    reloc = Relocalizer(targets, MOUNT, GateConfig(view=LIMITS))
    h = Hypothesis(truth, np.diag([0.05, 0.05, 0.002]) ** 2, matched={"B0", "B1"}, explained={"B0": 1, "B1": 2})
    reloc.hypotheses = [h]
    stray = Measurement([3.0, 0.2, -0.5], np.diag([1e-4, 1e-8, 1e-4]), "positive")  # a false detection
    assert reloc.process([precise(targets, truth, 0), stray]) is None
    assert h.explained == {"B0": 2, "B1": 2} and h.unexplained == 1
    assert h.misses == 0  # no hypothesis fits the false detection: it counts against none
    assert reloc.process([precise(targets, truth, 1)]) is None  # leads one frame
    assert reloc.process([precise(targets, truth, 0)]) is h


def test_only_an_observation_another_hypothesis_fits_counts_against_one():
    """Two misses from being dropped: a false detection that fits nowhere leaves a hypothesis
    alive (the soak's right hypotheses died of such, and wrong ones were confirmed unopposed); an
    observation another hypothesis fits drops it."""
    targets = alias_world().subset([2, 3])
    truth = np.array([16.5, 0.0, 0.0])
    reloc = Relocalizer(targets, MOUNT, GateConfig(view=LIMITS))
    h = Hypothesis(truth, np.diag([0.05, 0.05, 0.002]) ** 2, matched={"B0"}, misses=2)
    off = Hypothesis(truth + [0.0, 1.5, 0.0], np.diag([0.05, 0.05, 0.002]) ** 2, matched={"B0"}, misses=2)
    reloc.hypotheses = [h, off]
    stray = Measurement([3.0, 0.2, -0.5], np.diag([1e-4, 1e-8, 1e-4]), "positive")
    reloc.process([stray])
    assert h in reloc.hypotheses and off in reloc.hypotheses and h.misses == off.misses == 2
    reloc.process([precise(targets, truth, 1)])  # h fits it, off does not
    assert h in reloc.hypotheses and h.misses == 0 and off not in reloc.hypotheses


def test_an_observations_evidence_is_the_same_from_every_target():
    """The evidence test reads ``J R Jᵀ`` from one target for every pairing: its position σ does
    not depend on where the target is or which way it faces."""
    from localizer.filter import pose_from_measurement_jacobian, position_sigma

    m = Measurement([6.0, 0.1, 0.4], [[1e-3, 0, 2e-4], [0, 1e-6, 0], [2e-4, 0, 4e-3]])
    sig = [position_sigma(J @ m.R @ J.T) for J in
           (pose_from_measurement_jacobian(m.z, pos, yaw, MOUNT)
            for pos, yaw in (((0.0, 0.0), 0.0), ((12.0, -3.0), 1.1), ((-40.0, 7.0), -2.9)))]
    np.testing.assert_allclose(sig, sig[0], rtol=1e-12)


def test_a_seed_explains_nothing():
    """A hypothesis made from an observation fits it by construction: that is no test of it
    (the soak confirmed a pose 32 m off whose first target was a false detection's seed and one
    more that happened to fit)."""
    targets = alias_world()
    reloc = Relocalizer(targets, MOUNT, GateConfig(view=LIMITS))
    assert reloc.seed([precise(targets, np.array([16.5, 0.0, 0.0]), 2)]) == 2  # B0 and its alias A0
    assert all(h.explained == {} and len(h.matched) == 1 for h in reloc.hypotheses)


def test_a_lead_tipped_by_one_observation_is_not_confirmed():
    """An observation whose covariance does not cover its error can tip the lead to an alias
    for one frame (the soak confirmed a pose 12 m off so): the lead must hold two frames."""
    targets = alias_world()
    truth = np.array([16.5, 0.0, 0.0])
    tight = np.diag([0.01, 0.01, 0.0005]) ** 2
    right = Hypothesis(truth, tight, matched={"B0", "B1"}, explained={"B0": 2, "B1": 1})
    alias = Hypothesis(truth - [10.1, 0.0, 0.0], tight, matched={"A0", "A1"}, explained={"A0": 2, "A1": 1})
    reloc = Relocalizer(targets, MOUNT, GateConfig(view=LIMITS))
    reloc.hypotheses = [right, alias]
    Z, _ = predict_all(alias.x, targets, MOUNT, LIMITS)
    tip = Measurement(Z[1], np.diag([1e-6, 1e-8, 1e-6]), "negative")  # fits the alias, not the right one
    assert reloc.process([tip]) is None
    assert alias.explained["A1"] == 2 and right.unexplained == 1  # the alias leads ...
    assert reloc.process([precise(targets, truth, 3)]) is None  # ... for one frame: B1 ties it
    assert right.explained == {"B0": 2, "B1": 2} and alias in reloc.hypotheses


def test_a_frame_of_loose_observations_does_not_confirm():
    """The soak's vehicle was carried off while the right hypothesis led; the next frame held
    only loose observations and confirmed it, wrong by then. Such a frame says nothing: the lead
    holds, and the next informative frame decides."""
    targets = alias_world().subset([2, 3])
    truth = np.array([16.5, 0.0, 0.0])
    reloc = Relocalizer(targets, MOUNT, GateConfig(view=LIMITS))
    h = Hypothesis(truth, np.diag([0.05, 0.05, 0.002]) ** 2, matched={"B0", "B1"}, explained={"B0": 2, "B1": 1})
    reloc.hypotheses = [h]
    assert reloc.process([precise(targets, truth, 1)]) is None  # leads one frame
    loose = Measurement([5.0, 0.1, 0.2], np.diag([0.9, 0.4, 3.0]) ** 2, "negative")
    assert reloc.process([loose]) is None and reloc.process([loose, loose]) is None
    assert reloc.process([precise(targets, truth, 0)]) is h
