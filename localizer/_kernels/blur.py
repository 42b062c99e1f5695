"""The blurred box-pixel step, the edge model shared by the clipped-edge fits
(:mod:`localizer._kernels.clipped`) and the photometric refinement
(:mod:`localizer._kernels.photometric`).

A pixel ``j`` covers ``[j - 0.5, j + 0.5]`` (:mod:`localizer.model.camera`); the image of an
ideal step at ``e`` is blurred by a Gaussian of sd ``s`` sampled on the pixel grid
(taps ``-K..K``, ``K = ceil(3.5 sd)``, at least 3, normalised).
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import inline, jit

#: a pixel (or row-mean profile pixel) at or above this grey level is taken as clipped
CLIP = 254.5


#: most taps either side of the sampled Gaussian (blur sd up to 12 / 3.5 = 3.4 px is modelled
#: to 3.5 sd; a wider blur is cut at 12 px)
MAX_TAPS = 12


#: from this blur sd (px) on, the blurred step is the closed form of a continuous Gaussian
#: (:func:`blurred_step`; 0.6 % of the step from the sampled one here, 0.03 % at 3 px): one
#: erf and one exp per pixel edge instead of ``2 K + 1`` taps
ANALYTIC_SD = 1.0
_SQRT_HALF = math.sqrt(0.5)
_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)


@jit
def blur_weights(s):
    """Sampled Gaussian blur of sd ``s`` (px) on the pixel grid, taps ``-K..K`` with
    ``K = ceil(3.5 s)`` (3 at least, :data:`MAX_TAPS` at most), normalised: weights ``w``
    (2K + 1,) and their derivatives ``dw/ds`` (2K + 1,). From ``s >= ANALYTIC_SD`` on, ``w``
    is ``(s,)`` (and ``dw`` ``(0.0,)``): :func:`blurred_step` then takes the closed form."""
    if s >= ANALYTIC_SD:
        w1 = np.empty(1)
        w1[0] = s
        return w1, np.zeros(1)
    kk = min(max(3, int(math.ceil(3.5 * s))), MAX_TAPS)
    g = np.empty(2 * kk + 1)
    dg = np.empty(2 * kk + 1)
    sg = 0.0
    sdg = 0.0
    for k in range(-kk, kk + 1):
        g[k + kk] = math.exp(-0.5 * k * k / (s * s))
        dg[k + kk] = g[k + kk] * k * k / (s * s * s)
        sg += g[k + kk]
        sdg += dg[k + kk]
    w = g / sg
    dw = (dg * sg - g * sdg) / (sg * sg)
    return w, dw


@inline
def blurred_step(j, e, w, dw):
    """Fraction ``F`` of pixel ``j`` beyond an edge at ``e`` (box pixels ``[j - 0.5, j + 0.5]``)
    after the blur kernel ``w`` (:func:`blur_weights`), and its derivatives ``dF/de``, ``dF/ds``."""
    if w.size == 1:  # the closed form: F = s (psi(u1) - psi(u0)), psi(u) = u Phi(u) + phi(u)
        sd = w[0]
        u0 = (j - 0.5 - e) / sd
        u1 = (j + 0.5 - e) / sd
        c0 = 0.5 * (1.0 + math.erf(u0 * _SQRT_HALF))
        c1 = 0.5 * (1.0 + math.erf(u1 * _SQRT_HALF))
        p0 = _INV_SQRT_2PI * math.exp(-0.5 * u0 * u0)
        p1 = _INV_SQRT_2PI * math.exp(-0.5 * u1 * u1)
        return sd * (u1 * c1 + p1 - u0 * c0 - p0), c0 - c1, p1 - p0
    f = 0.0
    ds = 0.0
    de = 0.0
    kk = (w.size - 1) // 2
    for k in range(-kk, kk + 1):
        c = min(max(j - k + 0.5 - e, 0.0), 1.0)
        f += w[k + kk] * c
        ds += dw[k + kk] * c
        if abs(j - k - e) < 0.5:
            de -= w[k + kk]
    return f, de, ds


#: erfc(x) = t P(t) exp(-x^2), t = 1 / (1 + ERFC_A x), x >= 0: P by least squares on 4,000
#: Chebyshev nodes of t in (0, 1] (fitted to scipy's erfcx); |error| of erf < 3e-10 on x >= 0
ERFC_A = 0.4
ERFC_P = (0.2256758332947104, 0.22567586974362633, 0.20762010891864788, 0.17154032411404363,
          0.12151196623511365, 0.06690225653328269, 0.02319663790572366, -0.04746998944097801,
          0.08448855456246022, -0.22040214716569378, 0.22629027932494436, -0.10312632755693056,
          0.01809663381705614)


@inline
def gauss_cdf_pdf(u):
    """The standard normal ``(Phi(u), phi(u))`` from one ``exp`` (:data:`ERFC_P`: |error| of Phi
    < 1.5e-10; ``math.erf`` and ``math.exp`` cost three ``exp``'s worth)."""
    x = abs(u) * _SQRT_HALF
    e = math.exp(-x * x)
    t = 1.0 / (1.0 + ERFC_A * x)
    c = ERFC_P
    poly = c[12]
    poly = c[11] + t * poly
    poly = c[10] + t * poly
    poly = c[9] + t * poly
    poly = c[8] + t * poly
    poly = c[7] + t * poly
    poly = c[6] + t * poly
    poly = c[5] + t * poly
    poly = c[4] + t * poly
    poly = c[3] + t * poly
    poly = c[2] + t * poly
    poly = c[1] + t * poly
    poly = c[0] + t * poly
    half_tail = 0.5 * t * poly * e  # Phi(-|u|)
    return (1.0 - half_tail if u >= 0.0 else half_tail), _INV_SQRT_2PI * e


@inline
def closed_step(j, e, sd, reach, shared, u_prev, c_prev, p_prev):
    """:func:`edge_fraction`'s closed form (blur sd ``sd`` >= :data:`ANALYTIC_SD`, cut-off
    ``reach``) of pixel ``j`` for an edge at ``e``, through :func:`gauss_cdf_pdf`. When
    ``shared``, the pixel's lower side ``j - 0.5`` is the upper side of the pixel before it
    (``j - 1``, same edge and blur), whose ``(u, Phi(u), phi(u))`` were ``u_prev, c_prev,
    p_prev``: one ``exp`` per pixel instead of two. Returns ``(F, dF/de, dF/ds, u1, Phi(u1),
    phi(u1), ok)``: the last four this pixel's upper side, for the pixel after it (``ok``
    false when the pixel was beyond the cut-off)."""
    if j - e > reach:
        return 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    if e - j > reach:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    if shared:
        u0, c0, p0 = u_prev, c_prev, p_prev
    else:
        u0 = (j - 0.5 - e) / sd
        c0, p0 = gauss_cdf_pdf(u0)
    u1 = (j + 0.5 - e) / sd
    c1, p1 = gauss_cdf_pdf(u1)
    return sd * (u1 * c1 + p1 - u0 * c0 - p0), c0 - c1, p1 - p0, u1, c1, p1, True


@inline
def edge_fraction(j, e, w, dw):
    """:func:`blurred_step` of pixel ``j`` for an edge at ``e``, short-cut to ``(1, 0, 0)``
    (``(0, 0, 0)``) when the pixel lies wholly beyond (before) the edge: more than ``K + 1.5``
    px away, where the taps (``K`` px) cannot reach (``4.5 s + 1`` px for the closed form)."""
    reach = (w.size - 1) // 2 + 1.5 if w.size > 1 else 4.5 * w[0] + 1.0
    if j - e > reach:
        return 1.0, 0.0, 0.0
    if e - j > reach:
        return 0.0, 0.0, 0.0
    return blurred_step(j, e, w, dw)


@inline
def sampled_step(j, e, w, dw, kk, reach):
    """:func:`edge_fraction` for sampled taps (``w.size == 2 kk + 1 > 1``) with the half-width
    ``kk`` and the cut-off ``reach = kk + 1.5`` taken once per kernel call rather than per pixel:
    the same arithmetic in the same order (bit for bit), without re-deriving them and the
    closed-form test for every pixel (the photometric model's innermost loop: a fifth of its
    time)."""
    if j - e > reach:
        return 1.0, 0.0, 0.0
    if e - j > reach:
        return 0.0, 0.0, 0.0
    f = 0.0
    ds = 0.0
    de = 0.0
    for k in range(-kk, kk + 1):
        c = min(max(j - k + 0.5 - e, 0.0), 1.0)
        f += w[k + kk] * c
        ds += dw[k + kk] * c
        if abs(j - k - e) < 0.5:
            de -= w[k + kk]
    return f, de, ds
