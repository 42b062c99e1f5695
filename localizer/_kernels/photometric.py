"""Kernels of the whole-target photometric pose refinement (:mod:`localizer.measure.photometric`: the
model, the censoring of clipped pixels, the starts); the geometry is
:mod:`localizer._kernels.projection`'s, the blurred box-pixel step :mod:`localizer._kernels.blur`'s."""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit
from localizer._kernels.blur import CLIP, blur_weights, closed_step, edge_fraction, sampled_step
from localizer._kernels.photometric_select import select
from localizer._kernels.projection import bar_edge_u, edge_x_jacobian, plane, ray_inverse_range
from localizer._kernels.records import ColumnModel, FitEnds, FitRun, Refinement

#: the fraction of the printed margin (from the bars outwards) that enters the fit
MARGIN_SHARE = 0.5
#: pixels further than this from every edge (px, at the start pose) stay out of the fit
REACH = 4.0
#: most rows (columns) sampled along a vertical (horizontal) edge
MAX_LINES = 24
#: smallest and largest blur sd of the model (px)
SIGMA_MIN = 0.2
SIGMA_MAX = 4.0
#: the fit's unknowns: X, Z, alpha, Y (m, rad), dark, bright (grey levels), sigma (px) and the
#: illumination's slope across the target (share of the level per half target width)
NP = 8
#: LM iterations
ITERATIONS = 30
#: a fit ends when a step lowers the cost by less than this share of it (or promises less)
TOL = 1e-7
#: ... a start's fit (it only has to find its basin; the best start's fit then goes on at TOL)
START_TOL = 1e-5
#: a start whose fit comes within this share of an earlier start's end cost (its cost, and the
#: end's quadratic model of it) is in that end's basin (:func:`same_basin`)
BASIN = 1e-2
#: a start's fit whose cost is still above ABANDON times the lowest end cost of the starts
#: before it after ABANDON_AFTER steps is abandoned (it is headed for a worse minimum)
ABANDON = 100.0
ABANDON_AFTER = 2
#: a certain pose's (not ``wide``) mirror start (eq A.14's other root) is given up before its first
#: step when its cost there is above this many times the first start's end cost (ABANDON's factor,
#: without its two steps). Of 1,170 on the envelope's frames it won 8, from at most 56 times (10 lost
#: a 9.5 m target's alpha in the thesis points envelope); 40 % start above 100 (5 of a blurred
#: target's 12 model evaluations). Not ``wide``: there a start from 4,500 times the best can win
MIRROR_GIVE_UP = 100.0
#: starts of the fit: the edge-based pose scaled along its line of sight, and turned (rad)
SCALES = (1.0, 0.985, 1.015, 0.97, 1.03)
TURN = math.radians(12.0)
#: LM iterations from each start (the best start is then iterated to ``ITERATIONS``)
START_ITERATIONS = 6
#: starts turned beyond this orientation (rad) are skipped
ALPHA_MAX = math.radians(80.0)


