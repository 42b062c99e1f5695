"""Kernels of the edges of saturated targets: a clipped, blurred-step (erf) edge model.

On a saturated (clipped) target with some blur the centroid edges
(:mod:`localizer._kernels.subpixel`) carry a per-edge error that depends on the edge's
pixel phase. The four vertical edges are then re-measured by a joint fit of the
row-mean profile (:func:`fit_bar_profile`: four edges, one blur sd, one unclipped
bright and one dark level, Levenberg-Marquardt :func:`lm_bar`), and each top and bottom
point by a position-only fit with that blur and those levels
(:func:`refine_horizontal_clipped`). The model: :mod:`localizer._kernels.blur`.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit
from localizer._kernels.arrays import copy, copy_rows
from localizer._kernels.blur import CLIP, blur_weights, blurred_step, edge_fraction
from localizer.smallmat import solve

#: starts of the joint fit: unclipped bright level (dark + f * (255 - dark)) and edge shift
#: towards the bright side (px)
B_STARTS = (1.5, 3.0)
E_STARTS = (0.0, 0.4)
#: smallest fitted blur sd (px) for which the clipped-erf edges replace the centroids
SIGMA_MIN = 0.3
#: narrowest mean run (px) of a target for the clipped-erf fit
BAR_MIN = 8.0
#: blur sd (px, :func:`profile_blur`) from which an unclipped target's edges are fitted too: its
#: centroid windows (11 px) then take in the tails of the neighbouring edges
SIGMA_BLURRED = 1.2


@jit
def profile_blur(prof, a, e_init, positive):
    """Blur sd (px) of the row-mean profile ``prof`` (first pixel at column ``a``) of a target
    with edges near ``e_init`` (4,): ``C / (sqrt(2 pi) g)`` with ``C`` the contrast between the
    gap's and the bars' middle pixels and ``g`` the mean over the two inner edges of the
    steepest change between neighbouring profile pixels within 3 px (a Gaussian-blurred step
    of box pixels; a sharp edge gives about 0.4)."""
    n = prof.size
    cg = int(round(0.5 * (e_init[1] + e_init[2]))) - a
    c0 = int(round(0.5 * (e_init[0] + e_init[1]))) - a
    c1 = int(round(0.5 * (e_init[2] + e_init[3]))) - a
    if not (0 <= c0 < n and 0 <= cg < n and 0 <= c1 < n):
        return 0.0
    contrast = abs(prof[cg] - 0.5 * (prof[c0] + prof[c1]))
    g = 0.0
    for k in (1, 2):
        gk = 0.0
        e = int(round(e_init[k])) - a
        for i in range(max(e - 3, 0), min(e + 3, n - 1)):
            gk = max(gk, abs(prof[i + 1] - prof[i]))
        g += 0.5 * gk
    if g <= 0.0:
        return 0.0
    return contrast / (math.sqrt(2.0 * math.pi) * g)


@jit
def bar_model(prof, j0, idx, p, positive, J, res):
    """Residuals ``res`` (and Jacobian ``J``) of the clipped four-edge model over the pixels
    ``idx`` (m,) of the profile ``prof`` whose first pixel is at ``j0``.

    ``p`` = (e0, e1, e2, e3, sigma, bright, dark): the brightness is
    ``dark + (bright - dark) * b(x)`` with ``b`` the blurred box-pixel fraction of bright
    (gap and margins of a positive target, the bars of a negative one), clipped at 255.
    A pixel observed clipped is not penalised while the model is clipped too.
    Returns the residual sum of squares.
    """
    rss = 0.0
    kw, kdw = blur_weights(p[4])
    for t in range(idx.size):
        i = idx[t]
        j = j0 + i
        acc = 0.0
        for c in range(7):
            J[t, c] = 0.0
        dsum = 0.0
        for k in range(4):
            f, de, ds = edge_fraction(j, p[k], kw, kdw)
            sg = 1.0 if k % 2 == 0 else -1.0  # F(e0) - F(e1) + F(e2) - F(e3): fraction inside the bars
            acc += sg * f
            J[t, k] = sg * de
            dsum += sg * ds
        if positive:
            b = 1.0 - acc
            for k in range(4):
                J[t, k] = -J[t, k]
            dsum = -dsum
        else:
            b = acc
        amp = p[5] - p[6]
        m = p[6] + amp * b
        for k in range(4):
            J[t, k] *= amp
        J[t, 4] = amp * dsum
        J[t, 5] = b
        J[t, 6] = 1.0 - b
        if m >= 255.0:
            if prof[i] >= CLIP:
                r = 0.0
                for c in range(7):
                    J[t, c] = 0.0
            else:
                r = 255.0 - prof[i]
                for c in range(7):
                    J[t, c] = 0.0
        else:
            r = m - prof[i]
        res[t] = r
        rss += r * r
    return rss


@jit
def fit_bar_profile(image, rows, bounds, e_init, positive):
    """Joint clipped-erf fit of the row-mean profile across the four vertical edges: the
    profile is the mean over ``rows`` (n,) of ``image``, from ``e_init`` (4,) (the centroid
    edges, px) out by a quarter bar; ``bounds`` (4,) the stack's median run boundaries.

    Returns ``(ok, p)`` with ``p`` = (e0..e3, sigma, bright, dark); ``ok`` is False when
    the profile is not clipped (the caller keeps the centroid edges) or the fit failed.
    """
    w = image.shape[1]
    r0, r1, r2 = bounds[1] - bounds[0], bounds[2] - bounds[1], bounds[3] - bounds[2]
    bar = (r0 + r1 + r2) / 3.0
    p = np.empty(7)
    if bar < BAR_MIN:
        return False, p
    out = max(1.0, min(0.25 * bar, 3.0))  # half the (half-bar) margin, at most 3 px
    a = int(math.floor(e_init[0] - out + 0.5))
    bnd = int(math.ceil(e_init[3] + out - 0.5))
    a = max(a, 0)
    bnd = min(bnd, w - 1)
    n = bnd - a + 1
    if n < 12:
        return False, p
    prof = np.zeros(n)
    for r in rows:
        for i in range(n):
            prof[i] += image[r, a + i]
    pmax = 0.0
    pmin = 1e9
    for i in range(n):
        prof[i] /= rows.size
        pmax = max(pmax, prof[i])
        pmin = min(pmin, prof[i])
    clipped = pmax >= CLIP
    s_est = profile_blur(prof, a, e_init, positive)
    if not clipped and not s_est >= SIGMA_BLURRED:
        return False, p
    # the pixels within 5 px (or 3 blur sd) of an edge (the plateaus further in carry only the levels)
    reach = max(5, int(math.ceil(3.0 * s_est))) if s_est >= SIGMA_BLURRED else 5
    keep = np.zeros(n, np.bool_)
    for k in range(4):
        for i in range(max(int(e_init[k]) - a - reach, 0), min(int(e_init[k]) - a + reach + 1, n)):
            keep[i] = True
    idx = np.nonzero(keep)[0]
    best = np.empty(7)
    best_cost = np.inf
    if not clipped:  # blurred, not clipped: one start, at the centroids and the profile's levels
        for k in range(4):
            p[k] = e_init[k]
        p[4] = s_est
        p[5] = pmax
        p[6] = pmin
        lm_bar(prof, a, idx, p, positive, np.int64(30))
        for k in range(4):
            if abs(p[k] - e_init[k]) > 1.5:
                return False, p
        return p[4] >= SIGMA_MIN, p
    for start in range(len(B_STARTS) * len(E_STARTS)):
        # edges start from the centroids moved towards their bright side (clipping biases
        # the centroids towards the dark side)
        de = E_STARTS[start // len(B_STARTS)]
        for k in range(4):
            out_k = 1.0 if (k % 2 == 0) != positive else -1.0  # bright side of edge k: +x when 1
            p[k] = e_init[k] + out_k * de
        p[4] = 0.5
        p[6] = pmin
        p[5] = pmin + B_STARTS[start % len(B_STARTS)] * (255.0 - pmin)
        # iteration counts typed int64, not Literal[int](6) and (30): one compiled lm_bar, not two
        cost = lm_bar(prof, a, idx, p, positive, np.int64(6))
        if cost < best_cost:
            best_cost = cost
            copy(p, best)
    copy(best, p)
    lm_bar(prof, a, idx, p, positive, np.int64(30))
    # sharp edges: the clipped pixels hide where in them each edge lies, and the model
    # has nothing to add to the centroids (whose common shift the pose fit takes out)
    if p[4] < SIGMA_MIN:
        return False, p
    for k in range(4):
        if abs(p[k] - e_init[k]) > 1.5:
            return False, p
    return True, p


@jit
def lm_bar(prof, a, idx, p, positive, iterations):
    """Levenberg-Marquardt of :func:`bar_model` from ``p`` (7,) (updated in place), at most
    ``iterations`` steps; the normal equations are solved by :func:`localizer.smallmat.solve`.
    Returns the cost (sum of squared residuals, grey levels^2)."""
    n = idx.size
    J = np.empty((n, 7))
    res = np.empty(n)
    lam = 1e-3
    cost = bar_model(prof, a, idx, p, positive, J, res)
    q = np.empty(7)
    Jq = np.empty((n, 7))
    rq = np.empty(n)
    A = np.empty((7, 7))
    g = np.empty(7)
    for it in range(iterations):
        for a_ in range(7):  # J^T J and J^T res
            for b_ in range(a_, 7):
                acc = 0.0
                for t in range(n):
                    acc += J[t, a_] * J[t, b_]
                A[a_, b_] = acc
                A[b_, a_] = acc
            acc = 0.0
            for t in range(n):
                acc += J[t, a_] * res[t]
            g[a_] = acc
        for c in range(7):
            A[c, c] += lam * A[c, c] + 1e-9
        step = solve(A, g)
        for c in range(7):
            q[c] = p[c] - step[c]
        q[4] = min(max(q[4], 0.05), 3.0)
        q[5] = max(q[5], 255.0)
        cq = bar_model(prof, a, idx, q, positive, Jq, rq)
        if cq < cost:
            conv = cost - cq < 1e-6 * (cost + 1e-9)
            copy(q, p)
            copy_rows(Jq, J)
            copy(rq, res)
            cost = cq
            lam = max(lam * 0.3, 1e-7)
            if conv:
                break
        else:
            lam *= 10.0
            if lam > 1e6:
                break
    return cost


@jit
def refine_clipped(image, fixed, start, hw_dark, hw_bright, sgn, vertical, fit):
    """Position (px) of one edge by a clipped erf fit with the blur sd and levels of ``fit``
    (:class:`~localizer._kernels.records.ProfileFit`, shared by all edges of the target;
    Gauss-Newton on the position only), starting from ``start`` (px), along row ``fixed``
    of ``image`` (or column ``fixed`` when ``vertical``); ``sgn`` the sign of ``f(j+1) - f(j)``
    across the edge (dark to bright when positive). The window reaches ``hw_dark`` px into
    the dark side and ``hw_bright`` px into the bright side."""
    s, bright, dark = fit.sigma, fit.bright, fit.dark
    n_img = image.shape[0] if vertical else image.shape[1]
    if sgn > 0:
        lo = int(math.floor(start - hw_dark + 0.5))
        hi = int(math.ceil(start + hw_bright - 0.5))
    else:
        lo = int(math.floor(start - hw_bright + 0.5))
        hi = int(math.ceil(start + hw_dark - 0.5))
    lo = max(lo, 0)
    hi = min(hi, n_img - 1)
    e = start
    amp = bright - dark
    kw, kdw = blur_weights(s)
    for it in range(6):
        a11 = 0.0
        g1 = 0.0
        for j in range(lo, hi + 1):
            v = np.float64(image[j, fixed]) if vertical else np.float64(image[fixed, j])
            f, de, ds = blurred_step(j, e, kw, kdw)
            b = f if sgn > 0 else 1.0 - f
            dm = amp * (de if sgn > 0 else -de)
            m = dark + amp * b
            if m >= 255.0:  # clipped model: no position information (observed clipped or not)
                continue
            r = m - v
            a11 += dm * dm
            g1 += dm * r
        if a11 <= 1e-9:
            break
        stp = g1 / a11
        stp = min(max(stp, -0.5), 0.5)
        e -= stp
        if abs(stp) < 1e-4:
            break
    if abs(e - start) > 1.75:
        return start
    return e


@jit
def refine_horizontal_clipped(image, cols, grp, ys, positive, hbar, margin, fit):
    """:func:`refine_clipped` down each column ``cols`` (m,) around the centroid estimate
    ``ys`` (m,) (px; group ``grp`` (m,) = 2 * side + bar, side 0 = top) with the blur and
    levels of ``fit``; ``hbar`` the shorter bar's height (rows); the window's dark side
    stops at half the ``margin`` (px)."""
    out = np.empty(ys.size)
    pol = 1.0 if positive else -1.0
    hw_b = min(max(hbar / 8.0, 1.0), 4.0) + 1.0
    hw_d = hw_b
    if not positive:
        hw_d = min(hw_b, max(1.0, 0.5 * margin))
    for i in range(ys.size):
        side = grp[i] // 2
        sgn = -pol if side == 0 else pol
        out[i] = refine_clipped(image, cols[i], ys[i], hw_d, hw_b, sgn, True, fit)
    return out
