"""The world and the hostile inputs of ``agvsim bench filter-soak`` (:mod:`agvsim.bench.filter_soak`).

The hall (50 m x 24 m, targets at irregular places on its walls), the oval the vehicle drives,
and the frames and odometry calls offered to the filter: consistent observations with the
localizer's scale of σ, and the hostile kinds of :data:`FRAME_KINDS` and :data:`ODOMETRY_GARBAGE`.
Everything random comes from the ``numpy.random.Generator`` passed in.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["DT", "FRAME_KINDS", "Frames", "HALL", "LAP", "ODOMETRY_GARBAGE", "Raw", "SPEED", "in_hall",
           "odometry_garbage", "oval", "sigma_model", "turn", "world"]

DT = 0.02  # s, control step
SPEED = 1.0  # m/s
RADIUS = 6.0  # m, the oval's half circles
STRAIGHT = 30.0  # m, the oval's straights
LAP = 2.0 * STRAIGHT + 2.0 * math.pi * RADIUS  # m
HALL = (-10.0, -12.0, 40.0, 12.0)  # m, xmin, ymin, xmax, ymax
#: the kinds of frame and their shares
FRAME_KINDS = {"consistent": 0.58, "garbage": 0.05, "loose_garbage": 0.04, "scaled": 0.08, "near_singular": 0.05,
               "non_psd": 0.04, "nan_field": 0.04, "empty": 0.05, "bad_time": 0.04, "mixed": 0.03}
#: bogus odometry calls: (name, expected refusal reason)
ODOMETRY_GARBAGE = (("t_nan", "odometry_time"), ("t_inf", "odometry_time"), ("t_decreasing", "odometry_time"),
                    ("ds_nan", "odometry_increment"), ("ds_inf", "odometry_increment"),
                    ("ds_huge", "odometry_increment"), ("ds_1e200", "odometry_increment"),
                    ("turn_huge", "odometry_increment"), ("contact_not_bool", "odometry_contact"))


def odometry_garbage(name: str, t: float) -> tuple:
    """The arguments of ``PoseEKF.add_odometry`` for the bogus call ``name`` at time ``t`` (s)."""
    return {"t_nan": (math.nan, 0.01, 0.0), "t_inf": (math.inf, 0.01, 0.0), "t_decreasing": (t - 1.0, 0.01, 0.0),
            "ds_nan": (t, math.nan, 0.0), "ds_inf": (t, -math.inf, 0.0), "ds_huge": (t, 11.0, 0.0),
            "ds_1e200": (t, 1e200, 0.0), "turn_huge": (t, 0.01, 1e3), "contact_not_bool": (t, 0.01, 0.0, "yes")}[name]


@dataclass(frozen=True)
class Raw:
    """An observation as a detector might hand it over (the filter checks it)."""

    distance: float
    beta: float
    alpha: float
    covariance: object
    polarity: str | None


def world(seed: int):
    """``(targets, mount, config)``: the hall's targets, a camera looking 45° right of ahead,
    the filter's settings (the view limits of a 16 mm lens to 10 m)."""
    from localizer.filter import CameraMount, FilterConfig, GateConfig, OdometryNoise, TargetMap, ViewLimits

    rng = np.random.default_rng([seed, 1])
    xmin, ymin, xmax, ymax = HALL
    ids, pos, yaws = [], [], []
    walls = (((xmin, ymin), (xmax, ymin), math.pi / 2), ((xmax, ymin), (xmax, ymax), math.pi),
             ((xmax, ymax), (xmin, ymax), -math.pi / 2), ((xmin, ymax), (xmin, ymin), 0.0))
    for (ax, ay), (bx, by), yaw in walls:
        length = math.hypot(bx - ax, by - ay)
        s = rng.uniform(0.5, 3.0)
        while s < length - 0.5:
            f = s / length
            ids.append(f"W{len(ids):02d}")
            pos.append((ax + f * (bx - ax), ay + f * (by - ay)))
            yaws.append(yaw)
            s += rng.uniform(1.5, 6.0)
    pols = tuple(str(p) for p in rng.choice(["positive", "negative"], len(ids)))
    targets = TargetMap(tuple(ids), np.array(pos), np.array(yaws), pols)
    mount = CameraMount(forward=0.4, lateral=0.0, yaw=-math.radians(45.0))
    limits = ViewLimits(half_fov=math.radians(15.4), min_range=0.5, max_range=10.0,
                        max_incidence=math.radians(70.0), margin=0.0)
    config = FilterConfig(noise=OdometryNoise(wheel_noise=0.001, track_width=0.6), gate=GateConfig(view=limits))
    return targets, mount, config


def oval(s: float) -> tuple[float, float, float]:
    """The pose (m, m, rad) at arc length ``s`` (m) along the oval, counter-clockwise from (0, -6)."""
    s %= LAP
    half = math.pi * RADIUS
    if s < STRAIGHT:
        return s, -RADIUS, 0.0
    if s < STRAIGHT + half:
        a = (s - STRAIGHT) / RADIUS
        return STRAIGHT + RADIUS * math.sin(a), -RADIUS * math.cos(a), a
    if s < 2 * STRAIGHT + half:
        return STRAIGHT - (s - STRAIGHT - half), RADIUS, math.pi
    a = (s - 2 * STRAIGHT - half) / RADIUS
    return -RADIUS * math.sin(a), RADIUS * math.cos(a), math.pi + a


