r"""The pose filter's one predict and one update path, shared by the main filter and the hypotheses.

Every pose estimate of the filter (the main :class:`~localizer.filter.ekf.PoseEKF` and each
re-localization :class:`~localizer.filter.relocalize.Hypothesis`) is a :class:`PoseKF`, a filterpy
``ExtendedKalmanFilter`` over (x, y, θ) whose prediction is the pose composition ``x ⊕ u``:

* :func:`predict_pose`: filterpy's ``predict`` with ``F = ∂(x ⊕ u)/∂x`` and
  ``Q = G Q_u Gᵀ`` (``G = ∂(x ⊕ u)/∂u``), so ``P ← F P Fᵀ + G Q_u Gᵀ``;
* :func:`update_pose`: filterpy's ``update(z, HJacobian, Hx, R, residual)`` with the
  angle-wrapping residual :func:`~localizer.filter.association.innovation`. filterpy 2.0's EKF
  update is in Joseph form, ``P = (I - K H) P (I - K H)ᵀ + K R Kᵀ``, and leaves the
  innovation ``y = z ⊖ h(x⁻)`` at the prior state and its covariance ``S = H P⁻ Hᵀ + R`` on the
  filter;
* :func:`nis`: the normalised innovation squared ``yᵀ S⁻¹ y`` read from that state.

Neither wraps θ: the main filter wraps its heading after each step, the hypotheses do not (as
before the paths were shared).
"""
from __future__ import annotations

import math

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from localizer.filter.association import innovation
from localizer.filter.measurement import Measurement, is_positive_definite, measurement_jacobian, predict_measurement
from localizer.model.mount import CameraMount
from localizer.filter.motion import compose, compose_jacobians

__all__ = ["PoseKF", "is_positive_definite", "nis", "position_sigma", "predict_pose", "update_pose"]


class PoseKF(ExtendedKalmanFilter):
    """filterpy EKF over a pose (x, y, θ) whose prediction is the composition x ⊕ u.

    Args:
        x: (3,) initial pose (m, m, rad).
        P: (3, 3) its covariance.
    """

    def __init__(self, x=None, P=None) -> None:
        super().__init__(dim_x=3, dim_z=3)
        if x is not None:
            self.x = np.asarray(x, dtype=float).reshape(3, 1).copy()
        if P is not None:
            self.P = np.asarray(P, dtype=float).copy()

    def predict_x(self, u=0):
        self.x = compose(self.x, u).reshape(3, 1)


def _hx(x, pos, yaw, mount):
    return predict_measurement(x, pos, yaw, mount).reshape(3, 1)


def _H(x, pos, yaw, mount):
    return measurement_jacobian(x, pos, yaw, mount)


def predict_pose(kf: PoseKF, u: np.ndarray, Q: np.ndarray) -> None:
    """Move ``kf`` by the relative motion ``u`` (3,) with covariance ``Q`` (3, 3) (filterpy ``predict``)."""
    F, G = compose_jacobians(kf.x, u)
    kf.F = F
    kf.Q = G @ Q @ G.T
    kf.predict(u=u)


def update_pose(kf: PoseKF, m: Measurement, target_position, target_yaw: float,
                mount: CameraMount) -> float:
    """Fuse the measurement ``m`` of the target at ``target_position`` (2,), ``target_yaw`` (rad)
    into ``kf`` with filterpy's ``update``; returns the update's NIS (:func:`nis`)."""
    args = (target_position, target_yaw, mount)
    kf.update(m.z.reshape(3, 1), _H, _hx, R=m.R, args=args, hx_args=args, residual=innovation)
    return nis(kf)


def nis(kf: ExtendedKalmanFilter) -> float:
    """``yᵀ S⁻¹ y`` of ``kf``'s last update, from filterpy's innovation ``kf.y`` and its covariance ``kf.S``.

    χ²(3) when the filter is consistent. filterpy forms ``S = H (P Hᵀ) + R``; the filter used to
    recompute ``(H P) Hᵀ + R`` beside it, which differs in the last bits for about one update
    in twelve (a few ulp of the NIS; the drift figures are unchanged). Solved against ``S``
    rather than multiplied by filterpy's ``SI``, which would change more of them.
    """
    y = kf.y.reshape(-1)
    return float(y @ np.linalg.solve(kf.S, y))


def position_sigma(P) -> float:
    """The largest standard deviation (m) of the position in a pose covariance ``P`` (3, 3):
    √ of the larger eigenvalue of P_xy (closed form, on its lower triangle as ``eigvalsh``)."""
    a, b, d = P.item(0, 0), P.item(1, 0), P.item(1, 1)
    return math.sqrt(max(0.5 * (a + d) + math.hypot(0.5 * (a - d), b), 0.0))
