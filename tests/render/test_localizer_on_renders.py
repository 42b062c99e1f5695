"""The localizer finds every visible target in rendered frames at the thesis's 18 test points
(Tables 5.1-5.4: 16 mm and 50 mm lenses, the thesis's distances and angles), both polarities,
with d and alpha within the localizer's accuracy floors; distractors are not reported."""
from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.thesis.points import THESIS_POINTS
from agvsim.sensors.render.placement import vehicle_pose_for_target
from agvsim.sensors.render.renderer import RenderConditions
from localizer import detect_targets

pytestmark = pytest.mark.render

COLUMN_OFFSET_PX = 40.0  # target centre right of the principal point, as `agvsim reproduce thesis`


def _match(obs, truth):
    """Pairs (observation, truth) by bearing; unmatched observations; visible in-envelope truths not found."""
    pairs, extra = [], []
    wanted = [t for t in truth.targets if t.visible]
    for o in obs:
        t = min(wanted, key=lambda t: abs(t.beta - o.beta), default=None)
        if t is None or abs(t.beta - o.beta) > 0.02:
            extra.append(o)
        else:
            pairs.append((o, t))
    found = {t.id for _, t in pairs}
    missed = [t for t in truth.targets if t.in_envelope and t.id not in found]
    return pairs, extra, missed


def _run_points(renderers, hall, mount, target_id, conditions, rng):
    rows = []
    for lens, d_mm, _, a_deg, _ in THESIS_POINTS:
        r = renderers[lens]
        beta = math.atan(COLUMN_OFFSET_PX / r.camera.fx)
        vpose = vehicle_pose_for_target(mount, hall.target(target_id), d_mm / 1000.0, math.radians(a_deg), beta)
        image, truth = r.render(vpose, conditions, rng)
        assert truth.target(target_id).visible, (lens, d_mm, a_deg)
        pairs, extra, missed = _match(detect_targets(image, r.camera), truth)
        # the thesis's target must be found even where it is just outside the localizer's
        # envelope (point 9: bars 4.6 px wide at 5.72 m, 70 deg); others when in the envelope
        if target_id not in {t.id for _, t in pairs} and truth.target(target_id) not in missed:
            missed.append(truth.target(target_id))
        rows.append((lens, d_mm, a_deg, pairs, extra, missed))
    return rows


@pytest.mark.parametrize("target_id", ["P", "N"])  # positive and negative polarity
def test_thesis_points_found_within_floors(hall_renderers, hall, mount, rng, target_id):
    rows = _run_points(hall_renderers, hall, mount, target_id, RenderConditions(defocus_px=0.5), rng)
    d_err, a_err = [], []
    for lens, d_mm, a_deg, pairs, extra, missed in rows:
        assert not missed, f"{lens} mm, {d_mm} mm, {a_deg} deg: visible targets not found: {[t.id for t in missed]}"
        assert not extra, f"{lens} mm, {d_mm} mm, {a_deg} deg: {len(extra)} detections match no visible target"
        for o, t in pairs:
            assert o.polarity == t.polarity
            de = abs(o.distance - t.distance) / t.distance
            ae = abs(math.degrees(o.alpha - t.alpha))
            assert de <= 0.02, f"{t.id} at {lens} mm {d_mm} mm {a_deg} deg: d error {100 * de:.2f} %"
            if t.bar_rows >= 60:
                assert ae <= 3.0, f"{t.id} at {lens} mm {d_mm} mm {a_deg} deg: alpha error {ae:.2f} deg"
            if t.id == target_id:
                d_err.append(de)
                a_err.append(ae)
    assert len(d_err) == len(THESIS_POINTS)
    assert np.mean(d_err) <= 0.005, f"mean d error {100 * np.mean(d_err):.3f} %"
    assert np.mean(a_err) <= 1.0, f"mean alpha error {np.mean(a_err):.3f} deg"


def test_dim_lighting_still_detected(hall_renderers, hall, mount, rng):
    """The thesis's dim case (Fig. 5.5): a few test points under the 'dim' override."""
    r = hall_renderers[16]
    for d, a in ((1.41, 0.0), (3.24, -23.0), (5.72, 70.0)):
        vpose = vehicle_pose_for_target(mount, hall.target("P"), d, math.radians(a), 0.04)
        image, truth = r.render(vpose, RenderConditions(lighting="dim"), rng)
        t = truth.target("P")
        white = np.percentile(image[int(t.bbox[1]):int(t.bbox[3]), int(t.bbox[0]):int(t.bbox[2])], 95)
        assert white < 90  # really dim
        pairs, extra, missed = _match(detect_targets(image, r.camera), truth)
        assert not missed and not extra
        o, t = pairs[0]
        assert abs(o.distance - t.distance) / t.distance < 0.02
