"""Convergent stereo geometry and mid-point triangulation (thesis section 3.3.2, Eq. 3.8).

Cameras are pinholes with intrinsics K (3x3) and poses given as 4x4 homogeneous transforms
`T_ref_cam` mapping points of the camera's optical frame (z forward, x right, y down, REP 103)
into a common reference frame (the cyclopean frame C of the thesis, or any frame tf provides).
`vergence_poses` builds those poses from vergence, pan and tilt for tests and benchmarks; the node
will take them from tf instead.

Mid-point method (Eq. 3.8, ref. [213] of the thesis): the back-projected rays
c_l + s d_l and c_r + t d_r generally do not meet; the estimate is the midpoint of their common
perpendicular. With w = c_l - c_r, a = d_l.d_l, b = d_l.d_r, c = d_r.d_r, d = d_l.w, e = d_r.w:

    s = (b e - c d) / (a c - b^2),   t = (a e - b d) / (a c - b^2),
    z = ((c_l + s d_l) + (c_r + t d_r)) / 2.

A pair is invalid when the rays are (nearly) parallel (a c - b^2 ~ 0) or when the point lies
behind either camera (s <= 0 or t <= 0); invalid entries come back as NaN with a False mask.
Everything is vectorized over any leading batch shape (points x sigma points).

`fundamental_matrix` / `epipolar_distance`: how far a right-image match lies from the epipolar
line of its left point; SGBM matches along rows, which a verged pair's epipolar lines follow
only near the meridians, so the stereo pipeline drops matches farther than an RF spacing.
"""

from __future__ import annotations

import numpy as np

#: rays whose sin^2(angle) is below this are treated as parallel (about 0.006 deg)
PARALLEL_SIN2 = 1e-11


def check_pose(name: str, pose: np.ndarray) -> np.ndarray:
    """A 4x4 rigid transform as float64, or ValueError naming the problem."""
    p = np.asarray(pose, dtype=np.float64)
    if p.shape != (4, 4) or not np.all(np.isfinite(p)):
        raise ValueError(f'{name}: expected a finite 4x4 pose, got shape {p.shape}')
    r = p[:3, :3]
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-6) or not np.allclose(p[3], [0, 0, 0, 1]):
        raise ValueError(f'{name}: not a rigid transform (rotation not orthonormal)')
    return p


def check_intrinsics(name: str, k: np.ndarray) -> np.ndarray:
    """A 3x3 pinhole matrix with positive focal lengths, or ValueError."""
    k = np.asarray(k, dtype=np.float64)
    if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0:
        raise ValueError(f'{name}: expected a 3x3 intrinsic matrix with fx, fy > 0')
    return k


def rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def vergence_poses(baseline: float, vergence: float, version: float = 0.0,
                   tilt: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Optical-frame poses (T_cyc_left, T_cyc_right) in the cyclopean frame.

    The cyclopean frame is optical-style (z forward, x right, y down) at the baseline midpoint.
    Each eye sits at x = -/+ baseline/2 and turns about its y axis (section 3.3.2: theta^l =
    theta^v/2, theta^r = -theta^v/2, here inward for positive vergence) plus the common
    version (pan); the pair is then tilted about the x axis.
    """
    if not baseline > 0:
        raise ValueError(f'baseline must be > 0, got {baseline}')
    tilt_r = rot_x(-tilt)
    poses = []
    for _side, sign in (('left', 1.0), ('right', -1.0)):
        t = np.eye(4)
        t[:3, :3] = tilt_r @ rot_y(version + sign * vergence / 2.0)
        t[:3, 3] = tilt_r @ np.array([-sign * baseline / 2.0, 0.0, 0.0])
        poses.append(t)
    return poses[0], poses[1]


def _rays_xyz(u: np.ndarray, v: np.ndarray, k: np.ndarray, pose: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ray direction components (each (...)) in the reference frame for pixels (u, v)."""
    x = (u - k[0, 2]) * (1.0 / k[0, 0])
    y = (v - k[1, 2]) * (1.0 / k[1, 1])
    r = pose[:3, :3]
    return tuple(r[i, 0] * x + r[i, 1] * y + r[i, 2] for i in range(3))


def pixel_rays(uv: np.ndarray, k: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Ray directions (..., 3) in the reference frame for pixels uv (..., 2)."""
    uv = np.asarray(uv, np.float64)
    return np.stack(_rays_xyz(uv[..., 0], uv[..., 1], k, pose), axis=-1)


def project(points: np.ndarray, k: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Pixel coordinates (..., 2) of reference-frame points (..., 3) seen by a camera at pose."""
    inv = np.linalg.inv(pose)
    pc = points @ inv[:3, :3].T + inv[:3, 3]
    return np.stack([k[0, 0] * pc[..., 0] / pc[..., 2] + k[0, 2],
                     k[1, 1] * pc[..., 1] / pc[..., 2] + k[1, 2]], axis=-1)


def triangulate_components(uv_left: np.ndarray, uv_right: np.ndarray, k_left: np.ndarray,
                           k_right: np.ndarray, pose_left: np.ndarray, pose_right: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Eq. 3.8 as component arrays (x, y, z, valid), each (...); invalid entries unspecified."""
    ul, ur = np.asarray(uv_left, np.float64), np.asarray(uv_right, np.float64)
    if ul.shape != ur.shape or ul.shape[-1:] != (2,):
        raise ValueError(f'correspondences must be matching (..., 2) arrays, got '
                         f'{ul.shape} and {ur.shape}')
    return triangulate_uv(ul[..., 0], ul[..., 1], ur[..., 0], ur[..., 1], k_left, k_right,
                          pose_left, pose_right)


def triangulate_uv(ul: np.ndarray, vl: np.ndarray, ur: np.ndarray, vr: np.ndarray,
                   k_left: np.ndarray, k_right: np.ndarray, pose_left: np.ndarray,
                   pose_right: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Eq. 3.8 on pixel coordinate arrays of equal shape: (x, y, z, valid)."""
    # component arrays (structure of arrays) keep every operation contiguous
    lx, ly, lz = _rays_xyz(ul, vl, k_left, pose_left)
    rx, ry, rz = _rays_xyz(ur, vr, k_right, pose_right)
    cl, cr = pose_left[:3, 3], pose_right[:3, 3]
    w = cl - cr
    a = lx * lx + ly * ly + lz * lz
    b = lx * rx + ly * ry + lz * rz
    c = rx * rx + ry * ry + rz * rz
    d = lx * w[0] + ly * w[1] + lz * w[2]
    e = rx * w[0] + ry * w[1] + rz * w[2]
    den = a * c - b * b
    with np.errstate(divide='ignore', invalid='ignore'):
        inv = 1.0 / den
        s = (b * e - c * d) * inv
        t = (a * e - b * d) * inv
        xyz = [0.5 * (cl[i] + cr[i]) + 0.5 * (s * l_i + t * r_i)
               for i, l_i, r_i in ((0, lx, rx), (1, ly, ry), (2, lz, rz))]
    valid = (den > PARALLEL_SIN2 * a * c) & (s > 0) & (t > 0)
    valid &= np.isfinite(xyz[0]) & np.isfinite(xyz[1]) & np.isfinite(xyz[2])
    return xyz[0], xyz[1], xyz[2], valid


def triangulate_midpoint(uv_left: np.ndarray, uv_right: np.ndarray, k_left: np.ndarray,
                         k_right: np.ndarray, pose_left: np.ndarray,
                         pose_right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mid-point triangulation tau (Eq. 3.8) of correspondences, vectorized.

    uv_left, uv_right: (..., 2) pixel coordinates, same shape. Returns (points (..., 3) in the
    poses' reference frame, valid (...) bool); invalid entries (parallel rays, behind a camera,
    non-finite input) are NaN.
    """
    x, y, z, valid = triangulate_components(uv_left, uv_right, k_left, k_right, pose_left,
                                            pose_right)
    pts = np.stack([x, y, z], axis=-1)
    pts[~valid] = np.nan
    return pts, valid


def fundamental_matrix(k_left: np.ndarray, k_right: np.ndarray, pose_left: np.ndarray,
                       pose_right: np.ndarray) -> np.ndarray:
    """F with x_r^T F x_l = 0 for homogeneous pixels of one point seen by both cameras."""
    rel = np.linalg.inv(pose_right) @ pose_left          # right <- left
    r, t = rel[:3, :3], rel[:3, 3]
    tx = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    return np.linalg.inv(k_right).T @ tx @ r @ np.linalg.inv(k_left)


def epipolar_distance(uv_left: np.ndarray, uv_right: np.ndarray, k_left: np.ndarray,
                      k_right: np.ndarray, pose_left: np.ndarray,
                      pose_right: np.ndarray) -> np.ndarray:
    """Distance (px, (N,)) of each right point from the epipolar line of its left point: 0 for a
    correspondence the rig can produce; a horizontal match on a verged pair drifts off the line
    away from the horizontal and vertical meridians (vertical disparity)."""
    f = fundamental_matrix(k_left, k_right, pose_left, pose_right)
    xl = np.column_stack([uv_left, np.ones(len(uv_left))])
    xr = np.column_stack([uv_right, np.ones(len(uv_right))])
    lines = xl @ f.T
    return np.abs(np.sum(lines * xr, axis=1)) / np.maximum(np.hypot(lines[:, 0], lines[:, 1]),
                                                           1e-12)
