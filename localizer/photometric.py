"""Whole-target photometric pose refinement (saturated, small, far or dim targets).

The edge-based pose (:mod:`localizer.edges`, :mod:`localizer.pose`) measures each edge on
its own and then fits the pose to eight edge positions. Where the edges are poor that
throws information away. On a saturated frame the bright side of every edge is clipped at 255, so an edge
measured on its own is known only to lie somewhere inside its clipped pixel (up to
~0.6 px for sharp edges: the edge-based pose then carries 2-3 % distance error on
targets ~20 rows tall). The pixels still hold more than the edges taken one at a
time: every edge of the target is tied to the others by the pose, all share one
blur and one pair of grey levels, and every unclipped transition pixel gives its
edge's exact coverage once the (unseen, clipped) bright level is known. This module
fits that whole model to the pixels of the target at once:

    grey(c, r) = dark + (bright - dark) * b(c, r), observed through min(., 255)

with ``b`` the blurred box-pixel fraction of the bright paint at column ``c``, row
``r``: ``1 - bars`` for a positive target (black bars on white), ``bars`` for a
negative one, where ``bars(c, r) = (Fx1(c) + Fx2(c)) * Fy(c, r)``: ``Fx`` the
fractions of the pixel between each bar's two vertical edges, ``Fy`` the fraction
between the top and bottom lines of the target at that column, both blurred by one
sampled Gaussian of sd ``sigma`` on the pixel grid (:func:`localizer.edges._step`).
The geometry is :func:`localizer.pose._model`'s: the target centre at ``(X, Y, Z)`` in the
camera frame (m), orientation ``alpha`` (rad, thesis sign), and a point at target
abscissa ``u`` imaging at ``x = cx + fx (X + u cos a) / (Z - u sin a)``; the tops and
bottoms are the lines ``y = cy + fy (Y -+ H/2) / z(c)`` with ``z(c)`` the range where
the ray of column ``c`` meets the target plane.

Clipped observations are censored: a pixel seen at 255 costs nothing while the model
is at or above 255 and ``255 - model`` below it (likewise at 0); an unclipped pixel costs
``model - grey`` with the unclipped model. Seven unknowns (X, Z, alpha, Y, dark,
bright, sigma) by Levenberg-Marquardt with an analytic Jacobian, from the edge-based
pose (and the other root of eq A.14; for an uncertain start also from that pose scaled
along its line of sight and turned by +-12 deg; the lowest cost wins). Only pixels of
the printed target (bars, gap and half of the margin, which is what separates a target
from the background behind it) within a few pixels of an edge enter the fit, at most
``MAX_LINES`` rows along each vertical edge and columns along each top and bottom, so the
cost stays ~0.5-2 ms per target whatever its size (several starts: up to ~7 ms).

What the pixels cannot tell stays untold: on small, sharp, saturated targets the cost
can be flat along a combination of range, orientation and the (clipped, unseen) bright
level, and the fit then lands anywhere in that valley. The caller therefore keeps the
edge-based covariance (:func:`localizer.detect._photometric`).

Lens distortion is not modelled: the refinement applies to undistorted cameras only.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from localizer.edges import _CLIP, _kernel, _step

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
_SCALES = (1.0, 0.985, 1.015, 0.97, 1.03)
_TURN = math.radians(12.0)
_START_ITERATIONS = 6
_ALPHA_MAX = math.radians(80.0)


@numba.njit(cache=True, nogil=True)
def _columns(p, cols, fx, fy, cx, cy, b, H, kw, kdw, fxb, dfxb, ylin, dylin):
    """Per column ``cols`` (n,) at parameters ``p``: the bars' fraction ``fxb`` (n,) of the
    column's pixels and its derivatives ``dfxb`` (n, 5) over (X, Z, alpha, Y, sigma); the
    top and bottom lines ``ylin`` (n, 2) (px) and their derivatives ``dylin`` (n, 2, 4) over
    (X, Z, alpha, Y)."""
    X, Z, a, Y = p[0], p[1], p[2], p[3]
    c, s = math.cos(a), math.sin(a)
    xe = np.empty(4)
    dxe = np.empty((4, 3))
    for k in range(4):
        u = (k - 1.5) * b
        N = X + u * c
        iM = 1.0 / (Z - u * s)
        q = N * iM
        xe[k] = cx + fx * q
        dxe[k, 0] = fx * iM
        dxe[k, 1] = -fx * q * iM
        dxe[k, 2] = fx * u * (N * c - s / iM) * iM * iM
    D = Z * c + X * s
    iD = 1.0 / D
    dD = X * c - Z * s
    for i in range(cols.size):
        j = cols[i]
        f = 0.0
        for m in range(5):
            dfxb[i, m] = 0.0
        for k in range(4):
            if j - xe[k] > 4.5:
                fk = 1.0
                de = 0.0
                ds = 0.0
            elif xe[k] - j > 4.5:
                fk = 0.0
                de = 0.0
                ds = 0.0
            else:
                fk, de, ds = _step(j, xe[k], kw, kdw)
            sg = 1.0 if k % 2 == 0 else -1.0
            f += sg * fk
            for m in range(3):
                dfxb[i, m] += sg * de * dxe[k, m]
            dfxb[i, 4] += sg * ds
        fxb[i] = f
        t = (j - cx) / fx
        g = c + t * s
        q = g * iD  # 1 / z at this column
        dq_dx = -g * s * iD * iD
        dq_dz = -g * c * iD * iD
        dq_da = ((t * c - s) * D - g * dD) * iD * iD
        for side in range(2):
            yv = Y - 0.5 * H if side == 0 else Y + 0.5 * H
            ylin[i, side] = cy + fy * yv * q
            dylin[i, side, 0] = fy * yv * dq_dx
            dylin[i, side, 1] = fy * yv * dq_dz
            dylin[i, side, 2] = fy * yv * dq_da
            dylin[i, side, 3] = fy * q


@numba.njit(cache=True, nogil=True)
def _edge(r, e, kw, kdw):
    if r - e > 4.5:
        return 1.0, 0.0, 0.0
    if e - r > 4.5:
        return 0.0, 0.0, 0.0
    return _step(r, e, kw, kdw)


@numba.njit(cache=True, nogil=True)
def _evaluate(p, obs, ucols, pci, pr, fx, fy, cx, cy, b, H, positive, res, J, want_j):
    """Censored residuals ``res`` (n,) (module docstring) at ``p`` (7,) and, when ``want_j``,
    their Jacobian ``J`` (n, 7) (analytic). Returns the cost (sum of squares)."""
    kw, kdw = _kernel(max(p[6], 0.05))
    n = ucols.size
    fxb = np.empty(n)
    dfxb = np.empty((n, 5))
    ylin = np.empty((n, 2))
    dylin = np.empty((n, 2, 4))
    _columns(p, ucols, fx, fy, cx, cy, b, H, kw, kdw, fxb, dfxb, ylin, dylin)
    amp = p[5] - p[4]
    pol = -1.0 if positive else 1.0  # d(bright fraction) / d(bars)
    cost = 0.0
    for q in range(obs.size):
        i = pci[q]
        r = pr[q]
        ft, dte, dts = _edge(r, ylin[i, 0], kw, kdw)
        fb, dbe, dbs = _edge(r, ylin[i, 1], kw, kdw)
        fy_ = ft - fb
        bars = fxb[i] * fy_
        bf = 1.0 - bars if positive else bars
        m = p[4] + amp * bf
        o = obs[q]
        if o >= _CLIP:
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


@numba.njit(cache=True, nogil=True)
def _lm(p, obs, ucols, pci, pr, fx, fy, cx, cy, b, H, positive, iterations):
    """Levenberg-Marquardt from ``p`` (7,), updated in place.
    Returns the cost."""
    n = obs.size
    res = np.empty(n)
    J = np.empty((n, 7))
    cost = _evaluate(p, obs, ucols, pci, pr, fx, fy, cx, cy, b, H, positive, res, J, True)
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
        cq = _evaluate(q, obs, ucols, pci, pr, fx, fy, cx, cy, b, H, positive, rq, Jq, True)
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


@numba.njit(cache=True, nogil=True)
def _select(p, h, w, fx, fy, cx, cy, b, H, margin, share, reach, max_lines):
    """The pixels of the fit at pose ``p``: inside the printed target (the bars and the gap,
    plus ``share`` of the ``margin`` (m) around them, trimmed by one pixel so that the
    background behind the target stays out) and within ``reach`` px of an edge; along
    each edge at most ``max_lines`` evenly spread rows (vertical edges) or columns (tops
    and bottoms), which bounds the work on large targets. Returns ``(ucols (m,), pci (n,),
    pr (n,))``: the columns used, and each pixel's index into them and its row."""
    X, Z, a, Y = p[0], p[1], p[2], p[3]
    c, s = math.cos(a), math.sin(a)
    uo = 1.5 * b + share * margin
    xl = cx + fx * (X - uo * c) / (Z + uo * s)
    xr = cx + fx * (X + uo * c) / (Z - uo * s)
    c0 = max(int(math.ceil(xl + 0.5)), 0)
    c1 = min(int(math.floor(xr - 0.5)), w - 1)
    ncol = max(c1 - c0 + 1, 0)
    xe = np.empty(4)
    for k in range(4):
        u = (k - 1.5) * b
        xe[k] = cx + fx * (X + u * c) / (Z - u * s)
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
    return ucols[:m].copy(), pci[:n].copy(), pr[:n].copy()


