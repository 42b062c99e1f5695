"""The fused path of ``detect_targets`` (one compiled call per frame, :mod:`localizer.measure.fused`) gives
the step-by-step path's observations and statistics bit for bit: on envelope frames of every
kind of target it decides about (sharp, sRGB-encoded, blurred and refined, saturated, large
frames through the pyramid, a steep blurred target only the search of the sharpened copy finds),
under each response and refinement setting."""
from __future__ import annotations

import pytest

import localizer.measure.fused
from agvsim.bench.envelope_conditions import BY_NAME
from agvsim.bench.envelope_frames import make_frame
from localizer import DetectionStats, detect_targets

SETTINGS = ({}, {"response": "srgb"}, {"response": "linear"}, {"photometric": "all"}, {"photometric": "clipped"},
            {"photometric": "off"})


def _run(frames, **params) -> list[str]:
    out = []
    for f in frames:
        st = DetectionStats()
        obs = detect_targets(f.image, f.camera, stats=st, **params)
        st.seconds = 0.0
        out.append(repr(st) + "".join(repr(o.to_dict()) for o in obs))
    return out


def _step_by_step(monkeypatch) -> None:
    """Make the fused call fail as a degenerate measurement would: the step-by-step path runs."""
    def fail(*args):
        raise ZeroDivisionError("forced")

    monkeypatch.setattr(localizer.measure.fused.frame, "detect_frame", fail)


@pytest.mark.parametrize("condition, indices", [("baseline", range(0, 6)), ("webcam", range(0, 6)),
                                                ("blur3", range(0, 8)), ("blur3", (86,)), ("saturated", range(0, 6)),
                                                ("hires_1280", range(0, 2))])
def test_the_fused_path_is_the_step_by_step_path(monkeypatch, condition, indices):
    frames = [make_frame(BY_NAME[condition].settings, 0, i) for i in indices]
    frames.append(make_frame(BY_NAME[condition].settings, 0, 0, with_target=False))
    fused = {i: _run(frames, **kw) for i, kw in enumerate(SETTINGS)}
    assert sum("distance_m" in r for r in fused[0]) >= len(indices) - 1
    _step_by_step(monkeypatch)
    for i, kw in enumerate(SETTINGS):
        assert _run(frames, **kw) == fused[i], kw


def test_the_fused_path_refines_and_linearizes_on_these_frames():
    # the comparison above covers the refinement and the linearized window only if they happen
    refined = linearized = 0
    for i in range(8):
        f = make_frame(BY_NAME["blur3"].settings, 0, i)
        p = {"photometric": "all"}
        a = detect_targets(f.image, f.camera, **p)
        b = detect_targets(f.image, f.camera, photometric="off")
        refined += sum(x.distance != y.distance for x, y in zip(a, b))
    for i in range(6):
        f = make_frame(BY_NAME["webcam"].settings, 0, i)
        a = detect_targets(f.image, f.camera)
        b = detect_targets(f.image, f.camera, response="linear")
        linearized += sum(x.distance != y.distance for x, y in zip(a, b))
    assert refined >= 4 and linearized >= 3
