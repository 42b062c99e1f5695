"""The photometric refinement's kernels: the one-exp normal CDF, the closed-form blurred step
with shared pixel sides, the normal equations, the pixel selection and the fit's starts."""
import math

import numpy as np
from numba import njit

from localizer import Camera, TargetPose, TargetSpec
from localizer._kernels.blur import ANALYTIC_SD, blur_weights, closed_step, edge_fraction, gauss_cdf_pdf
from localizer._kernels.photometric import (ITERATIONS, MARGIN_SHARE, MAX_LINES, MIRROR_GIVE_UP, NP, REACH, SIGMA_MAX,
                                            START_ITERATIONS, START_TOL, TOL, evaluate, lm, normal_equations, select)
from localizer._kernels.records import FitEnds, FitRun, Intrinsics, TargetConstants
from localizer.tools.synthetic import render_frame

DEG = math.pi / 180
T = TargetSpec()


@njit
def _cdf_pdf(u):
    out = np.empty((u.size, 2))
    for i in range(u.size):
        out[i, 0], out[i, 1] = gauss_cdf_pdf(u[i])
    return out


@njit
def _closed(j, e, sd, shared_rows):
    """closed_step over rows ``j`` (consecutive when ``shared_rows``), as the model calls it."""
    out = np.empty((j.size, 3))
    reach = 4.5 * sd + 1.0
    u = c = p = 0.0
    ok = False
    for i in range(j.size):
        share = shared_rows and i > 0 and ok
        out[i, 0], out[i, 1], out[i, 2], u, c, p, ok = closed_step(j[i], e, sd, reach, share, u, c, p)
    return out


@njit
def _reference(j, e, sd):
    """``edge_fraction`` (the blurred step through ``math.erf``, with the same cut-off)."""
    w, dw = blur_weights(sd)
    out = np.empty((j.size, 3))
    for i in range(j.size):
        out[i, 0], out[i, 1], out[i, 2] = edge_fraction(j[i], e, w, dw)
    return out


def test_normal_cdf_and_density_errors():
    u = np.concatenate([np.linspace(-40.0, 40.0, 400_001), np.geomspace(1e-12, 10.0, 2_000)])
    u = np.concatenate([u, -u])
    got = _cdf_pdf(u)
    cdf = np.array([0.5 * math.erfc(-x / math.sqrt(2.0)) for x in u])
    pdf = np.exp(-0.5 * u * u) / math.sqrt(2.0 * math.pi)
    assert np.abs(got[:, 0] - cdf).max() < 1.5e-10
    assert np.abs(got[:, 1] - pdf).max() < 1e-15
    assert np.all(np.diff(got[np.argsort(u), 0]) >= -3e-10)  # monotone to within its error
    assert np.all((got[:, 0] >= 0.0) & (got[:, 0] <= 1.0))


def test_closed_step_matches_the_erf_form_and_shares_sides_exactly():
    rows = np.arange(-30, 31, dtype=np.int64)
    for sd in (ANALYTIC_SD, 1.7, 3.0):
        for e in (-0.37, 0.0, 0.5, 2.25):
            ref = _reference(rows, e, sd)
            alone = _closed(rows, e, sd, False)
            shared = _closed(rows, e, sd, True)
            assert np.abs(alone - ref).max() < 1e-8
            assert np.abs(shared - alone).max() < 1e-15


def test_closed_step_derivatives_match_finite_differences():
    rows = np.arange(-12, 13, dtype=np.int64)
    for sd in (1.2, 2.5):
        for e in (-0.3, 0.8):
            f = _closed(rows, e, sd, True)
            h = 1e-6
            de = (_closed(rows, e + h, sd, True)[:, 0] - _closed(rows, e - h, sd, True)[:, 0]) / (2 * h)
            ds = (_closed(rows, e, sd + h, True)[:, 0] - _closed(rows, e, sd - h, True)[:, 0]) / (2 * h)
            assert np.abs(f[:, 1] - de).max() < 1e-7
            assert np.abs(f[:, 2] - ds).max() < 1e-7


