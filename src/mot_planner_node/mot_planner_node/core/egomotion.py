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
