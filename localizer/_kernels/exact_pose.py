"""Kernels of the perspective-exact pose (Appendix A; :func:`localizer.measure.exact_pose.exact_pose`).

Unknowns ``p = (X, Z, alpha, Y, delta)``: the target centre in the camera frame (m),
its orientation (rad, thesis sign, :mod:`localizer.model.geometry`) and ``delta`` (px), the
common shift of every edge towards its dark side. Measurements: the four vertical edges
and the tops and bottoms of both bars at their centre columns (px). The projection:
:mod:`localizer._kernels.projection`; the linear algebra: :mod:`localizer.smallmat`.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit
from localizer._kernels.arrays import copy
from localizer._kernels.projection import bar_edges_u, edge_x_jacobian, plane, ray_inverse_range
from localizer._kernels.records import FitGeometry, FitStatus, PoseFit
from localizer.smallmat import inverse, null_vector, solve_augmented


@jit
def alpha_a14(r: float, width: float, beta: float, beta1: float, beta2: float) -> tuple[float, float]:
    """Appendix A's analytic orientation (eqs A.13-A.14), both roots.

    ``cos(alpha - beta) = (r^2 - (W/2)^2) / (r W) * tan(beta2 - beta1)`` with ``r``
    the horizontal distance to the target centre (m), ``width`` W (m), ``beta``
    the bearing of the centre, ``beta1``/``beta2`` of the left/right outer edges.
    Returns ``(beta + acos(.), beta - acos(.))``.
    """
    c = (r * r - 0.25 * width * width) / (r * width) * math.tan(beta2 - beta1)
    phi = math.acos(min(1.0, max(-1.0, c)))
    return beta + phi, beta - phi


@jit
def initial(ex, top, bot, bar_cx, cam, target, positive):
    """Starting point of the exact fit from the edges ``ex`` (4,), bar tops ``top``, bottoms
    ``bot`` and centre columns ``bar_cx`` (2,) (px); ``cam`` the
    :class:`~localizer._kernels.records.Intrinsics`, ``target`` the
    :class:`~localizer._kernels.records.TargetConstants` (bar width ``b`` and height ``H``, m).

    The common dark-side shift ``delta`` (px) from the gap against the mean bar; the
    orientation from Appendix A (eq A.14, :func:`alpha_a14`) -- the root nearer the
    bar-height estimate; the bearing from a 1-D projective fit of all four edges; ``X, Z``
    by least squares given alpha; ``Y`` from the bar tops and bottoms. Returns
    ``(p0 (5,) = (X, Z, alpha, Y, delta), (alpha1, alpha2))``.
    """
    fx, fy, cx, cy = cam.fx, cam.fy, cam.cx, cam.cy
    b, H = target.bar_width, target.bar_height
    s = 1.0 if positive else -1.0
    delta = s * ((ex[2] - ex[1]) - 0.5 * ((ex[1] - ex[0]) + (ex[3] - ex[2]))) / 4.0
    u = bar_edges_u(b)
    tx = np.empty(4)
    for k in range(4):
        sv = s if k % 2 == 0 else -s
        tx[k] = (ex[k] - delta * sv - cx) / fx
    topc = top - delta * s
    botc = bot + delta * s
    # bar-height ranges: a 3-D point on each bar's centre ray
    t = (bar_cx - cx) / fx
    zc = H * fy / (botc - topc)
    px = t * zc
    pz = zc
    alpha_h = math.atan2(-(pz[1] - pz[0]), px[1] - px[0])
    # Appendix A: bearings of the outer edges and of the centre (1-D projective fit of all 4 edges)
    A = np.empty((4, 4))
    for k in range(4):
        A[k, 0] = 1.0
        A[k, 1] = -tx[k]
        A[k, 2] = u[k]
        A[k, 3] = u[k] * tx[k]
    v = null_vector(A)
    v = v / math.hypot(v[2], v[3])
    if v[1] < 0:
        v = -v
    beta_c = math.atan2(v[0], v[1])
    r = 0.5 * (math.hypot(px[0], pz[0]) + math.hypot(px[1], pz[1]))
    a1, a2 = alpha_a14(r, 3.0 * b, beta_c, math.atan(tx[0]), math.atan(tx[3]))
    alpha0 = a1 if abs(a1 - alpha_h) <= abs(a2 - alpha_h) else a2
    c, sn = math.cos(alpha0), math.sin(alpha0)
    # X, Z given alpha: X - t Z = -u (c + t s), least squares over the four edges (normal equations)
    rhs = -u * (c + tx * sn)
    st_, stt = tx.sum(), (tx * tx).sum()
    sr, str_ = rhs.sum(), (tx * rhs).sum()
    det = 4.0 * stt - st_ * st_
    X, Z = 0.0, -1.0
    if abs(det) > 1e-15:
        X, Z = (stt * sr - st_ * str_) / det, (st_ * sr - 4.0 * str_) / det
    if not Z > 0:
        X, Z = px.mean(), pz.mean()
    uu = (t * Z - X) / (c + t * sn)
    zc2 = Z - uu * sn
    Y = 0.25 * ((((topc - cy) * zc2 / fy + 0.5 * H) + ((botc - cy) * zc2 / fy - 0.5 * H)).sum())
    return np.array([X, Z, alpha0, Y, delta]), (a1, a2)


@jit
def model(p, cam, geom, pred, J):
    """Predicted measurements and their Jacobian for parameters ``p = (X, Z, alpha, Y, delta)``
    (m, m, rad, m, px), camera ``cam`` (:class:`~localizer._kernels.records.Intrinsics`).

    Measurements, in order: the four vertical edges
    ``x_k = cx + fx (X + u_k cos a) / (Z - u_k sin a) + delta sv_k`` (``geom.u`` (4,) the
    edges' target abscissae, m; :func:`localizer._kernels.projection.edge_x_jacobian`),
    then the tops and bottoms of bars 1 and 2 at the bar centre columns, whose rays
    ``x/z = t_j`` (``geom.t`` (2,)) meet the target plane at range
    ``z_j = (Z cos a + X sin a) / (cos a + t_j sin a)``
    (:func:`localizer._kernels.projection.ray_inverse_range`):
    ``y = cy + fy (Y -+ H/2) / z_j + delta sh`` (``geom.hh`` = H/2). Fills ``pred`` (8,)
    and ``J`` (8, 5) (columns: X, Z, alpha, Y, delta) in place. ``geom``:
    :class:`~localizer._kernels.records.FitGeometry`.
    """
    fy, cy = cam.fy, cam.cy
    u, t, hh, sv, sh = geom.u, geom.t, geom.hh, geom.sv, geom.sh
    X, Z, a, Y, dl = p[0], p[1], p[2], p[3], p[4]
    c, s = math.cos(a), math.sin(a)
    for k in range(4):
        x, dx_dx, dx_dz, dx_da = edge_x_jacobian(X, Z, c, s, u[k], cam)
        pred[k] = x + dl * sv[k]
        J[k, 0] = dx_dx
        J[k, 1] = dx_dz
        J[k, 2] = dx_da
        J[k, 3] = 0.0
        J[k, 4] = sv[k]
    D, iD, dD = plane(X, Z, c, s)
    for j in range(2):
        q, dq_dx, dq_dz, dq_da = ray_inverse_range(t[j], c, s, D, iD, dD)  # 1 / z_j
        for side in range(2):  # row 4 + j: top of bar j, row 6 + j: its bottom
            yv = Y - hh if side == 0 else Y + hh
            r = 4 + 2 * side + j
            pred[r] = cy + fy * yv * q + dl * sh[side]
            J[r, 0] = fy * yv * dq_dx
            J[r, 1] = fy * yv * dq_dz
            J[r, 2] = fy * yv * dq_da
            J[r, 3] = fy * q
            J[r, 4] = sh[side]


@jit
def gauss_newton(p0, meas, wv, cam, geom, iterations):
    """Weighted Gauss-Newton from ``p0`` (5,) on ``meas`` (8,) (px) with weights ``wv`` (8,)
    (1 / sigma, px^-1), at most ``iterations`` steps; the model is :func:`model` with the
    camera ``cam`` and the geometry ``geom``. The steps solve the normal equations by
    :func:`localizer.smallmat.solve_augmented`.

    A fit stops when the range changes by less than 1e-5 of itself and alpha by less
    than 1e-5 rad (far below the noise), after one more pass for the final Jacobian.
    Returns ``(p (5,), chi2, JtWJ (5, 5), status)``: status
    :class:`~localizer._kernels.records.FitStatus` ``FITTED`` (converged or out of
    iterations), ``SINGULAR`` (singular normal equations) or ``BEHIND`` (left the
    half-space in front of the camera).
    """
    p = p0.copy()
    pred = np.empty(8)
    J = np.empty((8, 5))
    r = np.empty(8)
    A = np.empty((5, 5))
    b = np.empty(5)
    M = np.empty((5, 6))
    dp = np.empty(5)
    chi2 = 0.0
    left = iterations + 1
    while True:
        model(p, cam, geom, pred, J)
        chi2 = 0.0
        for i in range(8):
            r[i] = (meas[i] - pred[i]) * wv[i]
            chi2 += r[i] * r[i]
            for k in range(5):
                J[i, k] *= wv[i]
        for k in range(5):
            acc = 0.0
            for i in range(8):
                acc += J[i, k] * r[i]
            b[k] = acc
            for m in range(5):
                acc = 0.0
                for i in range(8):
                    acc += J[i, k] * J[i, m]
                A[k, m] = acc
        left -= 1
        if left <= 0:
            break
        # dp = A^-1 b on the 5 x 6 augmented matrix
        for k in range(5):
            for m in range(5):
                M[k, m] = A[k, m]
            M[k, 5] = b[k]
        if not solve_augmented(M, dp):
            return p, chi2, A, FitStatus.SINGULAR
        for k in range(5):
            p[k] += dp[k]
        p[2] = (p[2] + math.pi) % (2 * math.pi) - math.pi
        if not p[1] > 0:
            return p, chi2, A, FitStatus.BEHIND
        if abs(dp[1]) < 1e-5 * p[1] and abs(dp[2]) < 1e-5:
            left = min(left, 1)  # one more pass for the final Jacobian
    return p, chi2, A, FitStatus.FITTED


@jit
def fit(m, cam, target, positive, sigma_floor, iterations):
    """The numeric core of :func:`localizer.measure.exact_pose.exact_pose`.

    Args:
        m: the :class:`~localizer._kernels.records.MeasuredEdges` (px): edges (4,), tops and
            bottoms (2,) with their standard errors, bar centre columns (2,).
        cam: :class:`~localizer._kernels.records.Intrinsics` (px).
        target: :class:`~localizer._kernels.records.TargetConstants` (m).
        positive: target polarity (black bars on white).
        sigma_floor: px added in quadrature to every standard error.
        iterations: Gauss-Newton iterations per start.

    Fits from the start of :func:`initial` and from the other root of A.14 (unless
    within 0.5 deg), keeps the better minimum and widens its covariance by the
    separation of the other one as :func:`localizer.measure.exact_pose.exact_pose` describes.
    Returns a :class:`~localizer._kernels.records.PoseFit`: status ``FITTED``,
    ``SINGULAR`` (singular normal equations) or ``BEHIND`` (no fit stayed in front of the
    camera), ``p`` (5,), chi-square, ``cov`` (3, 3) over (d, beta, alpha), the two A.14
    roots and the number of minima found.
    """
    edges, edges_sd, top, bot, top_sd, bot_sd, bar_cx = m.edges, m.edges_sd, m.top, m.bottom, m.top_sd, \
        m.bottom_sd, m.bar_cx
    fx, cx = cam.fx, cam.cx
    b, H = target.bar_width, target.bar_height
    meas = np.empty(8)
    sig = np.empty(8)
    copy(edges, meas[:4])
    copy(top, meas[4:6])
    copy(bot, meas[6:])
    copy(edges_sd, sig[:4])
    copy(top_sd, sig[4:6])
    copy(bot_sd, sig[6:])
    wv = 1.0 / np.sqrt(sig * sig + sigma_floor * sigma_floor)
    top = meas[4:6].copy()
    bot = meas[6:8].copy()
    p0, cands = initial(meas[:4].copy(), top, bot, bar_cx, cam, target, positive)
    s = 1.0 if positive else -1.0
    sv = np.array([1.0, -1.0, 1.0, -1.0]) * s  # direction (+1 = +x / +y) of each edge's dark side
    sh = np.array([1.0, -1.0]) * s  # (top, bottom)
    t = (bar_cx - cx) / fx
    geom = FitGeometry(bar_edges_u(b), t, 0.5 * H, sv, sh)
    # both roots of A.14 (§4.2.2: the mirror solution), fitted one after the other
    other = cands[1] if abs(cands[0] - p0[2]) < abs(cands[1] - p0[2]) else cands[0]
    n_starts = 2 if abs(other - p0[2]) > math.radians(0.5) else 1
    best_p = p0
    best_chi2 = np.inf
    best_A = np.eye(5)
    q = p0
    chi2q = np.inf
    nsols = 0
    for k in range(n_starts):
        st = p0.copy()
        if k == 1:
            st[2] = other
        p, chi2, A, status = gauss_newton(st, meas, wv, cam, geom, iterations)
        if status == FitStatus.SINGULAR:
            return PoseFit(FitStatus.SINGULAR, p0, 0.0, np.eye(3), cands[0], cands[1], 0)
        if status == FitStatus.BEHIND:
            continue
        nsols += 1
        if chi2 < best_chi2:
            q, chi2q = best_p, best_chi2
            best_p, best_chi2, best_A = p, chi2, A.copy()
        else:
            q, chi2q = p, chi2
    if nsols == 0:
        return PoseFit(FitStatus.BEHIND, p0, 0.0, np.eye(3), cands[0], cands[1], 0)
    scale = max(1.0, best_chi2 / (meas.size - 5))
    cov = inverse(best_A) * scale
    if nsols > 1:
        dchi = (chi2q - best_chi2) / scale
        if dchi < 16.0 and abs(q[2] - best_p[2]) > 1e-6:
            w = math.exp(-0.5 * dchi)
            w = max(w / (1.0 + w), 0.25 * (1.0 - dchi / 16.0))
            for i in range(3):
                for j in range(3):
                    cov[i, j] += w * (q[i] - best_p[i]) * (q[j] - best_p[j])
    # (X, Z, alpha) -> (d, beta, alpha): d = hypot(X, Z), beta = atan2(X, Z)
    X, Z = best_p[0], best_p[1]
    d = math.hypot(X, Z)
    T = np.zeros((3, 3))
    T[0, 0] = X / d
    T[0, 1] = Z / d
    T[1, 0] = Z / (d * d)
    T[1, 1] = -X / (d * d)
    T[2, 2] = 1.0
    out = np.zeros((3, 3))  # T cov T^T
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                for m in range(3):
                    acc += T[i, k] * cov[k, m] * T[j, m]
            out[i, j] = acc
    return PoseFit(FitStatus.FITTED, best_p, best_chi2, out, cands[0], cands[1], nsols)