def _setup(rng, blur, lighting="normal"):
    cam = Camera.thesis(16.0)
    pose = TargetPose(6.0, 0.05, 25 * DEG, 0.1)
    img = render_frame(cam, pose, lighting=lighting, blur=blur, noise=1.0, background=0.5, rng=rng)
    c = pose.centre
    intr = Intrinsics(cam.fx, cam.fy, cam.cx, cam.cy)
    tc = TargetConstants(T.bar_width, T.bar_height, T.margin)
    p = np.array([c[0], c[2], pose.alpha, c[1], 20.0, 230.0 if lighting == "normal" else 300.0, blur, 0.0])
    sel = select(p, img.shape, intr, tc, MARGIN_SHARE, REACH, MAX_LINES)
    obs = img[sel.pr, sel.ucols[sel.pci]].astype(float)
    return p, obs, sel, intr, tc


def test_closed_form_jacobian_matches_finite_differences(rng):
    p, obs, sel, intr, tc = _setup(rng, 2.0)
    p[7] = 0.04  # light falling off across the target: every column of J scales with it
    n = obs.size
    for positive in (True, False):
        args = (obs, sel, intr, tc, positive)
        res, J = np.empty(n), np.empty((n, NP))
        evaluate(p, *args, res, J, True)
        steps = [1e-6 * p[1], 1e-6 * p[1], 1e-6, 1e-6 * p[1], 1e-4, 1e-4, 1e-6, 1e-6]
        for k, h in enumerate(steps):
            rp, rm = np.empty(n), np.empty(n)
            qp, qm = p.copy(), p.copy()
            qp[k] += h
            qm[k] -= h
            evaluate(qp, *args, rp, J.copy(), False)
            evaluate(qm, *args, rm, J.copy(), False)
            fd = (rp - rm) / (2 * h)
            assert np.abs(J[:, k] - fd).max() <= 1e-5 * np.abs(fd).max()


def test_normal_equations_are_those_of_the_jacobian(rng):
    for blur, lighting in ((0.5, "saturated"), (2.0, "normal")):
        p, obs, sel, intr, tc = _setup(rng, blur, lighting)
        n = obs.size
        for positive in (True, False):
            res, J = np.empty(n), np.empty((n, NP))
            cost = evaluate(p, obs, sel, intr, tc, positive, res, J, True)
            c2, A, g = normal_equations(p, obs, sel, intr, tc, positive, np.empty(n), np.empty((n, NP)))
            assert c2 == cost
            assert np.allclose(A, J.T @ J, rtol=1e-12, atol=1e-9 * np.abs(A).max())
            assert np.allclose(g, J.T @ res, rtol=1e-12, atol=1e-9 * np.abs(g).max())


def _select_reference(p, shape, cam, tc):
    """The selection rule of ``select`` written out over every pixel of the printed target."""
    h, w = shape
    X, Z, a, Y = p[:4]
    c, s = math.cos(a), math.sin(a)
    b, H, margin = tc.bar_width, tc.bar_height, tc.margin

    def ex(u):
        return cam.cx + cam.fx * (X + u * c) / (Z - u * s)

    uo = 1.5 * b + MARGIN_SHARE * margin
    c0, c1 = max(math.ceil(ex(-uo) + 0.5), 0), min(math.floor(ex(uo) - 0.5), w - 1)
    ncol = max(c1 - c0 + 1, 0)
    xe = [ex(u) for u in (-1.5 * b, -0.5 * b, 0.5 * b, 1.5 * b)]
    vo = 0.5 * H + MARGIN_SHARE * margin
    cstride = max(1, math.ceil(ncol / MAX_LINES))
    out = []
    for i in range(ncol):
        j = c0 + i
        z = (Z * c + X * s) / (c + (j - cam.cx) / cam.fx * s)
        rlo = max(math.ceil(cam.cy + cam.fy * (Y - vo) / z + 0.5), 0)
        rhi = min(math.floor(cam.cy + cam.fy * (Y + vo) / z - 0.5), h - 1)
        ytop, ybot = cam.cy + cam.fy * (Y - 0.5 * H) / z, cam.cy + cam.fy * (Y + 0.5 * H) / z
        near_v = any(abs(j - x) <= REACH for x in xe)
        rstride = max(1, math.ceil((ybot - ytop) / MAX_LINES))
        for r in range(rlo, rhi + 1):
            near_h = abs(r - ytop) <= REACH or abs(r - ybot) <= REACH
            if (near_h and (i % cstride == 0 or near_v)) or (near_v and (r - rlo) % rstride == 0):
                out.append((j, r))
    return out


