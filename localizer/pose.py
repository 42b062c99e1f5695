"""Pose recovery from edge measurements (thesis §4.1-4.2, Appendix A).

Units: pixels in, metres and radians out. Conventions: :mod:`localizer.geometry`.
Image quantities are converted with the camera's focal lengths instead of the
thesis's millimetre factors (§4.7): ``x_m / f = (x - cx) / fx``,
``h_m / f = h / fy``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.camera import Camera
from localizer.edges import EdgeMeasurements
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
    inputs = [ex.copy() for _ in range(6)]
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
    del inputs
    J = np.stack(cols, axis=1)  # already scaled by one sigma
    cov = J @ J.T
    # the sign choice of 4.13 can flip the whole root: add the root spread when ambiguous
    if amb:
        cov[2, 2] += (0.5 * (cands[0] - cands[1])) ** 2
    x = z * math.tan(beta_p)
    return PoseEstimate(d, beta_p, alpha, z, x, float("nan"), cov, cands, amb)


# ---------------------------------------------------------------------- exact
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


def _edge_signs(positive: bool) -> tuple[np.ndarray, np.ndarray]:
    """Direction (+1 = towards +x / +y) of each edge's dark side: vertical edges (4,), then
    (top, bottom) of the bars."""
    s = 1.0 if positive else -1.0
    return np.array([1.0, -1.0, 1.0, -1.0]) * s, np.array([1.0, -1.0]) * s


def _initial(m: EdgeMeasurements, camera: Camera, target: TargetSpec, positive: bool) -> np.ndarray:
    b, H = target.bar_width, target.bar_height
    sv, sh = _edge_signs(positive)
    ex = np.asarray(m.edges_x, float)
    runs = np.diff(ex)
    delta = (1.0 if positive else -1.0) * (runs[1] - 0.5 * (runs[0] + runs[2])) / 4.0
    exc = ex - delta * sv
    top = np.asarray(m.top_y) - delta * sh[0]
    bot = np.asarray(m.bottom_y) - delta * sh[1]
    # bar-height ranges: a 3-D point on each bar's centre ray
    t = (np.asarray(m.bar_cx) - camera.cx) / camera.fx
    zc = H * camera.fy / (bot - top)
    px, pz = t * zc, zc
    alpha_h = math.atan2(-(pz[1] - pz[0]), px[1] - px[0])
    # Appendix A: bearings of the outer edges and of the centre (1-D projective fit of all 4 edges)
    tx = (exc - camera.cx) / camera.fx
    u = np.array([-1.5, -0.5, 0.5, 1.5]) * b
    A = np.stack([np.ones(4), -tx, u, u * tx], axis=1)
    _, _, vt = np.linalg.svd(A)
    v = vt[-1]
    v = v / math.hypot(v[2], v[3])
    if v[1] < 0:
        v = -v
    beta_c = math.atan2(v[0], v[1])
    r = 0.5 * (math.hypot(px[0], pz[0]) + math.hypot(px[1], pz[1]))
    cands = alpha_a14(r, target.active_width, beta_c, math.atan(tx[0]), math.atan(tx[3]))
    alpha0 = min(cands, key=lambda a: abs(a - alpha_h))
    c, s = math.cos(alpha0), math.sin(alpha0)
    # X, Z given alpha: X - t Z = -u (c + t s), least squares over the four edges
    rhs = -u * (c + tx * s)
    # normal equations of [1, -t] (X, Z) = rhs, closed form
    n4, st_, stt = 4.0, float(tx.sum()), float(tx @ tx)
    sr, str_ = float(rhs.sum()), float(tx @ rhs)
    det = n4 * stt - st_ * st_
    X, Z = ((stt * sr - st_ * str_) / det, (st_ * sr - n4 * str_) / det) if abs(det) > 1e-15 else (0.0, -1.0)
    if not Z > 0:
        X, Z = float(np.mean(px)), float(np.mean(pz))
    uu = (t * Z - X) / (c + t * s)
    zc2 = Z - uu * s
    Y = float(np.mean(np.concatenate([(top - camera.cy) * zc2 / camera.fy + 0.5 * H,
                                      (bot - camera.cy) * zc2 / camera.fy - 0.5 * H])))
    return np.array([X, Z, alpha0, Y, delta]), cands


def _model(p, fx: float, fy: float, cx: float, cy: float, u: tuple, t: tuple, hh: float,
           sv: tuple, sh: tuple):
    """Predicted measurements and their Jacobian for parameters ``p = (X, Z, alpha, Y, delta)``.

    Pure-Python scalars (the problem is 8 x 5; numpy's per-call overhead would
    dominate). Measurements, in order: the four vertical edges
    ``x_k = cx + fx (X + u_k cos a) / (Z - u_k sin a) + delta sv_k`` (``u_k`` the
    edges' target abscissae, m), then the tops and bottoms of bars 1 and 2 at the
    bar centre columns, whose rays ``x/z = t_j`` meet the target plane at range
    ``z_j = (Z cos a + X sin a) / (cos a + t_j sin a)``:
    ``y = cy + fy (Y -+ H/2) / z_j + delta sh``. Returns ``(pred (8,), J (8, 5))``
    as lists (columns: X, Z, alpha, Y, delta).
    """
    X, Z, a, Y, dl = p
    c, s = math.cos(a), math.sin(a)
    pred = []
    J = []
    for k in range(4):
        uk = u[k]
        N = X + uk * c
        iM = 1.0 / (Z - uk * s)
        q = N * iM
        pred.append(cx + fx * q + dl * sv[k])
        J.append((fx * iM, -fx * q * iM, fx * uk * (N * c - s / iM) * iM * iM, 0.0, sv[k]))
    D = Z * c + X * s
    iD = 1.0 / D
    dD = X * c - Z * s
    rows_t, rows_b = [], []
    for j in range(2):
        tj = t[j]
        g = c + tj * s
        q = g * iD  # 1 / z_j
        dq_dx = -g * s * iD * iD
        dq_dz = -g * c * iD * iD
        dq_da = ((tj * c - s) * D - g * dD) * iD * iD
        for yv, dst, shv in ((Y - hh, rows_t, sh[0]), (Y + hh, rows_b, sh[1])):
            dst.append((cy + fy * yv * q + dl * shv,
                        (fy * yv * dq_dx, fy * yv * dq_dz, fy * yv * dq_da, fy * q, shv)))
    for pr, jr in rows_t + rows_b:
        pred.append(pr)
        J.append(jr)
    return pred, J


def _gauss_newton(starts, meas: np.ndarray, wv: np.ndarray, args, iterations: int):
    """Weighted Gauss-Newton from each start in ``starts`` (list of (5,)), all advanced together
    (one batched solve per iteration). Returns a list of ``(p (5,), chi2, JtWJ (5, 5))``; a start
    that fails (singular system, behind the camera) is dropped.

    A fit stops when the range changes by less than 1e-5 of itself and alpha by less
    than 1e-5 rad (far below the noise), after one more pass for the final Jacobian.
    """
    ps = [[float(v) for v in p] for p in starts]
    live = list(range(len(ps)))
    last = [None] * len(ps)
    left = [iterations + 1] * len(ps)
    while live:
        preds, Js = [], []
        for i in live:
            pr, J = _model(ps[i], *args)
            preds.append(pr)
            Js.append(J)
        r = (meas[None, :] - np.array(preds)) * wv[None, :]  # (n, 8)
        Jw = np.array(Js) * wv[None, :, None]  # (n, 8, 5)
        Jt = Jw.transpose(0, 2, 1)
        A = Jt @ Jw  # (n, 5, 5)
        for k, i in enumerate(live):
            last[i] = (float(r[k] @ r[k]), A[k])
            left[i] -= 1
        step = [k for k, i in enumerate(live) if left[i] > 0]
        if not step:
            break
        try:
            dp = np.linalg.solve(A[step], (Jt[step] @ r[step][:, :, None]))[:, :, 0]
        except np.linalg.LinAlgError:
            return []
        nxt = []
        for k, d in zip(step, dp.tolist()):
            i = live[k]
            p = [ps[i][j] + d[j] for j in range(5)]
            p[2] = (p[2] + math.pi) % (2 * math.pi) - math.pi
            if not p[1] > 0:
                left[i] = -1  # left the half-space in front of the camera
                continue
            ps[i] = p
            if abs(d[1]) < 1e-5 * p[1] and abs(d[2]) < 1e-5:
                left[i] = min(left[i], 1)  # one more pass for the final Jacobian
            nxt.append(i)
        live = nxt
    return [(np.array(ps[i]), last[i][0], last[i][1]) for i in range(len(ps)) if left[i] >= 0 and last[i]]


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
    meas = np.concatenate([m.edges_x, m.top_y, m.bottom_y]).astype(float)
    sig2 = np.concatenate([m.edges_sigma, m.top_sigma, m.bottom_sigma]) ** 2 + sigma_floor ** 2
    wv = 1.0 / np.sqrt(sig2)
    p0, cands = _initial(m, camera, target, positive)
    sv, sh = _edge_signs(positive)
    t = tuple(float(v) for v in (np.asarray(m.bar_cx, float) - camera.cx) / camera.fx)
    args = (camera.fx, camera.fy, camera.cx, camera.cy, tuple(float(v) for v in target_edges_u(target)), t,
            0.5 * target.bar_height, tuple(float(v) for v in sv), tuple(float(v) for v in sh))
    dof = meas.size - p0.size
    # both roots of A.14 (§4.2.2: the mirror solution), fitted side by side
    other = cands[1] if abs(cands[0] - p0[2]) < abs(cands[1] - p0[2]) else cands[0]
    starts = [p0]
    if abs(other - p0[2]) > math.radians(0.5):
        p1 = p0.copy()
        p1[2] = other
        starts.append(p1)
    sols = _gauss_newton(starts, meas, wv, args, iterations)
    if not sols:
        raise np.linalg.LinAlgError("no pose fit converged")
    sols.sort(key=lambda s: s[1])
    p, chi2, JtJ = sols[0]
    scale = max(1.0, chi2 / dof)
    cov_p = np.linalg.inv(JtJ) * scale
    if len(sols) > 1:
        q, chi2q, _ = sols[1]
        dchi = (chi2q - chi2) / scale
        sep = q[:3] - p[:3]
        if dchi < 16.0 and abs(sep[2]) > 1e-6:
            w = math.exp(-0.5 * dchi)
            w = max(w / (1.0 + w), 0.25 * (1.0 - dchi / 16.0))
            cov_p[:3, :3] += w * np.outer(sep, sep)
    X, Z, alpha = float(p[0]), float(p[1]), float(p[2])
    d = math.hypot(X, Z)
    T = np.array([[X / d, Z / d, 0.0], [Z / d ** 2, -X / d ** 2, 0.0], [0.0, 0.0, 1.0]])
    cov = T @ cov_p[:3, :3] @ T.T
    return PoseEstimate(d, math.atan2(X, Z), alpha, Z, X, float(p[3]), cov, tuple(cands), len(sols) > 1,
                        float(p[4]), math.sqrt(chi2 / dof))


def target_edges_u(target: TargetSpec) -> np.ndarray:
    """Target abscissae ``u`` (m) of the four vertical bar edges: ``-1.5b, -0.5b, 0.5b, 1.5b``."""
    return np.array([-1.5, -0.5, 0.5, 1.5]) * target.bar_width
