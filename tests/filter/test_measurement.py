"""Measurement model: conventions, Jacobians vs finite differences, inverse."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import approx_fprime

from localizer.filter import (CameraMount, Measurement, TargetMap, measurement_jacobian, pose_from_measurement,
                              pose_from_measurement_jacobian, predict_all, predict_measurement, wrap_angle)

angles = st.floats(-math.pi, math.pi)
coords = st.floats(-20.0, 20.0)
mounts = st.builds(lambda f, l, y: CameraMount(forward=f, lateral=l, yaw=y), st.floats(-1, 1), st.floats(-1, 1), angles)


def _numeric(f, x, eps=1e-6):
    x = np.asarray(x, dtype=float)
    return np.array([approx_fprime(x, lambda v, i=i: float(f(v)[i]), eps) for i in range(3)])


def test_conventions_match_localizer_geometry():
    mount = CameraMount(forward=0.0, lateral=0.0, yaw=0.0)  # camera at the vehicle origin looking along +x
    # a target 5 m ahead facing the camera squarely: d = 5, β = 0, α = 0
    z = predict_measurement([0, 0, 0], [5.0, 0.0], math.pi, mount)
    np.testing.assert_allclose(z, [5.0, 0.0, 0.0], atol=1e-12)
    # target to the right of the axis (negative map y when looking along +x): β > 0
    z = predict_measurement([0, 0, 0], [5.0, -1.0], math.pi, mount)
    assert z[1] > 0
    # a target squarely facing the camera from the right: α == β (geometry.py)
    t = np.array([5.0, -2.0])
    yaw = math.atan2(-t[1], -t[0])  # faces the lens
    z = predict_measurement([0, 0, 0], t, yaw, mount)
    assert z[2] == pytest.approx(z[1], abs=1e-12)
    # the target turned so its right edge (as the camera sees it, map -y side) comes nearer: α > 0
    z = predict_measurement([0, 0, 0], [5.0, 0.0], math.pi - 0.3, mount)
    assert z[2] == pytest.approx(0.3)


@settings(max_examples=60, deadline=None)
@given(coords, coords, angles, coords, coords, angles, mounts)
def test_jacobian_matches_finite_differences(px, py, th, tx, ty, tyaw, mount):
    x = np.array([px, py, th])
    t = np.array([tx, ty])
    z = predict_measurement(x, t, tyaw, mount)
    if z[0] < 0.5 or abs(abs(z[1]) - math.pi) < 0.1 or abs(abs(z[2]) - math.pi) < 0.1:
        return  # near the lens or at the wrap-around of an angle
    H = measurement_jacobian(x, t, tyaw, mount)
    Hn = _numeric(lambda v: predict_measurement(v, t, tyaw, mount), x)
    np.testing.assert_allclose(H, Hn, atol=2e-5 * max(1.0, 1.0 / z[0] ** 2))


@settings(max_examples=60, deadline=None)
@given(coords, coords, angles, coords, coords, angles, mounts)
def test_inverse_and_its_jacobian(px, py, th, tx, ty, tyaw, mount):
    x = np.array([px, py, th])
    t = np.array([tx, ty])
    z = predict_measurement(x, t, tyaw, mount)
    if z[0] < 0.5:
        return
    back = pose_from_measurement(z, t, tyaw, mount)
    if abs(abs(back[2]) - math.pi) < 0.1:
        return  # at the wrap-around of θ (finite differences would jump by 2π)
    np.testing.assert_allclose(back[:2], x[:2], atol=1e-9)
    assert wrap_angle(float(back[2] - th)) == pytest.approx(0.0, abs=1e-9)
    J = pose_from_measurement_jacobian(z, t, tyaw, mount)
    Jn = _numeric(lambda v: pose_from_measurement(v, t, tyaw, mount), z)
    np.testing.assert_allclose(J, Jn, atol=2e-5 * max(1.0, z[0]))


def test_predict_all_view_limits():
    from localizer.filter import ViewLimits

    tm = TargetMap(("A", "B", "C", "D"), [[5, 0], [5, 3], [5, 0.5], [50, 0]], [math.pi, math.pi, 0.0, math.pi])
    Z, vis = predict_all([0, 0, 0], tm, CameraMount(forward=0.0), ViewLimits(margin=0.0))
    assert vis.tolist() == [True, False, False, False]  # B outside FOV, C faces away, D too far
    np.testing.assert_allclose(Z[0], [5, 0, 0], atol=1e-12)


def test_bad_inputs_raise():
    with pytest.raises(ValueError):
        TargetMap(("A",), [[0, 0], [1, 1]], [0.0])
    with pytest.raises(ValueError):
        TargetMap(("A", "A"), [[0, 0], [1, 1]], [0.0, 0.0])
    with pytest.raises(ValueError):
        TargetMap(("A",), [[0, 0]], [0.0], ("grey",))
    with pytest.raises(ValueError):
        Measurement([1.0, 0.0], np.eye(3))
    with pytest.raises(ValueError):
        Measurement([-1.0, 0.0, 0.0], np.eye(3))
    with pytest.raises(ValueError):
        CameraMount(forward=float("nan"))
    with pytest.raises(ValueError):
        measurement_jacobian([1.0, 0.0, 0.0], [1.0, 0.0], 0.0, CameraMount(forward=0.0))


def test_localizer_does_not_import_agvsim():
    import pathlib

    root = pathlib.Path(__file__).resolve().parents[2] / "localizer" / "filter"
    for path in root.glob("*.py"):
        text = path.read_text()
        assert "import agvsim" not in text and "from agvsim" not in text, path
        assert "import envs" not in text and "from envs" not in text, path
