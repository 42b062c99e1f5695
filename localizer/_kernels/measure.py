"""The per-target path of ``detect_targets`` for an undistorted camera, fused in one call.

Subpixel edges (:func:`localizer._kernels.subpixel.subpixel`), the target test
(:func:`localizer._kernels.target_test.makes_target`) and the exact pose fit
(:func:`localizer._kernels.exact_pose.fit`) of one verified stack: Python between
these steps cost as much as the steps.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit
from localizer._kernels.exact_pose import fit
from localizer._kernels.records import ExactResult, FitStatus, PoseValues
from localizer._kernels.subpixel import edge_rows, subpixel
from localizer._kernels.target_test import makes_target


@jit
def exact_measure(image, stack_rows, bounds, ends, positive, cam, target, settings):
    """:func:`localizer.exact_pose.exact_measure`'s compiled body.

    Args:
        image: ``(H, W)`` uint8 frame.
        stack_rows: ``(n,)`` int64 rows of the verified stack.
        bounds: ``(4,)`` float median run boundaries of the stack (columns).
        ends: ``((top1, bottom1), (top2, bottom2))`` rough bar ends (rows).
        positive: target polarity (black bars on white).
        cam: :class:`~localizer._kernels.records.Intrinsics` (px).
        target: :class:`~localizer._kernels.records.TargetConstants` (m).
        settings: :class:`~localizer._kernels.records.ExactSettings`.

    Returns an :class:`~localizer._kernels.records.ExactResult`: ``found`` False when the
    edges do not make a target or no fit converged (the pose is then zeros and the
    covariance the identity); the edges (px) in either case.
    """
    e = np.empty((2, 2), np.int64)
    e[0, 0], e[0, 1], e[1, 0], e[1, 1] = ends[0][0], ends[0][1], ends[1][0], ends[1][1]
    rows = edge_rows(stack_rows)
    m, _, _, _ = subpixel(image, rows, bounds, e, positive)
    edges, cxs, top, bot = m.edges, m.bar_cx, m.top, m.bottom
    none = PoseValues(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0.0)
    out = ((edges[0], edges[1], edges[2], edges[3]), (cxs[0], cxs[1]), (top[0], top[1]), (bot[0], bot[1]))
    if not makes_target(edges[0], edges[1], edges[2], edges[3], bot[0] - top[0], bot[1] - top[1],
                        settings.width_tolerance, settings.width_slack, settings.min_rows):
        return ExactResult(False, out[0], out[1], out[2], out[3], none, np.eye(3))
    f = fit(m, cam, target, positive, settings.sigma_floor, settings.iterations)
    if f.status != FitStatus.FITTED:
        return ExactResult(False, out[0], out[1], out[2], out[3], none, np.eye(3))
    p = f.p
    pose = PoseValues(math.hypot(p[0], p[1]), math.atan2(p[0], p[1]), p[2], p[1], p[0], p[3], p[4], f.alpha1,
                      f.alpha2, f.n_solutions, f.chi2)
    return ExactResult(True, out[0], out[1], out[2], out[3], pose, f.cov)
