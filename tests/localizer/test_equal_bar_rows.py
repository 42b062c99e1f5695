"""False detections: rows of equal narrow bars are not targets.

Every neighbouring pair of bars in such a row passes the run test as a (blurred) target,
and two of 10,005 fuzzed frames were reported as overlapping targets sharing bars. A
target's bars have a half-bar margin beyond them (``localizer.model.target``), not a third bar at
the pitch (the periodic test, ``localizer._kernels.scan.triples``), and a bar belongs to one
target only (``localizer.detect._drop_shared_bars``)."""
import numpy as np
import pytest

from localizer import DetectionStats, detect_targets
from localizer.tools.synthetic import EQUAL_BAR_GRID, equal_bar_frame, equal_bar_rows, pose_at_column, render_frame

METHODS = ("thesis", "exact")


@pytest.mark.parametrize("method", METHODS)
def test_the_fuzzed_frame_finds_nothing(cam16, method):
    # 4 dark bars 5 px wide at a 15 px pitch, 16 rows tall, grey 24 on 172: were 3 "targets" at ~10 m
    img = equal_bar_frame(cam16, 4, 5, 15, 16, 24, 172)
    assert detect_targets(img, cam16, method=method) == []


def test_equal_bar_rows_find_nothing(cam16):
    # 3,024 exact-pixel frames: 3, 4 or 6 bars, 3-12 px wide, gaps 0-5 px wider than the bars,
    # 0.8-1.3 times a facing target's height, four contrasts, both polarities (was 740
    # false targets per method)
    found = {m: [] for m in METHODS}
    n = 0
    for name, img in equal_bar_rows(cam16):
        n += 1
        for m in METHODS:
            if detect_targets(img, cam16, method=m):
                found[m].append(name)
    assert n == int(np.prod([len(g) for g in EQUAL_BAR_GRID])) * 2
    assert found == {m: [] for m in METHODS}


@pytest.mark.slow
@pytest.mark.parametrize("blur, noise", [(0.6, 1.5), (1.2, 3.0)])
def test_blurred_equal_bar_rows_find_nothing(cam16, blur, noise):
    # a quarter of the grid (blur 0.6, noise 1.5: was 456 false targets, both methods together)
    rng = np.random.default_rng(18)
    for name, img in equal_bar_rows(cam16, blur, noise, rng, every=4):
        for m in METHODS:
            assert detect_targets(img, cam16, method=m) == [], (name, m)


@pytest.mark.parametrize("method", METHODS)
def test_shared_bars_reject_both(cam16, method):
    # without the periodic test the pairs of a row of bars as wide as their gaps are found; they
    # share bars, so none is kept
    img = equal_bar_frame(cam16, 4, 5, 10, 16, 24, 172)
    st = DetectionStats()
    assert detect_targets(img, cam16, method=method, reject_periodic=False, stats=st) == []
    assert st.rejected.get("shared_bars", 0) >= 2
    # bars half as wide as their gaps (the fuzzed frame) do not fit a target at all: the exact
    # fit needs a common edge shift of 1.25 px on sharp edges (localizer.detect.MAX_SHIFT_SHARE)
    img = equal_bar_frame(cam16, 4, 5, 15, 16, 24, 172)
    st = DetectionStats()
    assert detect_targets(img, cam16, method=method, reject_periodic=False, stats=st) == []
    assert st.rejected.get("pose", 0) >= 2


@pytest.mark.parametrize("method", METHODS)
def test_targets_beside_each_other_still_found(cam16, method):
    # two real targets side by side (printed 93 px wide at 3 m, 7 px of wall between them)
    # share no bar: both are kept
    poses = [pose_at_column(cam16, 3.0, 0.0, 200), pose_at_column(cam16, 3.0, 0.0, 300)]
    img = render_frame(cam16, poses, noise=1.0, blur=0.5, rng=np.random.default_rng(1))
    obs = detect_targets(img, cam16, method=method)
    assert len(obs) == 2
    assert sorted(o.distance for o in obs) == pytest.approx([3.0, 3.0], rel=0.01 if method == "exact" else 0.03)
