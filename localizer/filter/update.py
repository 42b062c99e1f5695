r"""The pose filter's one predict and one update path, shared by the main filter and the hypotheses.

Every pose estimate of the filter (the main :class:`~localizer.filter.ekf.PoseEKF` and each
re-localization :class:`~localizer.filter.relocalize.Hypothesis`) is a :class:`PoseKF`: filterpy
2.0's ``ExtendedKalmanFilter`` over (x, y, θ), operation for operation (the same attributes and
the same numpy and ``scipy.linalg`` calls in the same order, so the same numbers to the last bit:
``tests/filter/test_update.py`` holds it against filterpy's own class), whose prediction is the
pose composition ``x ⊕ u``. It is written out here because importing ``filterpy.kalman`` imports
every filter of the package and, through ``filterpy.stats``, ``scipy.stats`` (about 40 MB of
resident memory in each env process, issue 12); filterpy is imported only for
:attr:`PoseKF.log_likelihood`.

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
import sys
from copy import deepcopy

import numpy as np
from scipy import linalg

from localizer.filter.association import innovation
from localizer.filter.measurement import Measurement, measurement_jacobian, predict_measurement
from localizer.mount import CameraMount
from localizer.filter.motion import compose, compose_jacobians

__all__ = ["PoseKF", "nis", "predict_pose", "update_pose"]


class PoseKF:
    """filterpy 2.0's ``ExtendedKalmanFilter(dim_x=3, dim_z=3)`` over a pose (x, y, θ), its
    prediction the composition x ⊕ u (module docstring).

    Attributes as filterpy's: ``x`` (3, 1) and ``P`` (3, 3) the estimate; ``F``, ``Q`` of the
    last predict; ``R`` the default measurement noise; ``y``, ``S``, ``SI``, ``K``, ``z`` of the
    last update; ``x_prior``, ``P_prior``, ``x_post``, ``P_post`` copies after each step.

    Args:
        x: (3,) initial pose (m, m, rad).
        P: (3, 3) its covariance.
    """

    def __init__(self, x=None, P=None) -> None:
        self.dim_x, self.dim_z, self.dim_u = 3, 3, 0
        self.x = np.zeros((3, 1))
        self.P = np.eye(3)
        self.B = 0
        self.F = np.eye(3)
        self.R = np.eye(3)
        self.Q = np.eye(3)
        self.z = np.array([None] * 3).reshape(3, 1)
        self.K = np.zeros((3, 1))
        self.y = np.zeros((3, 1))
        self.S = np.zeros((3, 3))
        self.SI = np.zeros((3, 3))
        self._I = np.eye(3)
        self._log_likelihood = math.log(sys.float_info.min)
        self._likelihood = sys.float_info.min
        self._mahalanobis = None
        self.x_prior = self.x.copy()
        self.P_prior = self.P.copy()
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()
        if x is not None:
            self.x = np.asarray(x, dtype=float).reshape(3, 1).copy()
        if P is not None:
            self.P = np.asarray(P, dtype=float).copy()

    def predict_x(self, u=0):
        self.x = compose(self.x, u).reshape(3, 1)

    def predict(self, u=0) -> None:
        """filterpy's ``predict``: ``x ← x ⊕ u``, ``P ← F P Fᵀ + Q``."""
        self.predict_x(u)
        self.P = np.dot(self.F, self.P).dot(self.F.T) + self.Q
        self.x_prior = np.copy(self.x)
        self.P_prior = np.copy(self.P)

    def update(self, z, HJacobian, Hx, R=None, args=(), hx_args=(), residual=np.subtract) -> None:
        """filterpy's ``update``: the EKF update with the Jacobian ``HJacobian(x, *args)`` and the
        measurement function ``Hx(x, *hx_args)``, Joseph form; ``z=None`` only saves the posterior."""
        if z is None:
            self.z = np.array([[None] * self.dim_z]).T
            self.x_post = self.x.copy()
            self.P_post = self.P.copy()
            return
        if not isinstance(args, tuple):
            args = (args,)
        if not isinstance(hx_args, tuple):
            hx_args = (hx_args,)
        if R is None:
            R = self.R
        elif np.isscalar(R):
            R = np.eye(self.dim_z) * R
        H = HJacobian(self.x, *args)
        PHT = np.dot(self.P, H.T)
        self.S = np.dot(H, PHT) + R
        self.SI = linalg.inv(self.S)
        self.K = PHT.dot(self.SI)
        hx = Hx(self.x, *hx_args)
        self.y = residual(z, hx)
        self.x = self.x + np.dot(self.K, self.y)
        I_KH = self._I - np.dot(self.K, H)
        self.P = np.dot(I_KH, self.P).dot(I_KH.T) + np.dot(self.K, R).dot(self.K.T)
        self._log_likelihood = None
        self._likelihood = None
        self._mahalanobis = None
        self.z = deepcopy(z)
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()

    @property
    def log_likelihood(self) -> float:
        """Log-likelihood of the last measurement (filterpy's ``logpdf``, imported here)."""
        if self._log_likelihood is None:
            from filterpy.stats import logpdf

            self._log_likelihood = logpdf(x=self.y, cov=self.S)
        return self._log_likelihood

    @property
    def likelihood(self) -> float:
        """``exp(log_likelihood)``, at least ``sys.float_info.min``."""
        if self._likelihood is None:
            self._likelihood = math.exp(self.log_likelihood)
            if self._likelihood == 0:
                self._likelihood = sys.float_info.min
        return self._likelihood

    @property
    def mahalanobis(self) -> float:
        """Mahalanobis distance of the last innovation, ``sqrt(yᵀ S⁻¹ y)``."""
        if self._mahalanobis is None:
            self._mahalanobis = math.sqrt(np.dot(np.dot(self.y.T, self.SI), self.y).item())
        return self._mahalanobis

    def __repr__(self) -> str:
        return f"PoseKF(x={self.x.ravel().tolist()!r}, P={self.P.tolist()!r})"


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


def nis(kf: PoseKF) -> float:
    """``yᵀ S⁻¹ y`` of ``kf``'s last update, from filterpy's innovation ``kf.y`` and its covariance ``kf.S``.

    χ²(3) when the filter is consistent. filterpy forms ``S = H (P Hᵀ) + R``; the filter used to
    recompute ``(H P) Hᵀ + R`` beside it, which differs in the last bits for about one update
    in twelve (a few ulp of the NIS; the drift figures are unchanged). Solved against ``S``
    rather than multiplied by filterpy's ``SI``, which would change more of them.
    """
    y = kf.y.reshape(-1)
    return float(y @ np.linalg.solve(kf.S, y))
