r"""Target pose in the camera frame and the thesis's angle conventions.

Top view (camera frame seen from above, x right, z forward; thesis Figs 4.1-4.4)::

                      target plane (left edge L, right edge R)
                 L  __________T__________  R        alpha > 0: R nearer than L
                        \     |       ^ n (target normal, pointing away from camera)
                         \    | d     |
                          \   |       the plane's direction e = (cos a, -sin a)
                   beta -> \  |       in (x, z): alpha is the angle between the
                            \ |       target plane and the image plane, i.e.
               optical axis  \|       between the target normal and the optical axis
                    z ^       O  lens centre
                      |
                      +--> x

* ``beta`` (rad): angle from the optical axis to the line from the lens
  centre O to the target centre T; ``beta > 0`` when T is right of the axis
  (eq 4.4, ``tan beta = x / f``).
* ``alpha`` (rad): angle between the target plane and the image plane
  (thesis §4.1, Fig. 4.4), measured like beta: positive when the target's
  right edge is nearer the camera (smaller z) than its left edge. The target
  normal then points along ``(sin alpha, 0, cos alpha)``; a target squarely
  facing the camera (normal along OT) has ``alpha == beta``; a target parallel
  to the image plane has ``alpha == 0``. The rotation angle between the target
  normal and OT is ``gamma = alpha - beta`` (eq 4.6).
* ``d`` (m): horizontal distance from O to T (eq 4.5); ``z = d cos(beta)`` is
  the range along the optical axis (eq 4.3).
* ``height`` (m): camera-frame ``y`` of T (positive = below the optical axis).

A point at target coordinates ``(u, v)`` (m; ``u`` to the target's right,
``v`` down, origin at T) is at ``T + u * (cos a, 0, -sin a) + v * (0, 1, 0)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TargetPose:
    """Ground-truth or estimated pose of a target centre in the camera frame."""

    distance: float  # m, horizontal lens-centre-to-target-centre distance d
    beta: float  # rad, bearing of the target centre, > 0 right of the optical axis
    alpha: float  # rad, target plane vs image plane, > 0 when right edge nearer
    height: float = 0.0  # m, camera-frame y of the target centre (down positive)

    def __post_init__(self) -> None:
        for name in ("distance", "beta", "alpha", "height"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"TargetPose.{name} must be finite, got {getattr(self, name)!r}")
        if self.distance <= 0:
            raise ValueError(f"TargetPose.distance must be positive (m), got {self.distance!r}")

    @property
    def centre(self) -> np.ndarray:
        """``(3,)`` camera-frame position of the target centre T (m)."""
        return np.array([self.distance * math.sin(self.beta), self.height,
                         self.distance * math.cos(self.beta)])

    @property
    def z(self) -> float:
        """Range of T along the optical axis (m)."""
        return self.distance * math.cos(self.beta)

    def points(self, u, v) -> np.ndarray:
        """Camera-frame points (m), ``(..., 3)``, of target coordinates ``u``, ``v`` (m, broadcast)."""
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        cx, cy, cz = self.distance * math.sin(self.beta), self.height, self.distance * math.cos(self.beta)  # centre
        ca, sa = math.cos(self.alpha), math.sin(self.alpha)
        # np.stack of the broadcast coordinates, filled in place (the same values, less overhead)
        out = np.empty(np.broadcast_shapes(u.shape, v.shape) + (3,))
        out[..., 0] = cx + u * ca
        out[..., 1] = cy + v
        out[..., 2] = cz - u * sa
        return out


def bar_edges_u(bar_width: float) -> np.ndarray:
    """Target ``u`` (m) of the four vertical bar edges, left to right: ``-1.5b, -0.5b, 0.5b, 1.5b``
    (``(k - 1.5) b``; compiled code uses :func:`localizer._kernels.projection.bar_edge_u`, which
    gives the same values)."""
    return np.array([-1.5, -0.5, 0.5, 1.5]) * bar_width