@numba.njit(cache=True, nogil=True)
def _refine(image, p0, alt_alpha, fx, fy, cx, cy, b, H, margin, positive, dark0, bright0, sigma0, wide):
    """Fit from the pose ``p0`` = (X, Z, alpha, Y) (m, rad). Returns ``(ok, p (7,), n_pixels,
    cost)`` with ``p`` = (X, Z, alpha, Y, dark, bright, sigma)."""
    h, w = image.shape
    p = np.empty(7)
    p[:4] = p0
    ucols, pci, pr = _select(p, h, w, fx, fy, cx, cy, b, H, margin, MARGIN_SHARE, REACH, MAX_LINES)
    n = pr.size
    if n < 60:
        return False, p, n, 0.0
    obs = np.empty(n)
    for q in range(n):
        obs[q] = image[pr[q], ucols[pci[q]]]
    # starts: the edge-based pose, scaled along its line of sight (the range is what clipped
    # edges get wrong), turned by +-_TURN (small targets: alpha is weakly determined), and
    # the other root of A.14 (the mirror solution, thesis section 4.2.2) when it differs
    # (only when the edge-based pose is uncertain, ``wide``: otherwise from that pose and the
    # other root alone)
    n_alt = 1 if abs(alt_alpha - p0[2]) > 0.01 else 0
    n_scales = len(_SCALES) if wide else 1
    n_starts = n_scales * (1 + n_alt) + (2 if wide else 0)
    best = np.empty(7)
    best_cost = np.inf
    for st in range(n_starts):
        p[:4] = p0
        if st < n_scales * (1 + n_alt):
            sc = _SCALES[st % n_scales]
            p[0] *= sc
            p[1] *= sc
            p[3] *= sc
            if st >= n_scales:
                p[2] = alt_alpha
        else:
            p[2] = p0[2] + (_TURN if st == n_starts - 1 else -_TURN)
        if not abs(p[2]) < _ALPHA_MAX:
            continue
        p[4] = dark0
        p[5] = bright0 if bright0 < _CLIP - 5.0 else dark0 + 2.0 * (255.0 - dark0)
        p[6] = max(sigma0, SIGMA_MIN)
        c = _lm(p, obs, ucols, pci, pr, fx, fy, cx, cy, b, H, positive, _START_ITERATIONS)
        if c < best_cost:
            best_cost = c
            best[:] = p
    p[:] = best
    cost = _lm(p, obs, ucols, pci, pr, fx, fy, cx, cy, b, H, positive, ITERATIONS)
    return True, p, n, cost


