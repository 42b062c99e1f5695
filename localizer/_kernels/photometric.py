"""Kernels of the whole-target photometric pose refinement (:mod:`localizer.photometric`).

The model, the censoring of clipped pixels and the starts are described in
:mod:`localizer.photometric`. The geometry is :mod:`localizer._kernels.projection`'s, the
blurred box-pixel step :mod:`localizer._kernels.blur`'s.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit
from localizer._kernels.blur import CLIP, blur_weights, edge_fraction
from localizer._kernels.projection import bar_edge_u, edge_x, edge_x_jacobian, plane, ray_inverse_range
from localizer._kernels.records import ColumnModel, Refinement, Selection

#: the fraction of the printed margin (from the bars outwards) that enters the fit
MARGIN_SHARE = 0.5
#: pixels further than this from every edge (px, at the start pose) stay out of the fit
REACH = 4.0
#: most rows (columns) sampled along a vertical (horizontal) edge
MAX_LINES = 24
#: smallest blur sd of the model (px)
SIGMA_MIN = 0.2
#: LM iterations
ITERATIONS = 30
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
    """Censored residuals ``res`` (n,) (module docstring) at ``p`` (7,) = (X, Z, alpha, Y,
    dark, bright, sigma) of the grey levels ``obs`` (n,) of the pixels ``sel``
    (:class:`~localizer._kernels.records.Selection`) and, when ``want_j``, their Jacobian
    ``J`` (n, 7) (analytic). ``cam``: :class:`~localizer._kernels.records.Intrinsics`,
    ``target``: :class:`~localizer._kernels.records.TargetConstants`. Returns the cost (sum
    of squares, grey levels^2)."""
    ucols, pci, pr = sel.ucols, sel.pci, sel.pr
    kw, kdw = blur_weights(max(p[6], 0.05))
    n = ucols.size
    fxb = np.empty(n)
    dfxb = np.empty((n, 5))
    ylin = np.empty((n, 2))
    dylin = np.empty((n, 2, 4))
    columns(p, ucols, cam, target, kw, kdw, ColumnModel(fxb, dfxb, ylin, dylin))
    amp = p[5] - p[4]
    pol = -1.0 if positive else 1.0  # d(bright fraction) / d(bars)
    cost = 0.0
    for q in range(obs.size):
        i = pci[q]
        r = pr[q]
        ft, dte, dts = edge_fraction(r, ylin[i, 0], kw, kdw)
        fb, dbe, dbs = edge_fraction(r, ylin[i, 1], kw, kdw)
        fy_ = ft - fb
        bars = fxb[i] * fy_
        bf = 1.0 - bars if positive else bars
        m = p[4] + amp * bf
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
        res[q] = rr
        cost += rr * rr
        if want_j:
            if active:
                k = amp * pol
                for t in range(4):
                    dfy = dte * dylin[i, 0, t] - dbe * dylin[i, 1, t]
                    dfx = dfxb[i, t] if t < 3 else 0.0
                    J[q, t] = k * (dfx * fy_ + fxb[i] * dfy)
                J[q, 4] = 1.0 - bf
                J[q, 5] = bf
                J[q, 6] = k * (dfxb[i, 4] * fy_ + fxb[i] * (dts - dbs))
            else:
                for t in range(7):
                    J[q, t] = 0.0
    return cost


@jit
def lm(p, obs, sel, cam, target, positive, iterations):
    """Levenberg-Marquardt of :func:`evaluate` from ``p`` (7,), updated in place, at most
    ``iterations`` steps. Returns the cost.

    The damped normal equations are solved by ``np.linalg.solve`` (LAPACK), not by
    :mod:`localizer.smallmat` like the other fits: LAPACK's (OpenBLAS's) operation order
    cannot be reproduced by a hand-written elimination, and any other order changes the
    refined poses in their last bits (and with them the recorded accuracy figures)."""
    n = obs.size
    res = np.empty(n)
    J = np.empty((n, 7))
    cost = evaluate(p, obs, sel, cam, target, positive, res, J, True)
    lam = 1e-3
    q = np.empty(7)
    rq = np.empty(n)
    Jq = np.empty((n, 7))
    A = J.T @ J
    g = J.T @ res
    for it in range(iterations):
        M = A.copy()
        for k in range(7):
            M[k, k] += lam * A[k, k] + 1e-12
        step = np.linalg.solve(M, g)
        for k in range(7):
            q[k] = p[k] - step[k]
        q[6] = min(max(q[6], SIGMA_MIN), 3.0)
        q[5] = max(q[5], q[4] + 1.0)
        if not q[1] > 0:
            lam *= 10.0
            continue
        cq = evaluate(q, obs, sel, cam, target, positive, rq, Jq, True)
        if cq < cost:
            conv = cost - cq < 1e-7 * (cost + 1e-9)
            p[:] = q
            res[:] = rq
            J[:, :] = Jq
            A = J.T @ J
            g = J.T @ res
            cost = cq
            lam = max(lam * 0.3, 1e-7)
            if conv:
                break
        else:
            lam *= 10.0
            if lam > 1e7:
                break
    return cost


@jit
def select(p, shape, cam, target, share, reach, max_lines):
    """The pixels of an ``shape = (h, w)`` image in the fit at pose ``p`` (X, Z, alpha, Y, ...;
    m, rad): inside the printed target (the bars and the gap,
    plus ``share`` of the ``margin`` (m) around them, trimmed by one pixel so that the
    background behind the target stays out) and within ``reach`` px of an edge; along
    each edge at most ``max_lines`` evenly spread rows (vertical edges) or columns (tops
    and bottoms), which bounds the work on large targets. ``margin`` is ``target.margin``.
    Returns a :class:`~localizer._kernels.records.Selection` ``(ucols (m,), pci (n,),
    pr (n,))``: the columns used, and each pixel's index into them and its row."""
    h, w = shape
    fx, fy, cx, cy = cam.fx, cam.fy, cam.cx, cam.cy
    b, H, margin = target.bar_width, target.bar_height, target.margin
    X, Z, a, Y = p[0], p[1], p[2], p[3]
    c, s = math.cos(a), math.sin(a)
    uo = 1.5 * b + share * margin
    xl = edge_x(X, Z, c, s, -uo, cam)
    xr = edge_x(X, Z, c, s, uo, cam)
    c0 = max(int(math.ceil(xl + 0.5)), 0)
    c1 = min(int(math.floor(xr - 0.5)), w - 1)
    ncol = max(c1 - c0 + 1, 0)
    xe = np.empty(4)
    for k in range(4):
        xe[k] = edge_x(X, Z, c, s, bar_edge_u(k, b), cam)
    D = Z * c + X * s
    vo = 0.5 * H + share * margin
    cstride = max(1, int(math.ceil(ncol / max_lines)))
    ucols = np.empty(ncol, np.int64)
    cap = 64
    pci = np.empty(cap, np.int64)
    pr = np.empty(cap, np.int64)
    n = 0
    m = 0
    for i in range(ncol):
        j = c0 + i
        t = (j - cx) / fx
        z = D / (c + t * s)
        rlo = max(int(math.ceil(cy + fy * (Y - vo) / z + 0.5)), 0)
        rhi = min(int(math.floor(cy + fy * (Y + vo) / z - 0.5)), h - 1)
        ytop = cy + fy * (Y - 0.5 * H) / z
        ybot = cy + fy * (Y + 0.5 * H) / z
        near_v = False
        for k in range(4):
            if abs(j - xe[k]) <= reach:
                near_v = True
        on_h = (i % cstride) == 0
        rstride = max(1, int(math.ceil((ybot - ytop) / max_lines)))
        used = False
        for r in range(rlo, rhi + 1):
            near_h = abs(r - ytop) <= reach or abs(r - ybot) <= reach
            if (near_h and (on_h or near_v)) or (near_v and (r - rlo) % rstride == 0):
                if n == cap:
                    cap *= 2
                    a1 = np.empty(cap, np.int64)
                    a2 = np.empty(cap, np.int64)
                    a1[:n] = pci[:n]
                    a2[:n] = pr[:n]
                    pci = a1
                    pr = a2
                pci[n] = m
                pr[n] = r
                n += 1
                used = True
        if used:
            ucols[m] = j
            m += 1
    return Selection(ucols[:m].copy(), pci[:n].copy(), pr[:n].copy())