def turn(s: float, ds: float) -> float:
    """The heading change (rad) over arc length ``s .. s + ds`` of the oval (its curved part / R)."""
    s %= LAP
    half = math.pi * RADIUS
    curved = 0.0
    for a, b in ((STRAIGHT, STRAIGHT + half), (2 * STRAIGHT + half, LAP)):  # (a step past LAP is straight)
        curved += max(0.0, min(s + ds, b) - max(s, a))
    return curved / RADIUS


def in_hall(x: float, y: float) -> bool:
    """Whether (x m, y m) is free space: inside the hall, 0.5 m from its walls."""
    return HALL[0] + 0.5 <= x <= HALL[2] - 0.5 and HALL[1] + 0.5 <= y <= HALL[3] - 0.5


def sigma_model(d: float) -> np.ndarray:
    """(3,) σ of (d m, β rad, α rad) at distance ``d`` (m): the localizer's reported scale."""
    return np.array([max(2.6e-4 * d * d, 5e-4), 2e-5, max(3e-4 * d * d, 5e-4)])


class Frames:
    """The frames seen from a true pose: consistent, or of a hostile kind (:data:`FRAME_KINDS`).

    Args:
        rng: the run's generator.
        targets, mount, config: the world (:func:`world`).
    """

    def __init__(self, rng: np.random.Generator, targets, mount, config) -> None:
        self.rng, self.targets, self.mount, self.config = rng, targets, mount, config
        self.floor = np.diag(np.asarray(config.measurement_floor) ** 2)

    def consistent(self, x) -> list:
        from localizer.filter import Measurement, predict_all

        Z, vis = predict_all(x, self.targets, self.mount, self.config.gate.view)
        out = []
        for j in np.nonzero(vis)[0]:
            R = np.diag(sigma_model(float(Z[j, 0])) ** 2)
            z = Z[j] + np.sqrt(np.diag(R + self.floor)) * self.rng.standard_normal(3)
            out.append(Measurement(z, R, self.targets.polarities[j]))
        return out

    def hostile(self, kind: str, x) -> tuple[list, str | None]:
        """A frame of ``kind`` seen from the true pose ``x``, and the reason it must be refused
        for (None: it must be fused)."""
        from localizer.filter import Measurement
        from localizer.filter.measurement import MAX_MEASUREMENT_SIGMA

        rng = self.rng
        good = self.consistent(x)
        pol = lambda: str(rng.choice(["positive", "negative"]))  # noqa: E731
        off = lambda m: np.abs(m.z + rng.normal(0, 1, 3) * [3.0, 0.1, 0.3]) + [0.01, 0, 0]  # noqa: E731
        if kind == "consistent":
            return good, None
        if kind == "empty":
            return [], None
        if kind in ("garbage", "loose_garbage"):
            sig = [0.01, 1e-4, 0.01] if kind == "garbage" else 0.99 * np.array(MAX_MEASUREMENT_SIGMA)
            return [Measurement([rng.uniform(0.6, 11), rng.uniform(-0.3, 0.3), rng.uniform(-1.2, 1.2)],
                                np.diag(np.square(sig)), pol()) for _ in range(int(rng.integers(1, 4)))], None
        if kind == "scaled":
            return [Measurement(off(m) if rng.random() < 0.5 else m.z, m.R * 10.0 ** rng.uniform(3, 300), m.polarity)
                    for m in good], None
        if kind == "near_singular":
            out = []
            for m in good:
                u = rng.normal(size=3)
                R = np.outer(u, u) * 10.0 ** rng.uniform(-8, 4) + np.eye(3) * 10.0 ** rng.uniform(-300, -12)
                out.append(Measurement(off(m) if rng.random() < 0.5 else m.z, R, m.polarity))
            return out, None
        if kind == "mixed":
            mixed = good + self.hostile("garbage", x)[0] + self.hostile("scaled", x)[0]
            return [mixed[k] for k in rng.permutation(len(mixed))], None
        # refused whole: one bad observation among good ones
        z = good[0].z if good else np.array([5.0, 0.1, 0.2])
        R = np.diag([1e-4, 1e-8, 1e-4])
        if kind == "non_psd":
            R = [-np.eye(3) * 1e-4, np.diag([1e-4, -1e-8, 1e-4]), np.array([[1e-4, 1e-2, 0], [1e-2, 1e-4, 0],
                                                                            [0, 0, 1e-4]]),
                 np.array([[1e-4, 0, 0], [1e-3, 1e-4, 0], [0, 0, 1e-4]])][int(rng.integers(4))]
            bad = Raw(z[0], z[1], z[2], R, pol())
        else:  # nan_field
            k = int(rng.integers(5))
            vals = [z[0], z[1], z[2]]
            if k < 3:
                vals[k] = [math.nan, math.inf, -math.inf][int(rng.integers(3))]
            else:
                R = R.copy()
                R[int(rng.integers(3)), int(rng.integers(3))] = math.nan if k == 3 else math.inf
            bad = Raw(*vals, R, pol())
        obs = list(good)
        obs.insert(int(rng.integers(len(obs) + 1)), bad)
        return obs, "measurement_invalid"