@jit
def columns(p, cols, cam, target, kw, kdw, out):
    """Per column ``cols`` (n,) at parameters ``p`` (X, Z, alpha, Y, ...; m, rad): the bars'
    fraction ``out.fxb`` (n,) of the column's pixels and its derivatives ``out.dfxb`` (n, 5)
    over (X, Z, alpha, Y, sigma); the top and bottom lines ``out.ylin`` (n, 2) (px) and
    their derivatives ``out.dylin`` (n, 2, 4) over (X, Z, alpha, Y), filled in place
    (``out``: :class:`~localizer._kernels.records.ColumnModel`). ``kw``, ``kdw`` (7,): the
    blur taps and their derivatives (:func:`localizer._kernels.blur.blur_weights`); the
    projection: :mod:`localizer._kernels.projection`."""
    fxb, dfxb, ylin, dylin = out.fxb, out.dfxb, out.ylin, out.dylin
    fx, fy, cx, cy = cam.fx, cam.fy, cam.cx, cam.cy
    b, H = target.bar_width, target.bar_height
    X, Z, a, Y = p[0], p[1], p[2], p[3]
    c, s = math.cos(a), math.sin(a)
    xe = np.empty(4)
    dxe = np.empty((4, 3))
    for k in range(4):
        xe[k], dxe[k, 0], dxe[k, 1], dxe[k, 2] = edge_x_jacobian(X, Z, c, s, bar_edge_u(k, b), cam)
    D, iD, dD = plane(X, Z, c, s)
    for i in range(cols.size):
        j = cols[i]
        f = 0.0
        for m in range(5):
            dfxb[i, m] = 0.0
        for k in range(4):
            fk, de, ds = edge_fraction(j, xe[k], kw, kdw)
            sg = 1.0 if k % 2 == 0 else -1.0
            f += sg * fk
            for m in range(3):
                dfxb[i, m] += sg * de * dxe[k, m]
            dfxb[i, 4] += sg * ds
        fxb[i] = f
        t = (j - cx) / fx
        q, dq_dx, dq_dz, dq_da = ray_inverse_range(t, c, s, D, iD, dD)  # 1 / z at this column
        for side in range(2):
            yv = Y - 0.5 * H if side == 0 else Y + 0.5 * H
            ylin[i, side] = cy + fy * yv * q
            dylin[i, side, 0] = fy * yv * dq_dx
            dylin[i, side, 1] = fy * yv * dq_dz
            dylin[i, side, 2] = fy * yv * dq_da
            dylin[i, side, 3] = fy * q


@jit
def evaluate(p, obs, sel, cam, target, positive, res, J, want_j):
    """Censored residuals ``res`` (n,) (module docstring) at ``p`` (NP,) = (X, Z, alpha, Y,
    dark, bright, sigma, slope) of the grey levels ``obs`` (n,) of the pixels ``sel``
    (:class:`~localizer._kernels.records.Selection`) and, when ``want_j``, their Jacobian
    ``J`` (n, NP) (analytic). ``cam``: :class:`~localizer._kernels.records.Intrinsics`,
    ``target``: :class:`~localizer._kernels.records.TargetConstants`. Returns the cost (sum
    of squares, grey levels^2)."""
    return model(p, obs, sel, cam, target, positive, res, J, want_j, False)[0]


