"""Frames of the envelope benchmark (independent renders: a printed target on a cluttered wall
through a real camera's optics and sensor) that the localizer once got wrong: lettering taken
for a target."""
from __future__ import annotations

import pytest

from agvsim.bench.envelope_conditions import BY_NAME, GATE_BETA, GATE_DISTANCE
from agvsim.bench.envelope_frames import make_frame
from localizer import detect_targets


def _matches(o, pose) -> bool:
    return abs(o.beta - pose.beta) < GATE_BETA and abs(o.distance / pose.distance - 1.0) < GATE_DISTANCE


@pytest.mark.parametrize("condition, index", [("defocus", 108), ("motion_diag", 108), ("very_noisy", 108),
                                              ("flare", 108), ("saturated", 140)])
def test_lettering_beside_a_target_is_not_a_target(condition, index):
    # before: a U's right stroke and an L's (frame 108: the U's bowl and the L's foot turn out of
    # the side margins below the stack's last row) and a J's stem beside an O (frame 140, the J's
    # hat) were reported besides the true target
    frame = make_frame(BY_NAME[condition].settings, 0, index)
    obs = detect_targets(frame.image, frame.camera)
    assert len(obs) == 1
    assert _matches(obs[0], frame.scene.pose)


def test_a_stroke_beside_a_light_strip_is_not_a_target():
    # before: an I's stroke, a light strip across an H and the H's other stroke (bars of unequal
    # width: the exact fit's normalised residual 6.5) on a 1280 x 1024 frame without a target
    frame = make_frame(BY_NAME["hires_1280"].settings, 0, 21, with_target=False)
    assert detect_targets(frame.image, frame.camera) == []
