"""Whole-target photometric refinement of saturated targets (localizer.photometric)."""
import math

import numpy as np
import pytest

from localizer import Camera, TargetPose, TargetSpec, detect_targets
from localizer.photometric import MARGIN_SHARE, _evaluate, _roi
from localizer.synthetic import in_envelope, render_frame

DEG = math.pi / 180
T = TargetSpec()


def _small_saturated(n, seed):
    """``n`` saturated frames of sharp (blur <= 0.3 px) targets 17-24 rows tall, 16 mm lens."""
    rng = np.random.default_rng(seed)
    cam = Camera.thesis(16.0)
    out = []
    while len(out) < n:
        d = rng.uniform(8.4, 10.0)
        pose = TargetPose(d, rng.uniform(-0.2, 0.2), rng.uniform(-50, 50) * DEG, rng.uniform(-0.3, 0.3))
        if not in_envelope(cam, pose):
            continue
        pol = ("positive", "negative")[len(out) % 2]
        img = render_frame(cam, pose, polarities=pol, lighting="saturated", blur=rng.uniform(0.0, 0.3),
                           noise=rng.uniform(0.5, 2.5), background=0.5, rng=rng)
        out.append((cam, pose, img))
    return out


def test_jacobian_matches_finite_differences(rng):
    cam = Camera.thesis(16.0)
    pose = TargetPose(6.0, 0.05, 25 * DEG, 0.1)
    img = render_frame(cam, pose, lighting="normal", blur=0.6, noise=1.0, background=0.5, rng=rng)
    c = pose.centre
    for positive in (True, False):
        p = np.array([c[0], c[2], pose.alpha, c[1], 20.0, 230.0, 0.6])
        cols, rlo, rhi = _roi(p, img.shape[0], img.shape[1], cam.fx, cam.fy, cam.cx, cam.cy, T.bar_width,
                              T.bar_height, T.margin, MARGIN_SHARE)
        obs = np.concatenate([img[rlo[i]:rhi[i] + 1, cols[i]].astype(float) for i in range(cols.size)])
        args = (obs, cols, rlo, rhi, cam.fx, cam.fy, cam.cx, cam.cy, T.bar_width, T.bar_height, positive)
        n = obs.size
        res = np.empty(n)
        J = np.empty((n, 7))
        _evaluate(p, *args, res, J, True)
        steps = [1e-6 * p[1], 1e-6 * p[1], 1e-6, 1e-6 * p[1], 1e-4, 1e-4, 1e-6]
        for k, h in enumerate(steps):
            rp, rm = np.empty(n), np.empty(n)
            qp, qm = p.copy(), p.copy()
            qp[k] += h
            qm[k] -= h
            _evaluate(qp, *args, rp, J.copy(), False)
            _evaluate(qm, *args, rm, J.copy(), False)
            fd = (rp - rm) / (2 * h)
            # the model is piecewise smooth (box pixels): compare where both agree on smoothness
            assert np.median(np.abs(J[:, k] - fd)) <= 1e-4 * np.abs(fd).max()
            assert np.abs(J[:, k] - fd).max() <= 0.05 * np.abs(fd).max()


def test_small_sharp_saturated_targets_within_floor():
    """Clipped, sharp targets ~20 rows tall: the edge-based pose alone misses the 2 % distance
    floor on some of them (the clipped pixels hide ~0.6 px of each edge); the whole-target
    fit uses every pixel and the levels shared by all edges."""
    refined, edge_only = [], []
    for cam, pose, img in _small_saturated(16, seed=7):
        for store, kw in ((refined, {}), (edge_only, {"photometric_max_rows": 0})):
            obs = [o for o in detect_targets(img, cam, **kw) if abs(o.beta - pose.beta) < 0.02]
            assert len(obs) == 1
            store.append(abs(obs[0].distance / pose.distance - 1))
    refined, edge_only = np.array(refined), np.array(edge_only)
    assert refined.max() < 0.02
    assert refined.mean() < 0.004
    assert refined.mean() < 0.5 * edge_only.mean()


def test_refinement_is_off_for_normal_light(rng):
    cam = Camera.thesis(16.0)
    pose = TargetPose(9.0, 0.0, 20 * DEG, 0.0)
    img = render_frame(cam, pose, lighting="normal", blur=0.5, noise=1.0, background=0.5, rng=rng)
    a = detect_targets(img, cam)[0]
    b = detect_targets(img, cam, photometric_max_rows=0)[0]
    assert a.distance == b.distance and a.alpha == b.alpha
