"""Ego-motion compensation: move the beliefs with the camera's rotation between two frames.

When the head or the eyes turn between frames, every target jumps in the image by the same
rotation-induced flow; a constant-velocity prediction (Eq. 5.3) does not expect it, so the
search regions (Eqs. 5.16-5.19) miss the targets and the association gate rejects them. The
thesis's camera was static; Vizzy's is not.

For a camera that rotates about its optical centre by ``R`` (``d_cur = R d_prev`` for a
direction in optical-frame coordinates) a pixel moves by the homography
``H = K R K^-1`` (Hartley & Zisserman, "infinite homography"), whatever its depth. Vizzy's
optical centres sit 2.75 cm in front of the eye axes and ~0.13 m from the neck tilt axis, so
the rotation also translates the camera by up to a few cm: for people a few metres away that
parallax is a pixel or two (f ~ 347 px), well inside the detector's quantization noise.

Each track's belief ``N(x, P)``, ``x = [u v s du dv ds]`` (section 5.3.1), is mapped through
``H``: the centre exactly (``h(u, v)``), the scale by the vertical magnification
``m = |J e_v|`` of the homography's Jacobian ``J = dh/d(u, v)`` (the scale is the window's
height; a rotation stretches what it brings towards the image's edges: a pure pan that takes
a person from alpha to alpha' off the optical axis multiplies their height by
cos(alpha) / cos(alpha')), the velocity by ``J`` (the same
world motion seen by the rotated camera), and the covariance by the linearization
``P' = A P A^T`` with ``A = diag(J, m, J, m)`` (first-order propagation, like an EKF
prediction). Vectorized over targets.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def rotation_between(r_world_prev: FloatArray, r_world_cur: FloatArray) -> FloatArray:
    """R_prev_to_cur (3, 3) of a camera from its orientations in a world-fixed frame.

    r_world_*: the optical frame's orientation (columns: its axes in world coordinates), e.g.
    the rotation block of tf's lookup_transform('base_link', 'left_camera_optical_frame').
    A direction d (optical coordinates) before the motion is ``R d`` after it.
    """
    return np.asarray(r_world_cur, float).T @ np.asarray(r_world_prev, float)


def rotation_homography(k: FloatArray, r_prev_to_cur: FloatArray) -> FloatArray:
    """H = K R K^-1 (3, 3): pixel motion of a purely rotating camera."""
    k = np.asarray(k, dtype=float).reshape(3, 3)
    h = k @ np.asarray(r_prev_to_cur, dtype=float) @ np.linalg.inv(k)
    return h / h[2, 2]


def is_identity(h: FloatArray, tol: float = 1e-9) -> bool:
    return bool(np.allclose(h / h[2, 2], np.eye(3), atol=tol))


def warp_points(h: FloatArray, uv: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Points (N, 2) through H, and the Jacobians (N, 2, 2) of the map at them."""
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    p = np.concatenate([uv, np.ones((uv.shape[0], 1))], axis=1) @ h.T     # (N, 3)
    w = p[:, 2]
    out = p[:, :2] / w[:, None]
    # d(p_i / w)/du_j = (H_ij - out_i H_2j) / w
    jac = (h[None, :2, :2] - out[:, :, None] * h[None, 2:3, :2]) / w[:, None, None]
    return out, jac