@jit
def refine(image, p0, alt_alpha, start, cam, target, positive, wide):
    """Fit of the target in ``image`` (H, W) uint8 from the pose ``p0`` (4,) = (X, Z, alpha, Y)
    (m, rad), also from orientation ``alt_alpha`` (rad) and (``wide``) from several poses
    around ``p0``; ``start``: the :class:`~localizer._kernels.records.Levels` to start from.
    Returns a :class:`~localizer._kernels.records.Refinement`: ``(ok, p (7,), n_pixels,
    cost)`` with ``p`` = (X, Z, alpha, Y, dark, bright, sigma)."""
    dark0, bright0, sigma0 = start.dark, start.bright, start.sigma
    p = np.empty(7)
    p[:4] = p0
    sel = select(p, image.shape, cam, target, MARGIN_SHARE, REACH, MAX_LINES)
    ucols, pci, pr = sel.ucols, sel.pci, sel.pr
    n = pr.size
    if n < 60:
        return Refinement(False, p, n, 0.0)
    obs = np.empty(n)
    for q in range(n):
        obs[q] = image[pr[q], ucols[pci[q]]]
    # starts: the edge-based pose, scaled along its line of sight (the range is what clipped
    # edges get wrong), turned by +-TURN (small targets: alpha is weakly determined), and
    # the other root of A.14 (the mirror solution, thesis section 4.2.2) when it differs
    # (only when the edge-based pose is uncertain, ``wide``: otherwise from that pose and the
    # other root alone)
    n_alt = 1 if abs(alt_alpha - p0[2]) > 0.01 else 0
    n_scales = len(SCALES) if wide else 1
    n_starts = n_scales * (1 + n_alt) + (2 if wide else 0)
    best = np.empty(7)
    best_cost = np.inf
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
        p[6] = max(sigma0, SIGMA_MIN)
        # iteration counts typed int64, not as the literals 6 and 30: one compiled lm, not two
        c = lm(p, obs, sel, cam, target, positive, np.int64(START_ITERATIONS))
        if c < best_cost:
            best_cost = c
            best[:] = p
    p[:] = best
    cost = lm(p, obs, sel, cam, target, positive, np.int64(ITERATIONS))
    return Refinement(True, p, n, cost)
