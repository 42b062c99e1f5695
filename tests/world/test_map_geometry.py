"""Plane geometry behind the map checks, against brute force."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agvsim.world import geometry as geo

coord = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)
pt = st.tuples(coord, coord).map(np.array)


def sampled_distance(p0, p1, a, b, n=400):
    """Distance between two segments by dense sampling (an upper bound, close for n large)."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    u = p0 + s * (p1 - p0)
    v = a + s * (b - a)
    return float(np.min(np.linalg.norm(u[:, None, :] - v[None, :, :], axis=2)))


@settings(max_examples=60, deadline=None)
@given(pt, pt, pt, pt)
def test_segment_distance_matches_sampling(p0, p1, a, b):
    d = geo.segment_segment_distance(p0, p1, a[None], b[None])[0]
    approx = sampled_distance(p0, p1, a, b)
    step = (np.linalg.norm(p1 - p0) + np.linalg.norm(b - a)) / 399
    assert d <= approx + 1e-9
    assert d >= approx - step - 1e-9


@settings(max_examples=60, deadline=None)
@given(pt, pt, pt, pt)
def test_segment_distance_is_symmetric(p0, p1, a, b):
    d1 = geo.segment_segment_distance(p0, p1, a[None], b[None])[0]
    d2 = geo.segment_segment_distance(a, b, p0[None], p1[None])[0]
    assert d1 == pytest.approx(d2, abs=1e-9)


def test_crossing_and_touching_segments_are_at_distance_zero():
    segs_a = np.array([[0.0, -1.0], [1.0, 0.0], [2.0, 0.0]])
    segs_b = np.array([[0.0, 1.0], [1.0, 1.0], [3.0, 0.0]])
    d = geo.segment_segment_distance([-1.0, 0.0], [1.0, 0.0], segs_a, segs_b)
    np.testing.assert_allclose(d, [0.0, 0.0, 1.0])


def test_point_in_polygon_concave():
    # a U shape: the notch (1..2, 1..3) is outside
    u = np.array([[0, 0], [3, 0], [3, 3], [2, 3], [2, 1], [1, 1], [1, 3], [0, 3]], dtype=float)
    inside = geo.points_in_polygon([[0.5, 2.0], [1.5, 2.0], [2.5, 2.0], [1.5, 0.5], [4, 1]], u)
    assert inside.tolist() == [True, False, True, True, False]


def test_self_intersection():
    assert geo.polygon_self_intersection([[0, 0], [1, 0], [1, 1], [0, 1]]) is None
    assert geo.polygon_self_intersection([[0, 0], [1, 1], [1, 0], [0, 1]]) is not None  # bow tie
    assert geo.polygon_self_intersection([[0, 0], [2, 0], [1, 0], [1, 1]]) is not None  # folds back


def test_box_polygon_is_counter_clockwise_and_rotated():
    box = geo.box_polygon([1.0, 2.0], [4.0, 2.0], math.pi / 2)
    assert geo.polygon_signed_area(box) == pytest.approx(8.0)
    np.testing.assert_allclose(box.min(axis=0), [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(box.max(axis=0), [2.0, 4.0], atol=1e-12)


def test_segment_enters_polygon():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    assert geo.segment_enters_polygon([-1, 0.5], [2, 0.5], square)  # straight through
    assert geo.segment_enters_polygon([-1, -1], [2, 2], square)  # through two corners
    assert not geo.segment_enters_polygon([-1, 0], [2, 0], square)  # along an edge
    assert not geo.segment_enters_polygon([-1, 1], [1, 3], square)  # grazes a corner
    assert geo.segment_enters_polygon([0.5, 0.5], [0.6, 0.6], square)  # wholly inside


def test_the_float_segment_distances_are_numpys_to_the_bit():
    """``segment_segment_distances_xy`` (line of sight, a few segments) is
    ``segment_segment_distance`` on floats: the same values, bit for bit."""
    rng = np.random.default_rng(0)
    for k in range(600):
        n = int(rng.integers(1, 6))
        shape = (2 + 2 * n, 2)
        # every third case on a coarse grid: touching, collinear and degenerate segments
        pts = rng.integers(-3, 4, shape).astype(float) if k % 3 == 0 else rng.uniform(-5, 5, shape)
        segs = pts[2:].reshape(n, 2, 2)
        expected = geo.segment_segment_distance(pts[0], pts[1], segs[:, 0], segs[:, 1])
        got = geo.segment_segment_distances_xy(pts[0].tolist(), pts[1].tolist(), segs.tolist())
        assert got == expected.tolist()
