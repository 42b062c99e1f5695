"""A synthetic world for the filter tests: a corridor of targets, a vehicle driving past them,
odometry with noise drawn from the filter's own model, measurements from h(x) plus R noise."""
from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.filter import (CameraMount, Measurement, OdometryNoise, TargetMap, ViewLimits, arc_motion,
                              compose, predict_all)

MOUNT = CameraMount(forward=0.4, lateral=0.0, yaw=-math.radians(45.0))
LIMITS = ViewLimits(half_fov=math.radians(15.4), min_range=0.5, max_range=10.0,
                    max_incidence=math.radians(70.0), margin=0.0)
NOISE = OdometryNoise(wheel_noise=0.001, track_width=0.6)


def corridor_targets() -> TargetMap:
    """Targets every 6 m on a wall at y = -4 facing north, polarities alternating."""
    xs = np.arange(2.0, 62.0, 6.0)
    return TargetMap(tuple(f"T{i:02d}" for i in range(len(xs))), np.stack([xs, np.full_like(xs, -4.0)], 1),
                     np.full(len(xs), math.pi / 2),
                     tuple("positive" if i % 2 == 0 else "negative" for i in range(len(xs))))


def sigma_model(d: float) -> np.ndarray:
    """(3,) σ of (d, β, α) at distance d (m): the localizer's reported scale."""
    return np.array([max(2.6e-4 * d * d, 5e-4), 2e-5, max(3e-4 * d * d, 5e-4)])


def measure(x, targets: TargetMap, rng: np.random.Generator, floor=(0.002, 3e-4, 2e-3)) -> list[tuple[int, Measurement]]:
    """Noisy measurements of every target in view from true pose x; R includes the floor
    (the filter adds the floor again: pass ``Measurement`` with R minus floor)."""
    Z, vis = predict_all(x, targets, MOUNT, LIMITS)
    out = []
    for j in np.nonzero(vis)[0]:
        s = sigma_model(float(Z[j, 0]))
        R = np.diag(s ** 2)
        full = R + np.diag(np.asarray(floor) ** 2)
        z = Z[j] + rng.multivariate_normal(np.zeros(3), full)
        out.append((int(j), Measurement(z, R, targets.polarities[j])))
    return out


def drive(rng: np.random.Generator, steps: int = 400, v: float = 1.2, dt: float = 0.1, omega: float = 0.0,
          noise: OdometryNoise = NOISE):
    """True poses (steps+1, 3) driving east from (0, 0, 0) and noisy odometry increments (steps, 2).

    The odometry noise is drawn from ``noise.covariance`` itself (a consistent motion model).
    """
    x = np.array([0.0, 0.0, 0.0])
    poses = [x]
    incs = []
    for _ in range(steps):
        ds, dth = v * dt, omega * dt
        x = compose(x, arc_motion(ds, dth))
        poses.append(x)
        vs, c, vt = noise.covariance(ds, dth)
        e = rng.multivariate_normal(np.zeros(2), [[vs, c], [c, vt]])
        incs.append((ds + e[0], dth + e[1]))
    return np.array(poses), np.array(incs)


@pytest.fixture
def targets() -> TargetMap:
    return corridor_targets()