def test_select_keeps_the_rule_it_states():
    cam = Camera.thesis(16.0)
    intr = Intrinsics(cam.fx, cam.fy, cam.cx, cam.cy)
    tc = TargetConstants(T.bar_width, T.bar_height, T.margin)
    for d, alpha in ((2.0, 0.0), (3.5, 40.0), (9.0, -55.0)):
        pose = TargetPose(d, 0.05, alpha * DEG, 0.1)
        p = np.array([*pose.centre[[0, 2]], pose.alpha, pose.centre[1], 0, 0, 0])
        sel = select(p, (cam.height, cam.width), intr, tc, MARGIN_SHARE, REACH, MAX_LINES)
        got = list(zip(sel.ucols[sel.pci].tolist(), sel.pr.tolist()))
        assert got == _select_reference(p, (cam.height, cam.width), intr, tc)
        assert len(got) > 100


def test_blur_is_held_at_its_bound(rng):
    """A target blurred beyond SIGMA_MAX: the fit holds the blur at the bound (the step is
    solved with the blur fixed there, no zig-zag between a clamped step and the full one); the
    range then carries the bias of the narrower model (a few per cent)."""
    from localizer.measure.photometric import refine_pose

    cam = Camera.thesis(16.0)
    pose = TargetPose(5.0, 0.02, 20 * DEG, 0.1)
    img = render_frame(cam, pose, lighting="normal", blur=SIGMA_MAX + 1.0, noise=1.0, background=0.5, rng=rng)
    c = pose.centre
    r = refine_pose(img, cam, T, (c[0], c[2], pose.alpha, c[1]), True, 30.0, 220.0, sigma=SIGMA_MAX + 0.5)
    assert r is not None
    assert r[0][6] == SIGMA_MAX
    assert abs(r[0][1] / c[2] - 1) < 0.05


def _ends(k=2):
    return FitEnds(np.empty((k, NP)), np.empty((k, NP, NP)), np.empty((k, NP)), np.empty(k))


def test_lm_resumes_from_an_end_bit_for_bit(rng):
    """The final fit taken on from a start's end with that end's normal equations kept ends
    exactly where forming them again would."""
    for blur, lighting in ((0.5, "saturated"), (2.0, "normal")):
        p, obs, sel, intr, tc = _setup(rng, blur, lighting)
        p[1] *= 1.01
        args = (obs, sel, intr, tc, True)
        ends = _ends()
        c, merged = lm(p, *args, ends, FitRun(START_ITERATIONS, START_TOL, 0, np.inf, np.inf, -1))
        assert merged == -1
        ends.p[0], ends.cost[0] = p, c
        c2, A, g = normal_equations(p, *args, np.empty(obs.size), np.empty((obs.size, NP)))
        assert c2 == c and np.array_equal(A, ends.A[0]) and np.array_equal(g, ends.g[0])
        q1, q2 = p.copy(), p.copy()
        r1 = lm(q1, *args, _ends(), FitRun(ITERATIONS, TOL, 0, np.inf, np.inf, -1))
        r2 = lm(q2, *args, ends, FitRun(ITERATIONS, TOL, 0, np.inf, np.inf, 0))
        assert r1 == r2 and np.array_equal(q1, q2)


def test_a_far_worse_start_is_given_up_before_its_first_step(rng):
    """A start whose cost exceeds ``give_up`` times the best end's is given up before its first
    step (``MIRROR_GIVE_UP`` for a certain pose's mirror start); below it, it is fitted."""
    assert MIRROR_GIVE_UP >= 100.0
    p, obs, sel, intr, tc = _setup(rng, 2.0)
    args = (obs, sel, intr, tc, True)
    ends = _ends()
    c, _ = lm(p, *args, ends, FitRun(START_ITERATIONS, START_TOL, 0, np.inf, np.inf, -1))
    ends.p[0], ends.cost[0] = p, c
    far = p.copy()
    far[2] = -far[2]  # the mirror orientation
    c0 = evaluate(far, *args, np.empty(obs.size), np.empty((obs.size, NP)), False)
    assert c0 > 2.0 * c
    q = far.copy()
    assert lm(q, *args, ends, FitRun(START_ITERATIONS, START_TOL, 1, c, 0.5 * c0 / c, -1)) == (c0, -2)
    assert np.array_equal(q, far)  # not a step taken
    lm(q, *args, ends, FitRun(START_ITERATIONS, START_TOL, 1, c, 2.0 * c0 / c, -1))
    assert not np.array_equal(q, far)