@jit
def model(p, obs, sel, cam, target, positive, res, J, want_j, compact):
    """:func:`evaluate`; when ``compact``, only the pixels whose residual moves with ``p`` (not
    censored) are written, to the first rows of ``res`` and ``J``. Returns ``(cost, rows
    written)``. A blur from :data:`~localizer._kernels.blur.ANALYTIC_SD` on takes the closed
    form, a pixel's lower side shared with the upper side of the pixel above it when that
    is in the fit too."""
    ucols, pci, pr = sel.ucols, sel.pci, sel.pr
    kw, kdw = blur_weights(max(p[6], 0.05))
    closed = kw.size == 1
    sd = kw[0]
    reach = 4.5 * sd + 1.0
    kk = (kw.size - 1) // 2  # sampled taps: edge_fraction's half-width and cut-off, once
    taps_reach = kk + 1.5
    n = ucols.size
    fxb = np.empty(n)
    dfxb = np.empty((n, 5))
    ylin = np.empty((n, 2))
    dylin = np.empty((n, 2, 4))
    columns(p, ucols, cam, target, kw, kdw, ColumnModel(fxb, dfxb, ylin, dylin))
    amp = p[5] - p[4]
    pol = -1.0 if positive else 1.0  # d(bright fraction) / d(bars)
    k = amp * pol
    # the illumination's slope: the levels scale by 1 + p[7] u, u the column's place across the
    # fit's columns (-1 at the first, +1 at the last)
    c_mid = 0.5 * (ucols[0] + ucols[n - 1])
    c_half = max(0.5 * (ucols[n - 1] - ucols[0]), 1.0)
    gx = p[7]
    cost = 0.0
    w = 0
    i_prev = -1
    r_prev = -10
    ok_t = ok_b = False
    ut = ct = pt = ub = cb = pb = 0.0
    for q in range(obs.size):
        i = pci[q]
        r = pr[q]
        if closed:
            shared = i == i_prev and r == r_prev + 1
            ft, dte, dts, ut, ct, pt, ok_t = closed_step(r, ylin[i, 0], sd, reach, shared and ok_t, ut, ct, pt)
            fb, dbe, dbs, ub, cb, pb, ok_b = closed_step(r, ylin[i, 1], sd, reach, shared and ok_b, ub, cb, pb)
            i_prev = i
            r_prev = r
        else:
            ft, dte, dts = sampled_step(r, ylin[i, 0], kw, kdw, kk, taps_reach)
            fb, dbe, dbs = sampled_step(r, ylin[i, 1], kw, kdw, kk, taps_reach)
        fy_ = ft - fb
        bars = fxb[i] * fy_
        bf = 1.0 - bars if positive else bars
        u = (ucols[i] - c_mid) / c_half
        light = 1.0 + gx * u
        base = p[4] + amp * bf
        m = base * light
        o = obs[q]
        if o >= CLIP:
            rr = m - 255.0 if m < 255.0 else 0.0
            active = m < 255.0
        elif o <= 0.5:  # clipped at black (dim light)
            rr = m if m > 0.0 else 0.0
            active = m > 0.0
        else:
            rr = m - o
            active = True
        cost += rr * rr
        if compact and not active:
            continue
        row = w if compact else q
        w += 1
        res[row] = rr
        if want_j:
            if active:
                for t in range(4):
                    dfy = dte * dylin[i, 0, t] - dbe * dylin[i, 1, t]
                    dfx = dfxb[i, t] if t < 3 else 0.0
                    J[row, t] = k * (dfx * fy_ + fxb[i] * dfy) * light
                J[row, 4] = (1.0 - bf) * light
                J[row, 5] = bf * light
                J[row, 6] = k * (dfxb[i, 4] * fy_ + fxb[i] * (dts - dbs)) * light
                J[row, 7] = base * u
            else:
                for t in range(NP):
                    J[row, t] = 0.0
    return cost, w


@jit
def normal_equations(p, obs, sel, cam, target, positive, res, J):
    """The cost at ``p`` and the normal equations ``(J^T J, J^T r)`` of :func:`evaluate`'s
    Jacobian, through the buffers ``res`` (n,) and ``J`` (n, NP) (censored pixels left out)."""
    cost, w = model(p, obs, sel, cam, target, positive, res, J, True, True)
    Jw = J[:w]
    return cost, Jw.T @ Jw, Jw.T @ res[:w]


@jit
def _solve(A, g, lam, p):
    """The damped Gauss-Newton step ``(A + lam diag(A)) step = g`` at ``p``, with the blur sd
    held where it is when it is at a bound and the step would take it further out."""
    M = A.copy()
    for a in range(NP):
        M[a, a] += lam * A[a, a] + 1e-12
    step = np.linalg.solve(M, g)
    s6 = p[6] - step[6]
    if (s6 > SIGMA_MAX and p[6] >= SIGMA_MAX) or (s6 < SIGMA_MIN and p[6] <= SIGMA_MIN):
        for a in range(NP):
            M[6, a] = 0.0
            M[a, 6] = 0.0
        M[6, 6] = 1.0
        h = g.copy()
        h[6] = 0.0
        step = np.linalg.solve(M, h)
    return step


