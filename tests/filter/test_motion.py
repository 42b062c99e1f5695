"""Odometry accumulation: composition, covariance vs Monte Carlo, noise model."""
from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.filter import OdometryAccumulator, OdometryNoise, arc_motion, compose, compose_jacobians


def test_accumulated_motion_equals_stepwise_composition():
    rng = np.random.default_rng(1)
    acc = OdometryAccumulator(OdometryNoise())
    x0 = np.array([1.0, 2.0, 0.7])
    x = x0.copy()
    for _ in range(25):
        ds, dth = rng.uniform(0, 0.15), rng.uniform(-0.1, 0.1)
        acc.add(ds, dth)
        x = compose(x, arc_motion(ds, dth))
    np.testing.assert_allclose(compose(x0, acc.u), x, atol=1e-12)


def test_accumulated_covariance_matches_monte_carlo():
    noise = OdometryNoise(wheel_noise=0.002, track_width=0.6, diameter_bias=0.001, correlation=5.0)
    rng = np.random.default_rng(2)
    incs = [(0.12, 0.03 * math.sin(k / 3.0)) for k in range(30)]
    acc = OdometryAccumulator(noise)
    for ds, dth in incs:
        acc.add(ds, dth)
    n = 4000
    u = np.zeros((n, 3))
    for ds, dth in incs:  # vectorised over the samples: u <- u (+) m(ds + e_s, dth + e_t)
        vs, c, vt = noise.covariance(ds, dth)
        e = rng.multivariate_normal([0, 0], [[vs, c], [c, vt]], size=n)
        s_, t_ = ds + e[:, 0], dth + e[:, 1]
        half = 0.5 * t_
        k = np.sinc(half / np.pi)
        mx, my = s_ * k * np.cos(half), s_ * k * np.sin(half)
        cu, su = np.cos(u[:, 2]), np.sin(u[:, 2])
        u = np.stack([u[:, 0] + cu * mx - su * my, u[:, 1] + su * mx + cu * my, u[:, 2] + t_], axis=1)
    samples = u
    mc = np.cov(np.array(samples).T)
    np.testing.assert_allclose(acc.Q, mc, rtol=0.12, atol=2e-8)


def test_compose_jacobians_finite_differences():
    from scipy.optimize import approx_fprime

    x, u = np.array([1.0, -2.0, 2.5]), np.array([0.4, 0.1, 0.2])
    F, G = compose_jacobians(x, u)
    Fn = np.array([approx_fprime(x, lambda v, i=i: compose(v, u)[i], 1e-7) for i in range(3)])
    Gn = np.array([approx_fprime(u, lambda v, i=i: compose(x, v)[i], 1e-7) for i in range(3)])
    np.testing.assert_allclose(F, Fn, atol=1e-6)
    np.testing.assert_allclose(G, Gn, atol=1e-6)


def test_noise_model_variances():
    n = OdometryNoise(wheel_noise=0.001, track_width=0.5)
    vs, c, vt = n.covariance(1.0, 0.0)
    assert vs == pytest.approx(0.001 ** 2 * 2 / 4)
    assert vt == pytest.approx(0.001 ** 2 * 2 / 0.25)
    assert c == pytest.approx(0.0)
    with pytest.raises(ValueError):
        OdometryNoise(wheel_noise=-1.0)
    with pytest.raises(ValueError):
        OdometryAccumulator(n).add(float("nan"), 0.0)


def _reference_add(q, u, noise, ds, dth):
    """OdometryAccumulator.add as it read before it was written out inline: with
    arc_motion, OdometryNoise.covariance and a quad() helper."""
    mx, my, mphi = arc_motion(ds, dth)
    c, s = math.cos(u[2]), math.sin(u[2])
    f02, f12 = -s * mx - c * my, c * mx - s * my
    a, b, cc, d, e, f = q
    a2 = a + 2 * f02 * cc + f02 * f02 * f
    b2 = b + f02 * e + f12 * cc + f02 * f12 * f
    c2 = cc + f02 * f
    d2 = d + 2 * f12 * e + f12 * f12 * f
    e2 = e + f12 * f
    vs, cst, vt = noise.covariance(ds, dth)
    ch, sh = math.cos(0.5 * dth), math.sin(0.5 * dth)
    gx = (c * ch - s * sh, -0.5 * ds * (c * sh + s * ch))
    gy = (s * ch + c * sh, 0.5 * ds * (c * ch - s * sh))

    def quad(p, r):
        return p[0] * r[0] * vs + (p[0] * r[1] + p[1] * r[0]) * cst + p[1] * r[1] * vt

    gphi = (0.0, 1.0)
    q = [a2 + quad(gx, gx), b2 + quad(gx, gy), c2 + quad(gx, gphi), d2 + quad(gy, gy), e2 + quad(gy, gphi), f + vt]
    return q, [u[0] + (c * mx - s * my), u[1] + (s * mx + c * my), u[2] + mphi]


def test_add_is_arc_motion_and_the_noise_model_to_the_bit():
    noise = OdometryNoise(wheel_noise=0.002, track_width=0.6, diameter_bias=0.001, wheelbase_bias=0.003,
                          scale_bias=0.002, correlation=5.0, inflation=1.5)
    rng = np.random.default_rng(5)
    acc = OdometryAccumulator(noise)
    q, u = [0.0] * 6, [0.0, 0.0, 0.0]
    for k in range(200):
        ds = float(rng.uniform(-0.15, 0.15)) if k % 7 else 0.0
        dth = float(rng.uniform(-0.2, 0.2)) if k % 5 else float(rng.uniform(-1e-5, 1e-5))
        acc.add(ds, dth)
        q, u = _reference_add(q, u, noise, ds, dth)
        assert acc.q == q and [acc.ux, acc.uy, acc.uphi] == u
