import math

import numpy as np
import pytest

from localizer import TargetPose
from localizer.tools.synthetic import quad_coverage, in_envelope, render_reflectance, target_outline


def testquad_coverage_is_exact_area():
    # trapezoid with vertical sides at x = 10.3 and 30.7, slanted top and bottom
    xl, xr, ytl, ytr, ybl, ybr = 10.3, 30.7, 5.2, 8.9, 40.1, 36.6
    r0, c0, cov = quad_coverage(60, 60, xl, xr, ytl, ytr, ybl, ybr)
    area = (xr - xl) * ((ybl - ytl) + (ybr - ytr)) / 2
    assert cov.sum() == pytest.approx(area, rel=1e-4)
    # column 20 (fully inside in x) sums to the exact local height
    t = (20 - xl) / (xr - xl)
    assert cov[:, 20 - c0].sum() == pytest.approx((ybl - ytl) + t * ((ybr - ytr) - (ybl - ytl)), abs=2e-3)
    # partial first column: fraction of pixel 10 right of x = 10.3
    assert cov[20 - r0, 10 - c0] == pytest.approx(0.2, abs=1e-9)


def test_rendered_bars_sit_at_projected_edges(cam16):
    pose = TargetPose(2.0, 0.05, math.radians(30), 0.0)
    g = target_outline(cam16, pose)
    refl = render_reflectance(cam16, [pose], background=0.5)
    row = refl[240]
    # the left bar's left edge lies inside pixel j with coverage equal to the overlap
    e = g["edges_x"][0]
    j = int(math.floor(e + 0.5))
    frac_bar = (j + 0.5) - e
    assert row[j] == pytest.approx(0.9 + (0.06 - 0.9) * frac_bar, abs=1e-6)
    assert g["bar_heights"][1] > g["bar_heights"][0]  # alpha > 0: right bar nearer


def test_alpha_equals_beta_faces_camera(cam16):
    # alpha == beta: the target normal points at the lens, both outer edges equally far
    beta = 0.12
    pose = TargetPose(3.0, beta, beta)
    left, right = pose.points([-0.1125, 0.1125], [0.0, 0.0])
    assert np.linalg.norm(left) == pytest.approx(np.linalg.norm(right), rel=1e-12)
    # alpha > 0 means the right edge is nearer along the optical axis (smaller z)
    assert right[2] < left[2]
    assert TargetPose(3.0, 0.0, 0.0).points([-0.1, 0.1], [0, 0])[:, 2].tolist() == [3.0, 3.0]


def test_envelope(cam16):
    assert in_envelope(cam16, TargetPose(5.0, 0.0, 0.3))
    assert not in_envelope(cam16, TargetPose(12.0, 0.0, 0.0))  # bars shorter than 16 rows
    assert not in_envelope(cam16, TargetPose(2.0, 0.26, 0.0))  # out of view
