"""Where the target's edges and lines image: the one projection of the pose kernels.

Conventions: :mod:`localizer.model.geometry` (camera frame x right, y down, z forward; target
centre at ``(X, Y, Z)`` m; orientation ``a`` = alpha rad, thesis sign). A point at target
abscissa ``u`` (m, to the target's right) lies at ``(X + u cos a, ., Z - u sin a)``, so
the target's vertical line at ``u`` images at column

    x = cx + fx (X + u cos a) / (Z - u sin a)

(:func:`edge_x`, :func:`edge_x_jacobian`). The bar edges are at ``u = -1.5b, -0.5b,
0.5b, 1.5b`` (:func:`bar_edge_u`, :func:`localizer.model.geometry.bar_edges_u`). The ray of a
column with ``x / z = t`` meets the target plane at range ``z = D / (cos a + t sin a)``,
``D = Z cos a + X sin a`` (:func:`plane`, :func:`ray_inverse_range`); a target row at
``v`` (m, down) images there at ``y = cy + fy (Y + v) / z``.

``c``, ``s`` are ``cos a``, ``sin a``; ``cam`` an
:class:`~localizer._kernels.records.Intrinsics`.
"""
from __future__ import annotations

import numpy as np

from localizer._jit import inline, jit


@inline
def bar_edge_u(k, b):
    """Target abscissa (m) of vertical bar edge ``k`` (0..3, left to right) for bar width
    ``b`` (m): ``(k - 1.5) b``."""
    return (k - 1.5) * b


@jit
def bar_edges_u(b):
    """``(4,)`` target abscissae (m) of the four vertical bar edges (:func:`bar_edge_u`)."""
    u = np.empty(4)
    for k in range(4):
        u[k] = bar_edge_u(k, b)
    return u


@inline
def edge_x(X, Z, c, s, u, cam):
    """Image column (px) of the target's vertical line at abscissa ``u`` (m)."""
    return cam.cx + cam.fx * (X + u * c) / (Z - u * s)


@inline
def edge_x_jacobian(X, Z, c, s, u, cam):
    """:func:`edge_x` and its derivatives: ``(x, dx/dX, dx/dZ, dx/dalpha)`` (px, px/m, px/m,
    px/rad), computed through ``1 / (Z - u sin a)``."""
    fx = cam.fx
    N = X + u * c
    iM = 1.0 / (Z - u * s)
    q = N * iM
    return cam.cx + fx * q, fx * iM, -fx * q * iM, fx * u * (N * c - s / iM) * iM * iM


@inline
def plane(X, Z, c, s):
    """The target plane's ``(D, 1 / D, dD/dalpha)`` with ``D = Z cos a + X sin a`` (m)."""
    D = Z * c + X * s
    return D, 1.0 / D, X * c - Z * s


@inline
def ray_inverse_range(t, c, s, D, iD, dD):
    """``1 / z`` (1/m) where the ray ``x / z = t`` meets the target plane (``D, iD, dD`` from
    :func:`plane`), and its derivatives over ``X``, ``Z`` and ``alpha``."""
    g = c + t * s
    q = g * iD
    return q, -g * s * iD * iD, -g * c * iD * iD, ((t * c - s) * D - g * dD) * iD * iD