def refine_pose(image: np.ndarray, camera, target, pose: tuple[float, float, float, float], positive: bool,
                dark: float, bright: float = 255.0, sigma: float = 0.4, alt_alpha: float | None = None,
                wide: bool = True):
    """Refine an edge-based pose of a target on its pixels (module docstring).

    Args:
        image: ``(H, W)`` uint8 grey frame.
        camera: an undistorted :class:`localizer.Camera`.
        target: :class:`localizer.TargetSpec`.
        pose: ``(X, Z, alpha, Y)`` start (m, rad), camera frame (:func:`localizer.pose._model`).
        positive: target polarity.
        dark: start of the dark grey level.
        bright: the bright grey level seen (255 when clipped: the fit then starts above it).
        sigma: start of the blur sd (px).
        alt_alpha: a second orientation to start from (rad; the other root of eq A.14).
        wide: start from several poses around ``pose`` (scaled along the line of sight, turned
            by +-12 deg), for an uncertain start; else from ``pose`` (and ``alt_alpha``) alone.
    Returns:
        ``None`` if the target has too few pixels or the fit is not finite, else
        ``(p, n_pixels, cost)``: ``p`` (7,) = (X, Z, alpha, Y, dark, bright, sigma), the number
        of pixels fitted and the final sum of squared (censored) residuals, grey levels^2. No
        covariance: on clipped targets the normal matrix cannot see the flat directions
        (module docstring), so callers keep the edge-based one.
    """
    pose = np.asarray(pose, np.float64)
    alt = float(pose[2] if alt_alpha is None else alt_alpha)
    ok, p, n, cost = _refine(image, pose, alt, float(camera.fx), float(camera.fy),
                            float(camera.cx), float(camera.cy), float(target.bar_width),
                            float(target.bar_height), float(target.margin), bool(positive), float(dark), float(bright),
                            float(sigma), bool(wide))
    if not ok or not np.all(np.isfinite(p)):
        return None
    return p, n, cost
