"""Hostile input: every detector parameter is checked, with a message naming the
parameter, the value and the valid range (``localizer.model.params.PARAM_RANGES``)."""
import math
from dataclasses import fields

import numpy as np
import pytest

from localizer import DetectorParams, detect_targets
from localizer.model.params import PARAM_RANGES


def test_every_parameter_has_a_range():
    assert list(PARAM_RANGES) == [f.name for f in fields(DetectorParams)]


@pytest.mark.parametrize("name, value, expected", [
    ("coarse_step", 0, "whole number >= 1 and <= 4096 (rows)"),  # was silently the default
    ("coarse_step", 2.5, "whole number"),  # was accepted
    ("edge_window", 1e9, "whole number >= 3 and <= 255 (px)"),  # made the thesis method find nothing
    ("min_rows", 0, "whole number >= 1"),  # was silently the default
    ("threshold_window", 0, ">= 3"),
    ("threshold_window", 10**9, "<= 4096"),
    ("contrast_window", 1.5, "whole number"),
    ("min_bar_px", 0, ">= 1"),
    ("width_tolerance", 1.0, "< 1"),
    ("max_edge_shift", math.inf, "finite"),
    ("global_threshold", 300, "<= 255 (grey levels)"),
    ("local_contrast", -1, ">= 0"),
    ("min_contrast", float("nan"), "finite"),
    ("min_contrast_ratio", 2.0, "<= 1"),
    ("periodic_tolerance", -0.1, ">= 0"),
    ("aspect_tolerance", 1.5, "< 1"),
    ("max_row_gap", -1, ">= 0"),
    ("max_alpha", 2.0, "< 1.5708"),
    ("uniformity", "20", "finite number"),
    ("max_targets", 0, ">= 1"),
    ("max_candidates", 2.5, "whole number"),
    ("edge_sigma_floor", -0.1, ">= 0"),
    ("reject_periodic", "no", "True or False"),
    ("check_margins", 1, "True or False"),
    ("photometric", "some", "one of off, clipped, auto, all"),
    ("debug_dir", 3, "folder path or None"),
])
def test_nonsense_parameter_refused(cam16, name, value, expected):
    img = np.zeros(cam16.shape, np.uint8)
    for method in ("thesis", "exact"):
        with pytest.raises(ValueError) as e:
            detect_targets(img, cam16, method=method, **{name: value})
        msg = str(e.value)
        assert msg.startswith(f"DetectorParams.{name} must be") and expected in msg and repr(value) in msg, msg


def test_whole_numbers_given_as_floats_become_ints():
    p = DetectorParams(coarse_step=5.0, edge_window=np.int64(11), min_rows=20.0)
    assert (p.coarse_step, p.edge_window, p.min_rows) == (5, 11, 20)
    assert all(type(v) is int for v in (p.coarse_step, p.min_rows))


def test_explicit_values_are_kept_when_resolved():
    p = DetectorParams(coarse_step=1, min_rows=3).resolved(480, 512)
    assert (p.coarse_step, p.min_rows) == (1, 3)
    d = DetectorParams().resolved(480, 512)
    assert (d.coarse_step, d.threshold_window, d.min_rows) == (10, 33, 15)


@pytest.mark.parametrize("window", [3, 9, 31, 255])
def test_any_valid_edge_window_finds_the_target(cam16, window):
    # the neighbourhood of a rough edge stops half way to the next edge, across and along the bars
    from localizer.tools.synthetic import pose_at_column, render_frame

    img = render_frame(cam16, pose_at_column(cam16, 5.0, 0.3), noise=1.0, blur=0.5, rng=np.random.default_rng(2))
    obs = detect_targets(img, cam16, method="thesis", edge_window=window)
    assert len(obs) == 1 and obs[0].distance == pytest.approx(5.0, rel=0.01)
