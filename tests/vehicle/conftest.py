"""Shared helpers for the vehicle tests: bare worlds and open-loop drivers."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from agvsim.vehicle.simulation import SimConfig, Simulation
from agvsim.vehicle.encoders import OdometryErrorModel


def bare_world(walls=(), obstacles=()):
    """A world with only the given walls ((id, [[x,y],...], thickness)) and
    obstacles ((id, [[x,y],...])) — what :func:`agvsim.vehicle.physics.build_space` reads."""
    return SimpleNamespace(
        walls=[SimpleNamespace(id=i, points=np.asarray(p, float), thickness=t) for i, p, t in walls],
        obstacles=[SimpleNamespace(id=i, polygon=np.asarray(p, float)) for i, p in obstacles],
    )


def make_sim(odometry="ideal", seed=0, world=None, pose=(0.0, 0.0, 0.0), **config):
    model = odometry if isinstance(odometry, OdometryErrorModel) else OdometryErrorModel.preset(odometry)
    return Simulation(world or bare_world(), pose, SimConfig(odometry=model, **config),
                      np.random.default_rng(seed))


def wrap(a):
    return math.atan2(math.sin(a), math.cos(a))


def drive_straight(sim, length, speed=1.0):
    """Drive ``length`` m along the current true heading, steering on truth."""
    x0, y0, th0 = sim.true_pose
    for _ in range(5000):
        x, y, th = sim.true_pose
        along = (x - x0) * math.cos(th0) + (y - y0) * math.sin(th0)
        lateral = -(x - x0) * math.sin(th0) + (y - y0) * math.cos(th0)
        remaining = length - along
        if remaining < 0.005:
            break
        v = max(0.05, min(speed, math.sqrt(2 * 0.5 * remaining)))
        w = -2.0 * wrap(th - th0) - 1.0 * lateral
        sim.step(v, w)
    else:
        raise AssertionError("drive_straight did not converge")
    _settle(sim)


def turn_in_place(sim, angle, rate=0.8):
    """Rotate by ``angle`` rad on the spot, steering on truth."""
    target = sim.true_pose[2] + angle
    for _ in range(2000):
        err = target - sim.true_pose[2]
        if abs(err) < 1e-4:
            break
        w = math.copysign(min(rate, math.sqrt(2 * 2.5 * abs(err)), 4.0 * abs(err)), err)
        sim.step(0.0, w)
    else:
        raise AssertionError("turn_in_place did not converge")
    _settle(sim)


def _settle(sim):
    for _ in range(20):
        sim.step(0.0, 0.0)


@pytest.fixture
def world():
    return bare_world()
