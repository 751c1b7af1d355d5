"""Quaternion and frame helpers shared by every package, on SciPy's Rotation.

One convention everywhere: quaternions are (x, y, z, w), as geometry_msgs/Quaternion and tf2
order them, unit, with w >= 0 where this module makes one. MuJoCo orders them (w, x, y, z): convert
at that boundary with to_wxyz / from_wxyz and nowhere else.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

Quaternion = tuple[float, float, float, float]


def _tuple(q: np.ndarray) -> Quaternion:
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def quaternion_about(axis: str, angle: float) -> Quaternion:
    """Quaternion (x, y, z, w) of a rotation by angle [rad] about the 'x', 'y' or 'z' axis."""
    # Exact zeros off the axis (the URDF and MJCF writers print them), which from_euler keeps.
    s, c = math.sin(angle / 2.0), math.cos(angle / 2.0)
    return {'x': (s, 0.0, 0.0, c), 'y': (0.0, s, 0.0, c), 'z': (0.0, 0.0, s, c)}[axis]


def quaternion_multiply(a: Sequence[float], b: Sequence[float]) -> Quaternion:
    """The rotation a * b (b first, then a) of unit quaternions (x, y, z, w)."""
    return _tuple((Rotation.from_quat(a) * Rotation.from_quat(b)).as_quat())


def quaternion_conjugate(q: Sequence[float]) -> Quaternion:
    """The inverse rotation of a unit quaternion (x, y, z, w)."""
    return (-float(q[0]), -float(q[1]), -float(q[2]), float(q[3]))


def rotation_matrix(q: Sequence[float]) -> np.ndarray:
    """3x3 rotation matrix of a unit quaternion (x, y, z, w).

    Written out rather than through Rotation: the gaze controller's inverse kinematics builds the
    head's chain hundreds of times per solve, and one Rotation costs 4x this (2.7 vs 6.4 ms per
    solve_fixation). Batches go through quaternions_to_matrices.
    """
    x, y, z, w = (float(c) for c in q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def matrix_to_quaternion(r: np.ndarray) -> Quaternion:
    """Unit quaternion (x, y, z, w), w >= 0, of a 3x3 rotation matrix."""
    return _tuple(Rotation.from_matrix(np.asarray(r, dtype=np.float64)).as_quat(canonical=True))


def quaternions_to_matrices(quaternions: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions (x, y, z, w) -> (N, 3, 3) rotation matrices (normalized first).

    Raises ValueError for a quaternion of (near) zero norm or with non-finite values.
    """
    q = np.asarray(quaternions, dtype=np.float64).reshape(-1, 4)
    norm = np.linalg.norm(q, axis=1)
    bad = ~np.isfinite(norm) | (norm < 1e-9)
    if bad.any():
        raise ValueError(f'invalid rotation quaternion(s) {q[bad].tolist()}')
    if len(q) == 0:
        return np.empty((0, 3, 3))
    return Rotation.from_quat(q).as_matrix().reshape(-1, 3, 3)


def matrices_from_transforms(translations: np.ndarray, quaternions: np.ndarray) -> np.ndarray:
    """(N, 3) translations and (N, 4) quaternions (x, y, z, w) -> (N, 4, 4) homogeneous matrices."""
    t = np.asarray(translations, dtype=np.float64).reshape(-1, 3)
    if not np.isfinite(t).all():
        raise ValueError(f'non-finite translation(s) {t[~np.isfinite(t).all(axis=1)].tolist()}')
    m = np.zeros((len(t), 4, 4))
    m[:, :3, :3] = quaternions_to_matrices(quaternions)
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    return m


def quaternion_z_to(axis: Sequence[float] | np.ndarray) -> Quaternion:
    """(x, y, z, w) of the shortest rotation taking +z onto the direction of axis (a cylinder's
    or a plane's orientation); a half turn about +x for -z."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    if a[2] < -1.0 + 1e-9:      # antiparallel: every half turn about a horizontal axis works
        return (1.0, 0.0, 0.0, 0.0)
    q = np.array([-a[1], a[0], 0.0, 1.0 + a[2]])      # (z x a, 1 + z.a), normalized
    return _tuple(q / np.linalg.norm(q))


def axis_angle_matrix(axis: Sequence[float] | np.ndarray, angle: float) -> np.ndarray:
    """3x3 rotation by angle [rad] about axis (any length)."""
    a = np.asarray(axis, dtype=np.float64)
    return Rotation.from_rotvec(angle * a / np.linalg.norm(a)).as_matrix()


def to_wxyz(q: Sequence[float] | np.ndarray) -> np.ndarray:
    """MuJoCo's order (w, x, y, z) of a quaternion (x, y, z, w)."""
    return np.array([q[3], q[0], q[1], q[2]], dtype=np.float64)


def from_wxyz(q: Sequence[float] | np.ndarray) -> Quaternion:
    """(x, y, z, w) of a quaternion in MuJoCo's order (w, x, y, z)."""
    return (float(q[1]), float(q[2]), float(q[3]), float(q[0]))


__all__ = ['Quaternion', 'axis_angle_matrix', 'from_wxyz', 'matrices_from_transforms',
           'matrix_to_quaternion', 'quaternion_about', 'quaternion_conjugate',
           'quaternion_multiply', 'quaternion_z_to', 'quaternions_to_matrices',
           'rotation_matrix', 'to_wxyz']
