"""Constant-velocity Kalman filters, one per target, vectorized over targets (section 5.3.1).

State ``x = [u, v, s, du, dv, ds]``: detector-window centre (pixels), scale relative to the
smallest window (Eq. 5.1) and their velocities per frame. Beliefs are Gaussian
``b = N(x_hat, P)`` (Eq. 5.4); the thesis's Sigma (Eq. 5.6) is the [u, v, s] block of P.
Prediction is Eq. 5.3 and the update Eq. 5.2 for linear-Gaussian models.

Every function takes stacks: ``x`` is (K, 6), ``P`` is (K, 6, 6), observations ``z`` (K, 3)
with covariances ``R`` (K, 3, 3). No per-target Python loops.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

STATE_DIM = 6
MEAS_DIM = 3
#: Observation matrix: the detector measures [u, v, s].
H = np.hstack([np.eye(MEAS_DIM), np.zeros((MEAS_DIM, MEAS_DIM))])


@dataclass(frozen=True)
class MotionModel:
    """Constant velocity with white-noise acceleration (discrete, per frame).

    accel_std: std of the centre acceleration at scale 1, pixels/frame^2; at scale s it is
        ``s * accel_std`` (a person twice as close moves twice as many pixels). The default
        suits walking people at 25-30 frames/s.
    scale_accel_std: std of the scale acceleration per frame^2, relative (times s).
    dt: frames per step.
    """

    accel_std: float = 0.3
    scale_accel_std: float = 0.01
    dt: float = 1.0

    def __post_init__(self) -> None:
        if self.accel_std < 0 or self.scale_accel_std < 0 or not self.dt > 0:
            raise ValueError(f'MotionModel: stds must be >= 0 and dt > 0, got {self}')

    @property
    def F(self) -> FloatArray:
        """Transition matrix (6, 6): ``p' = p + dt v``, ``v' = v``."""
        f = np.eye(STATE_DIM)
        f[:MEAS_DIM, MEAS_DIM:] = self.dt * np.eye(MEAS_DIM)
        return f

    def Q(self, s: NDArray[np.float64]) -> FloatArray:
        """Process noise (K, 6, 6) for targets at scales s (K,): ``sigma^2 G G^T`` per axis,
        ``G = [dt^2 / 2, dt]``."""
        s = np.maximum(np.asarray(s, dtype=float), 1e-6)
        dt = self.dt
        sig = np.stack([self.accel_std * s, self.accel_std * s, self.scale_accel_std * s], -1)
        var = sig ** 2                                   # (K, 3)
        q = np.zeros(s.shape + (STATE_DIM, STATE_DIM))
        i = np.arange(MEAS_DIM)
        q[..., i, i] = var * dt ** 4 / 4.0
        q[..., i, i + 3] = var * dt ** 3 / 2.0
        q[..., i + 3, i] = var * dt ** 3 / 2.0
        q[..., i + 3, i + 3] = var * dt ** 2
        return q


def predict(x: FloatArray, P: FloatArray, motion: MotionModel) -> tuple[FloatArray, FloatArray]:
    """Prediction step (Eq. 5.3): ``x' = F x``, ``P' = F P F^T + Q(s)``; stacks of any
    leading shape."""
    f = motion.F
    x_new = x @ f.T
    p_new = f @ P @ f.T + motion.Q(x[..., 2])
    return x_new, 0.5 * (p_new + np.swapaxes(p_new, -1, -2))


def innovation_covariance(P: FloatArray, R: FloatArray) -> FloatArray:
    """S = H P H^T + R for stacks (..., 6, 6) and (..., 3, 3)."""
    return P[..., :MEAS_DIM, :MEAS_DIM] + R


def update_covariance(P: FloatArray, R: FloatArray) -> FloatArray:
    """Posterior covariance (I - K H) P, which does not depend on the observed value (so the
    planner can predict it, Eq. 5.21)."""
    S = innovation_covariance(P, R)
    PHt = P[..., :, :MEAS_DIM]                            # P H^T
    gain = np.swapaxes(np.linalg.solve(S, np.swapaxes(PHt, -1, -2)), -1, -2)   # P H^T S^-1
    p_new = P - gain @ np.swapaxes(PHt, -1, -2)
    return 0.5 * (p_new + np.swapaxes(p_new, -1, -2))


def update(x: FloatArray, P: FloatArray, z: FloatArray,
           R: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Measurement update (Eq. 5.2 for Gaussians) of stacks x (K, 6), P (K, 6, 6) with
    observations z (K, 3) of covariance R (K, 3, 3)."""
    S = innovation_covariance(P, R)
    PHt = P[..., :, :MEAS_DIM]
    gain = np.swapaxes(np.linalg.solve(S, np.swapaxes(PHt, -1, -2)), -1, -2)   # (K, 6, 3)
    resid = z - x[..., :MEAS_DIM]
    x_new = x + np.einsum('...ij,...j->...i', gain, resid)
    p_new = P - gain @ np.swapaxes(PHt, -1, -2)
    return x_new, 0.5 * (p_new + np.swapaxes(p_new, -1, -2))


def mahalanobis_sq(x: FloatArray, P: FloatArray, z: FloatArray, R: FloatArray) -> FloatArray:
    """Squared Mahalanobis distance (K, M) between K predicted targets and M observations.

    ``d2[k, m] = r^T S^-1 r`` with ``r = z_m - H x_k`` and ``S = H P_k H^T + R_m``.
    """
    K, M = x.shape[0], z.shape[0]
    if K == 0 or M == 0:
        return np.zeros((K, M))
    S = P[:, None, :MEAS_DIM, :MEAS_DIM] + R[None, :, :, :]            # (K, M, 3, 3)
    r = z[None, :, :] - x[:, None, :MEAS_DIM]                          # (K, M, 3)
    sol = np.linalg.solve(S, r[..., None])[..., 0]
    return np.einsum('kmi,kmi->km', r, sol)


def logdet_sigma(P: FloatArray) -> FloatArray:
    """log |Sigma| of the [u, v, s] block (Eq. 5.6); the reward of Eq. 5.24 is its negative."""
    sign, ld = np.linalg.slogdet(P[..., :MEAS_DIM, :MEAS_DIM])
    return np.where(sign > 0, ld, -np.inf)