def warp_beliefs(x: FloatArray, P: FloatArray, h: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Beliefs x (K, 6), P (K, 6, 6) expressed in the previous camera -> the current one.

    Points behind the rotated camera (w <= 0, a turn of 90 degrees or more) cannot be mapped;
    their centre is sent to -1e9 so the tracker's out-of-image pruning drops them.
    """
    x = np.asarray(x, dtype=float)
    P = np.asarray(P, dtype=float)
    if x.shape[0] == 0:
        return x.copy(), P.copy()
    p = np.concatenate([x[:, :2], np.ones((x.shape[0], 1))], axis=1) @ h.T
    ahead = p[:, 2] > 1e-9
    uv, jac = warp_points(h, np.where(ahead[:, None], x[:, :2], 0.0))
    m = np.linalg.norm(jac[:, :, 1], axis=1)           # (K,) how much a vertical extent grows
    a = np.zeros((x.shape[0], 6, 6))
    a[:, 0:2, 0:2] = jac
    a[:, 2, 2] = m
    a[:, 3:5, 3:5] = jac
    a[:, 5, 5] = m
    x_new = np.einsum('kij,kj->ki', a, x)          # velocities and scale: linear in x
    x_new[:, 0:2] = uv                             # the centre: the exact homography
    p_new = a @ P @ np.swapaxes(a, -1, -2)
    x_new[~ahead, 0:2] = -1e9
    p_new[~ahead] = P[~ahead]
    return x_new, 0.5 * (p_new + np.swapaxes(p_new, -1, -2))


class OrientationHistory:
    """Recent poses of a camera in a world-fixed frame (orientation (3, 3), position (3,)), by
    time stamp.

    Fed from /tf (the simulator publishes the head's transforms at every image's stamp, and at
    100 Hz); :meth:`at` answers the orientation at an image's stamp by spherical linear
    interpolation between the two samples around it (scipy's Slerp; :meth:`pose_at`: the
    4x4 pose, position interpolated linearly). A stamp after the newest
    sample by at most ``max_extrapolation_s`` gets the newest one (the transform for this image
    may arrive just after it); older than the oldest sample, or further ahead: None.
    """

    def __init__(self, max_age_s: float = 2.0, max_extrapolation_s: float = 0.05) -> None:
        self.max_age_s = float(max_age_s)
        self.max_extrapolation_s = float(max_extrapolation_s)
        self._t: list[float] = []
        self._r: list[FloatArray] = []
        self._p: list[FloatArray] = []

    def __len__(self) -> int:
        return len(self._t)

    def clear(self) -> None:
        self._t.clear()
        self._r.clear()
        self._p.clear()

    def add(self, t: float, r: FloatArray, position: FloatArray | None = None) -> None:
        """A sample at time t [s]; out-of-order samples are inserted, duplicates replaced."""
        r = np.asarray(r, dtype=float).reshape(3, 3)
        p = np.zeros(3) if position is None else np.asarray(position, dtype=float).reshape(3)
        i = int(np.searchsorted(self._t, t))
        if i < len(self._t) and self._t[i] == t:
            self._r[i], self._p[i] = r, p
        else:
            self._t.insert(i, float(t))
            self._r.insert(i, r)
            self._p.insert(i, p)
        cut = int(np.searchsorted(self._t, self._t[-1] - self.max_age_s))
        del self._t[:cut], self._r[:cut], self._p[:cut]

    def pose_at(self, t: float) -> FloatArray | None:
        """The 4x4 pose at time t, or None when the history does not cover t."""
        from scipy.spatial.transform import Rotation, Slerp

        if not self._t or t < self._t[0]:
            return None
        pose = np.eye(4)
        if t >= self._t[-1]:
            if t - self._t[-1] > self.max_extrapolation_s:
                return None
            pose[:3, :3], pose[:3, 3] = self._r[-1], self._p[-1]
            return pose
        i = int(np.searchsorted(self._t, t, side='right'))   # t_(i-1) <= t < t_i
        times = [self._t[i - 1], self._t[i]]
        slerp = Slerp(times, Rotation.from_matrix(np.stack([self._r[i - 1], self._r[i]])))
        w = (t - times[0]) / (times[1] - times[0])
        pose[:3, :3] = slerp([t]).as_matrix()[0]
        pose[:3, 3] = (1 - w) * self._p[i - 1] + w * self._p[i]
        return pose

    def at(self, t: float) -> FloatArray | None:
        """The orientation (3, 3) at time t, or None when the history does not cover t."""
        pose = self.pose_at(t)
        return None if pose is None else pose[:3, :3]
