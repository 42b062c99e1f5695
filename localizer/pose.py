"""Pose recovery from edge measurements (thesis §4.1-4.2, Appendix A).

Units: pixels in, metres and radians out. Conventions: :mod:`localizer.geometry`.
Image quantities are converted with the camera's focal lengths instead of the
thesis's millimetre factors (§4.7): ``x_m / f = (x - cx) / fx``,
``h_m / f = h / fy``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from localizer.camera import Camera
from localizer.edges import EdgeMeasurements, _edge_rows, _subpixel, makes_target
from localizer.smallmat import inverse, null_vector
from localizer.target import TargetSpec


@dataclass(frozen=True)
class PoseEstimate:
    distance: float  # m
    beta: float  # rad
    alpha: float  # rad
    z: float  # m, along the optical axis
    x: float  # m, camera-frame lateral position of the target centre
    height: float  # m, camera-frame y of the target centre (nan if not estimated)
    covariance: np.ndarray  # (3, 3) over (d, beta, alpha), m and rad
    alpha_candidates: tuple[float, float]  # rad, the two roots of eq 4.13 / A.13
    ambiguous: bool  # both roots were legitimate (§4.2.2)
    edge_bias: float = 0.0  # px, common shift of every edge towards its dark side
    rms: float = float("nan")  # normalised fit residual (exact only)


# --------------------------------------------------------------------- thesis
def thesis_alpha(ratio: float, beta_p: float, sign: int) -> tuple[float, tuple[float, float], bool]:
    """Solve eq 4.12 for alpha with the §4.2.2 rule.

    Args:
        ratio: ``(H/W) * (dx/dy)``, the measured width/height ratio over the true one.
        beta_p: beta' (rad), the bearing of the image mid-point m (eq 4.4).
        sign: +1 if the right bar is taller (right edge nearer, alpha > 0), -1 if
            the left bar is taller, 0 if undecided. (Ties of the half-pixel heights at
            the centre columns are first broken by the heights averaged over each
            bar's columns, :func:`localizer.edges.thesis_edges`.)
    Returns:
        ``(alpha, (alpha1, alpha2), ambiguous)``. ``alpha1 = beta' + phi`` (4.14),
        ``alpha2 = beta' - phi`` (4.15), ``phi = acos(ratio * cos beta')`` (argument
        clipped to [-1, 1]). The root whose sign agrees with ``sign`` is taken; if
        both agree (the interval ``0..2 beta'`` of §4.2.2) the one of larger
        magnitude, which reproduces the thesis's over-estimates at small angles
        (Tables 5.3-5.4: 0 -> 4.4, 5 -> 13, 0 -> 6.8, 10 -> 14.5 degrees); if none
        agrees, the one nearer zero. When the half-pixel heights tie (``sign`` 0)
        the target is assumed turned towards the camera: the sign of beta' is
        used (the root nearer zero if beta' is 0 too).
    """
    phi = math.acos(min(1.0, max(-1.0, ratio * math.cos(beta_p))))
    a1, a2 = beta_p + phi, beta_p - phi
    if sign == 0:
        if beta_p != 0.0:
            return (a1 if beta_p > 0 else a2), (a1, a2), True
        return (a1 if abs(a1) <= abs(a2) else a2), (a1, a2), True
    ok = [a for a in (a1, a2) if a * sign >= 0]
    if len(ok) == 2:
        return (a1 if abs(a1) >= abs(a2) else a2), (a1, a2), True
    if len(ok) == 1:
        return ok[0], (a1, a2), False
    return (a1 if abs(a1) <= abs(a2) else a2), (a1, a2), False


def _thesis_core(edges_x: np.ndarray, h1: float, h2: float, camera: Camera, target: TargetSpec,
                 tie_sign: int = 0):
    w = edges_x[3] - edges_x[0]  # target width in the image (px), §4.7
    h = 0.5 * (h1 + h2)  # centre height (px)
    xc = 0.25 * (edges_x[0] + edges_x[1] + edges_x[2] + edges_x[3])  # mean of the bar centre lines
    z = target.bar_height * camera.fy / h  # eq 4.3 / 4.11
    tb = (xc - camera.cx) / camera.fx  # eq 4.4
    beta_p = math.atan(tb)
    d = z * math.sqrt(1.0 + tb * tb)  # eq 4.5
    ratio = target.active_height / target.active_width * (w / camera.fx) / (h / camera.fy)
    sign = tie_sign if abs(h2 - h1) < 1e-9 else (1 if h2 > h1 else -1)
    alpha, cands, amb = thesis_alpha(ratio, beta_p, sign)
    return d, beta_p, alpha, z, cands, amb


def thesis_pose(m: EdgeMeasurements, camera: Camera, target: TargetSpec) -> PoseEstimate:
    """Eqs 4.3, 4.4, 4.5 and 4.13 on the half-pixel measurements.

    The covariance propagates the half-pixel rule's uniform +-0.5 px error of
    each edge through the equations by secant differences of one standard
    deviation (finite near the acos singularity).
    """
    h1, h2 = (float(v) for v in m.bar_heights)
    ex = np.asarray(m.edges_x, float)
    d, beta_p, alpha, z, cands, amb = _thesis_core(ex, h1, h2, camera, target, m.height_sign)
    base = np.array([d, beta_p, alpha])
    s = float(m.edges_sigma[0])
    cols = []
    for k in range(4):
        e = ex.copy()
        e[k] += s
        dd, bb, aa, *_ = _thesis_core(e, h1, h2, camera, target, m.height_sign)
        cols.append((np.array([dd, bb, aa]) - base))
    for k in range(2):
        hh = [h1, h2]
        hh[k] += s * math.sqrt(2.0)
        # keep the sign decision of the measurement itself
        dd, bb, aa, *_ = _thesis_core(ex, hh[0], hh[1], camera, target, m.height_sign)
        if (aa > 0) != (alpha > 0) and abs(alpha) > 1e-9:
            aa = alpha
        cols.append((np.array([dd, bb, aa]) - base))
    J = np.stack(cols, axis=1)  # already scaled by one sigma
    cov = J @ J.T
    # the sign choice of 4.13 can flip the whole root: add the root spread when ambiguous
    if amb:
        cov[2, 2] += (0.5 * (cands[0] - cands[1])) ** 2
    x = z * math.tan(beta_p)
    return PoseEstimate(d, beta_p, alpha, z, x, float("nan"), cov, cands, amb)


# ---------------------------------------------------------------------- exact
@numba.njit(cache=True, nogil=True)
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


@numba.njit(cache=True, nogil=True)
def _initial(ex, top, bot, bar_cx, fx, fy, cx, cy, b, H, positive):
    """Starting point of the exact fit from the edges ``ex`` (4,), bar tops ``top``, bottoms
    ``bot`` and centre columns ``bar_cx`` (2,) (px); ``b``, ``H`` bar width and height (m).

    The common dark-side shift ``delta`` (px) from the gap against the mean bar; the
    orientation from Appendix A (eq A.14, :func:`alpha_a14`) -- the root nearer the
    bar-height estimate; the bearing from a 1-D projective fit of all four edges; ``X, Z``
    by least squares given alpha; ``Y`` from the bar tops and bottoms. Returns
    ``(p0 (5,) = (X, Z, alpha, Y, delta), (alpha1, alpha2))``.
    """
    s = 1.0 if positive else -1.0
    delta = s * ((ex[2] - ex[1]) - 0.5 * ((ex[1] - ex[0]) + (ex[3] - ex[2]))) / 4.0
    u = np.array([-1.5, -0.5, 0.5, 1.5]) * b
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


@numba.njit(cache=True, nogil=True)
def _model(p, fx, fy, cx, cy, u, t, hh, sv, sh, pred, J):
    """Predicted measurements and their Jacobian for parameters ``p = (X, Z, alpha, Y, delta)``.

    Measurements, in order: the four vertical edges
    ``x_k = cx + fx (X + u_k cos a) / (Z - u_k sin a) + delta sv_k`` (``u_k`` (4,) the
    edges' target abscissae, m), then the tops and bottoms of bars 1 and 2 at the
    bar centre columns, whose rays ``x/z = t_j`` (``t`` (2,)) meet the target plane at range
    ``z_j = (Z cos a + X sin a) / (cos a + t_j sin a)``:
    ``y = cy + fy (Y -+ H/2) / z_j + delta sh``. Fills ``pred`` (8,) and ``J`` (8, 5)
    (columns: X, Z, alpha, Y, delta) in place.
    """
    X, Z, a, Y, dl = p[0], p[1], p[2], p[3], p[4]
    c, s = math.cos(a), math.sin(a)
    for k in range(4):
        uk = u[k]
        N = X + uk * c
        iM = 1.0 / (Z - uk * s)
        q = N * iM
        pred[k] = cx + fx * q + dl * sv[k]
        J[k, 0] = fx * iM
        J[k, 1] = -fx * q * iM
        J[k, 2] = fx * uk * (N * c - s / iM) * iM * iM
        J[k, 3] = 0.0
        J[k, 4] = sv[k]
    D = Z * c + X * s
    iD = 1.0 / D
    dD = X * c - Z * s
    for j in range(2):
        tj = t[j]
        g = c + tj * s
        q = g * iD  # 1 / z_j
        dq_dx = -g * s * iD * iD
        dq_dz = -g * c * iD * iD
        dq_da = ((tj * c - s) * D - g * dD) * iD * iD
        for side in range(2):  # row 4 + j: top of bar j, row 6 + j: its bottom
            yv = Y - hh if side == 0 else Y + hh
            r = 4 + 2 * side + j
            pred[r] = cy + fy * yv * q + dl * sh[side]
            J[r, 0] = fy * yv * dq_dx
            J[r, 1] = fy * yv * dq_dz
            J[r, 2] = fy * yv * dq_da
            J[r, 3] = fy * q
            J[r, 4] = sh[side]


@numba.njit(cache=True, nogil=True)
def _gauss_newton(p0, meas, wv, fx, fy, cx, cy, u, t, hh, sv, sh, iterations):
    """Weighted Gauss-Newton from ``p0`` (5,) on ``meas`` (8,) with weights ``wv`` (8,)
    (1 / sigma, px^-1); the model is :func:`_model` with the camera and target constants.

    A fit stops when the range changes by less than 1e-5 of itself and alpha by less
    than 1e-5 rad (far below the noise), after one more pass for the final Jacobian.
    Returns ``(p (5,), chi2, JtWJ (5, 5), status)``: status 1 converged or out of
    iterations, 0 singular normal equations, -1 left the half-space in front of the camera.
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
        _model(p, fx, fy, cx, cy, u, t, hh, sv, sh, pred, J)
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
        # dp = A^-1 b, Gaussian elimination with partial pivoting on the 5 x 6 augmented matrix
        for k in range(5):
            for m in range(5):
                M[k, m] = A[k, m]
            M[k, 5] = b[k]
        for k in range(5):
            piv = k
            for i in range(k + 1, 5):
                if abs(M[i, k]) > abs(M[piv, k]):
                    piv = i
            if M[piv, k] == 0.0:
                return p, chi2, A, 0
            if piv != k:
                for m in range(6):
                    M[k, m], M[piv, m] = M[piv, m], M[k, m]
            for i in range(k + 1, 5):
                f = M[i, k] / M[k, k]
                for m in range(k, 6):
                    M[i, m] -= f * M[k, m]
        for k in range(4, -1, -1):
            acc = M[k, 5]
            for m in range(k + 1, 5):
                acc -= M[k, m] * dp[m]
            dp[k] = acc / M[k, k]
        for k in range(5):
            p[k] += dp[k]
        p[2] = (p[2] + math.pi) % (2 * math.pi) - math.pi
        if not p[1] > 0:
            return p, chi2, A, -1
        if abs(dp[1]) < 1e-5 * p[1] and abs(dp[2]) < 1e-5:
            left = min(left, 1)  # one more pass for the final Jacobian
    return p, chi2, A, 1


@numba.njit(cache=True, nogil=True)
def _fit(edges, edges_sd, top, bot, top_sd, bot_sd, bar_cx, sigma_floor, fx, fy, cx, cy, b, H, positive,
         iterations):
    """The numeric core of :func:`exact_pose`: measurements (px) ``edges`` (4,), ``top``
    and ``bot`` (2,) with standard errors ``edges_sd`` (4,), ``top_sd``, ``bot_sd`` (2,),
    bar centre columns ``bar_cx`` (2,).

    Fits from the start of :func:`_initial` and from the other root of A.14 (unless
    within 0.5 deg), keeps the better minimum and widens its covariance by the
    separation of the other one as :func:`exact_pose` describes. Returns ``(status,
    p (5,), chi2, cov (3, 3) over (d, beta, alpha), (alpha1, alpha2), n_solutions)``;
    status 1 = fitted, 0 = singular normal equations, -1 = no fit stayed in front of
    the camera.
    """
    meas = np.empty(8)
    sig = np.empty(8)
    meas[:4] = edges
    meas[4:6] = top
    meas[6:] = bot
    sig[:4] = edges_sd
    sig[4:6] = top_sd
    sig[6:] = bot_sd
    wv = 1.0 / np.sqrt(sig * sig + sigma_floor * sigma_floor)
    top = meas[4:6].copy()
    bot = meas[6:8].copy()
    p0, cands = _initial(meas[:4].copy(), top, bot, bar_cx, fx, fy, cx, cy, b, H, positive)
    s = 1.0 if positive else -1.0
    sv = np.array([1.0, -1.0, 1.0, -1.0]) * s  # direction (+1 = +x / +y) of each edge's dark side
    sh = np.array([1.0, -1.0]) * s  # (top, bottom)
    t = (bar_cx - cx) / fx
    u = np.array([-1.5, -0.5, 0.5, 1.5]) * b
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
        p, chi2, A, status = _gauss_newton(st, meas, wv, fx, fy, cx, cy, u, t, 0.5 * H, sv, sh, iterations)
        if status == 0:
            return 0, p0, 0.0, np.eye(3), cands, 0
        if status < 0:
            continue
        nsols += 1
        if chi2 < best_chi2:
            q, chi2q = best_p, best_chi2
            best_p, best_chi2, best_A = p, chi2, A.copy()
        else:
            q, chi2q = p, chi2
    if nsols == 0:
        return -1, p0, 0.0, np.eye(3), cands, 0
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
    return 1, best_p, best_chi2, out, cands, nsols


def exact_pose(m: EdgeMeasurements, camera: Camera, target: TargetSpec, positive: bool,
               sigma_floor: float = 0.05, iterations: int = 8) -> PoseEstimate:
    """Perspective-exact pose by weighted Gauss-Newton over every measured edge.

    Unknowns ``(X, Z, alpha, Y, delta)``: target centre (m), orientation (rad), and
    ``delta`` (px), the common shift of every edge towards its dark side (blur
    asymmetry, saturation clipping) -- identifiable because the gap and the bars
    are equally wide on the target.

    Far away the widths alone allow two orientations (the thesis's ambiguity,
    §4.2.2; the mirror solution about the line of sight) and only the small
    bar-height difference separates them. The fit is therefore started from
    the root of Appendix A's analytic solution (eq A.14) nearer the bar-height
    estimate and again from the other root (unless the two are within 0.5 deg);
    the better minimum is reported. When the other one is not ruled out (chi-square difference below
    16) the covariance is widened by the separation of the two minima, weighted
    by their relative likelihood, so that it says honestly how little the image
    tells about alpha.

    Measurement standard deviations are the edges' standard errors plus
    ``sigma_floor`` (px) in quadrature; the covariance is ``(J^T W J)^-1``
    scaled up by the reduced chi-square when it exceeds one, mapped to
    (d, beta, alpha).
    """
    fit = _fit(m.edges_x, m.edges_sigma, m.top_y, m.bottom_y, m.top_sigma, m.bottom_sigma, m.bar_cx,
               float(sigma_floor), float(camera.fx), float(camera.fy), float(camera.cx), float(camera.cy),
               float(target.bar_width), float(target.bar_height), bool(positive), int(iterations))
    return _estimate(*fit)


def _estimate(status, p, chi2, cov, cands, nsols) -> PoseEstimate:
    """The :class:`PoseEstimate` of a :func:`_fit` result (raises ``LinAlgError`` on failure)."""
    if status == 0:
        raise np.linalg.LinAlgError("singular normal equations in the pose fit")
    if status < 0:
        raise np.linalg.LinAlgError("no pose fit converged")
    X, Z, alpha, Y, delta = p.tolist()
    return PoseEstimate(math.hypot(X, Z), math.atan2(X, Z), alpha, Z, X, Y, cov, tuple(cands), nsols > 1,
                        delta, math.sqrt(chi2 / 3.0))  # 8 measurements, 5 unknowns


def exact_measure(image: np.ndarray, camera: Camera, target: TargetSpec, st, sigma_floor: float,
                  width_tolerance: float, width_slack: float, min_rows: float, iterations: int = 8):
    """:func:`localizer.edges.subpixel_edges`, the target test of
    :func:`localizer.edges.makes_target` and :func:`exact_pose` of the verified stack ``st``,
    in one compiled call (:func:`_exact_kernel`), for a camera without lens distortion: the
    per-target path of ``detect_targets``, where Python between the steps cost as much as
    the steps.

    Returns ``(edges, bar_cx, top, bottom, pose)``: tuples of pixel coordinates (4, 2, 2, 2)
    and the :class:`PoseEstimate` (None when the edges do not make a target or the fit
    fails).
    """
    (t0, b0), (t1, b1) = st.ends
    status, v, cov = _exact_kernel(
        image, st.rows, st.bounds, t0, b0, t1, b1, bool(st.positive), float(sigma_floor), float(camera.fx),
        float(camera.fy), float(camera.cx), float(camera.cy), float(target.bar_width), float(target.bar_height),
        int(iterations), float(width_tolerance), float(width_slack), float(min_rows))
    v = v.tolist()
    est = None
    if status == 1:
        est = PoseEstimate(v[10], v[11], v[12], v[13], v[14], v[15], cov, (v[17], v[18]), v[19] > 1, v[16],
                           math.sqrt(v[20] / 3.0))  # 8 measurements, 5 unknowns
    return tuple(v[:4]), (v[4], v[5]), (v[6], v[7]), (v[8], v[9]), est


@numba.njit(cache=True, nogil=True)
def _exact_kernel(image, stack_rows, bounds, t0, b0, t1, b1, positive, sigma_floor, fx, fy, cx, cy, b, H,
                  iterations, width_tolerance, width_slack, min_rows):
    """:func:`exact_measure`'s compiled body. Returns ``(status, v (21,), cov (3, 3))``:
    status 1 = a pose, 0 = not a target or no fit; ``v`` = edges (4), bar centre columns
    (2), tops (2), bottoms (2), d, beta, alpha, Z, X, Y, delta, the two A.14 roots, the
    number of minima found and chi-square."""
    ends = np.empty((2, 2), np.int64)
    ends[0, 0], ends[0, 1], ends[1, 0], ends[1, 1] = t0, b0, t1, b1
    rows = _edge_rows(stack_rows)
    edges, sd_e, cxs, icpt, sig, _, _, _ = _subpixel(image, rows, bounds, ends, positive)
    v = np.zeros(21)
    v[:4] = edges
    v[4:6] = cxs
    v[6:10] = icpt
    if not makes_target(edges[0], edges[1], edges[2], edges[3], icpt[2] - icpt[0], icpt[3] - icpt[1],
                        width_tolerance, width_slack, min_rows):
        return 0, v, np.eye(3)
    status, p, chi2, cov, cands, nsols = _fit(edges, sd_e, icpt[:2], icpt[2:], sig[:2], sig[2:], cxs, sigma_floor,
                                              fx, fy, cx, cy, b, H, positive, iterations)
    if status != 1:
        return 0, v, np.eye(3)
    v[10] = math.hypot(p[0], p[1])
    v[11] = math.atan2(p[0], p[1])
    v[12] = p[2]
    v[13] = p[1]
    v[14] = p[0]
    v[15] = p[3]
    v[16] = p[4]
    v[17] = cands[0]
    v[18] = cands[1]
    v[19] = nsols
    v[20] = chi2
    return 1, v, cov