@jit
def lm(p, obs, sel, cam, target, positive, ends, run):
    """Levenberg-Marquardt of :func:`evaluate` from ``p`` (NP,), updated in place, as ``run``
    (a :class:`~localizer._kernels.records.FitRun`) says: at most ``run.iterations`` steps, ended
    when a step lowers the cost by less than ``run.tol`` of it or the linear model promises less
    than that. The ends of earlier fits of the same pixels
    (``ends``: :class:`~localizer._kernels.records.FitEnds`, ``run.n_ends`` of them filled): a fit
    that reaches the bowl of one of them stops there (:func:`same_basin`: it would end where
    that one did). ``resume``: the index of an end at ``p`` whose normal equations are taken
    rather than formed again (``run.resume``; -1: none). Returns ``(cost, merged)``: ``merged`` the index of
    that end, -2 when the fit was abandoned (after :data:`ABANDON_AFTER` steps its cost still
    above :data:`ABANDON` times ``run.best``, the lowest end cost so far, or before its first step
    above ``run.give_up`` times it), else -1 (and the normal equations at ``p`` are left in
    ``ends.A[run.n_ends]``, ``ends.g[run.n_ends]`` when there is room).

    The damped normal equations are solved by ``np.linalg.solve`` (LAPACK), not by
    :mod:`localizer.smallmat` like the other fits: LAPACK's (OpenBLAS's) operation order
    cannot be reproduced by a hand-written elimination, and any other order changes the
    refined poses in their last bits (and with them the recorded accuracy figures)."""
    iterations, tol, n_ends, best, give_up, resume = run
    n = obs.size
    res = np.empty(n)
    J = np.empty((n, NP))
    if resume >= 0:  # the very numbers normal_equations would give again at this p
        cost = ends.cost[resume]
        A = ends.A[resume].copy()
        g = ends.g[resume].copy()
    else:
        cost, A, g = normal_equations(p, obs, sel, cam, target, positive, res, J)
        if n_ends > 0 and cost > give_up * best:
            return cost, -2
    lam = 1e-3
    q = np.empty(NP)
    for it in range(iterations):
        step = _solve(A, g, lam, p)
        for a in range(NP):
            q[a] = p[a] - step[a]
        q[6] = min(max(q[6], SIGMA_MIN), SIGMA_MAX)
        q[5] = max(q[5], q[4] + 1.0)
        if not q[1] > 0:
            lam *= 10.0
            continue
        cq, Aq, gq = normal_equations(q, obs, sel, cam, target, positive, res, J)
        if cq < cost:
            conv = cost - cq < tol * (cost + 1e-9)
            for a in range(NP):
                p[a] = q[a]
            A = Aq
            g = gq
            cost = cq
            lam = max(lam * 0.3, 1e-7)
            if conv:
                break
            for e in range(n_ends):
                if same_basin(p, cost, ends.p[e], ends.A[e], ends.cost[e]):
                    return cost, e
            if it + 1 >= ABANDON_AFTER and cost > ABANDON * best:
                return cost, -2
        else:
            # the step the linear model promised (2 s.g - s.A.s) is all a more damped one can give
            pred = 0.0
            for a in range(NP):
                sa = p[a] - q[a]
                pred += 2.0 * sa * g[a]
                for b in range(NP):
                    pred -= sa * A[a, b] * (p[b] - q[b])
            if pred < tol * (cost + 1e-9):
                break
            lam *= 10.0
            if lam > 1e7:
                break
    if n_ends < ends.cost.size:
        for a in range(NP):
            ends.g[n_ends, a] = g[a]
            for b in range(NP):
                ends.A[n_ends, a, b] = A[a, b]
    return cost, -1


@jit
def same_basin(p, cost, pe, Ae, ce):
    """Whether ``p`` (cost ``cost``) lies in the bowl of an earlier fit's end ``pe`` (NP,) (normal
    matrix ``Ae``, cost ``ce``): no lower, and both its cost and the end's quadratic model of it
    (``ce + d^T Ae d``, ``d = p - pe``) within :data:`BASIN` of ``ce``."""
    if cost < ce:
        return False
    quad = 0.0
    for a in range(NP):
        da = p[a] - pe[a]
        for b in range(NP):
            quad += da * Ae[a, b] * (p[b] - pe[b])
    return quad < BASIN * ce and cost - ce < BASIN * ce


@jit
def refine(image, p0, alt_alpha, start, cam, target, positive, wide):
    """Fit of the target in ``image`` (H, W) uint8 from the pose ``p0`` (4,) = (X, Z, alpha, Y)
    (m, rad), also from orientation ``alt_alpha`` (rad) and (``wide``) from several poses
    around ``p0``; ``start``: the :class:`~localizer._kernels.records.Levels` to start from.
    Returns a :class:`~localizer._kernels.records.Refinement`: ``(ok, p (NP,), n_pixels,
    cost)`` with ``p`` = (X, Z, alpha, Y, dark, bright, sigma, slope)."""
    dark0, bright0, sigma0 = start.dark, start.bright, start.sigma
    p = np.empty(NP)
    p[:4] = p0
    sel = select(p, image.shape, cam, target, MARGIN_SHARE, REACH, MAX_LINES)
    ucols, pci, pr = sel.ucols, sel.pci, sel.pr
    n = pr.size
    if n < 60:
        return Refinement(False, p, n, 0.0)
    obs = np.empty(n)
    for q in range(n):
        obs[q] = image[pr[q], ucols[pci[q]]]
    # starts (the best one's end goes on from its normal equations, lm's ``resume``): the edge-based
    # pose, scaled along its line of sight (the range is what clipped edges get wrong), turned by
    # +-TURN (small targets: alpha is weakly determined), and the other root of A.14 (the mirror solution, thesis section 4.2.2) when it differs
    # (only when the edge-based pose is uncertain, ``wide``: otherwise from it and the other root)
    n_alt = 1 if abs(alt_alpha - p0[2]) > 0.01 else 0
    n_scales = len(SCALES) if wide else 1
    n_starts = n_scales * (1 + n_alt) + (2 if wide else 0)
    best = np.empty(NP)
    best_cost = np.inf
    # the ends of the starts' fits, for the later starts to recognise (lm: a start that reaches
    # an earlier one's basin stops there; a certain pose's mirror start given up when far worse)
    ends = FitEnds(np.empty((n_starts, NP)), np.empty((n_starts, NP, NP)), np.empty((n_starts, NP)), np.empty(n_starts))
    n_ends = 0
    i_best = -1
    give_up = np.inf if wide else MIRROR_GIVE_UP
    for st in range(n_starts):
        p[:4] = p0
        if st < n_scales * (1 + n_alt):
            sc = SCALES[st % n_scales]
            p[0] *= sc
            p[1] *= sc
            p[3] *= sc
            if st >= n_scales:
                p[2] = alt_alpha
        else:
            p[2] = p0[2] + (TURN if st == n_starts - 1 else -TURN)
        if not abs(p[2]) < ALPHA_MAX:
            continue
        p[4] = dark0
        p[5] = bright0 if bright0 < CLIP - 5.0 else dark0 + 2.0 * (255.0 - dark0)
        p[6] = min(max(sigma0, SIGMA_MIN), SIGMA_MAX)
        p[7] = 0.0
        # (counts typed int64, costs float64, in both calls: one compiled lm)
        c, merged = lm(p, obs, sel, cam, target, positive, ends,
                       FitRun(np.int64(START_ITERATIONS), np.float64(START_TOL), np.int64(n_ends),
                              np.float64(best_cost), np.float64(give_up), np.int64(-1)))
        if merged != -1:
            continue
        for a in range(NP):
            ends.p[n_ends, a] = p[a]
        ends.cost[n_ends] = c
        if c < best_cost:
            best_cost = c
            best[:] = p
            i_best = n_ends
        n_ends += 1
    if not best_cost < np.inf:  # every start turned beyond ALPHA_MAX (or no finite fit): nothing to refine
        return Refinement(False, p, n, 0.0)
    p[:] = best
    cost, _ = lm(p, obs, sel, cam, target, positive, ends,
                 FitRun(np.int64(ITERATIONS), np.float64(TOL), np.int64(0), np.float64(np.inf), np.float64(np.inf),
                        np.int64(i_best)))
    return Refinement(True, p, n, cost)
