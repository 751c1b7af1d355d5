"""Per-point surface normals and principal curvature (thesis section 4.3.3, Fig. 4.3).

Both are batched: one k-d tree query, then one batched 3x3 eigendecomposition per quantity
(covariances as batched matrix products, which numpy runs faster than the equivalent einsum).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

Array = NDArray[np.float64]


def pca_normals(points: Array, k: int = 15) -> tuple[Array, NDArray[np.intp]]:
    """PCA normals over the k nearest neighbours: the eigenvector of the smallest eigenvalue of the
    neighbourhood covariance. Returns (normals (N, 3), neighbour indices (N, k)); the baseline of
    Rabbani & van den Heuvel needs only these."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    kk = int(min(max(k, 3), len(pts)))
    _, idx = cKDTree(pts).query(pts, k=kk)
    nb = pts[idx]                                            # (N, k, 3)
    centred = nb - nb.mean(axis=1, keepdims=True)
    cov = np.matmul(centred.transpose(0, 2, 1), centred)     # (N, 3, 3); the 1/k scale is irrelevant
    _, vec = np.linalg.eigh(cov)                             # ascending eigenvalues
    return np.ascontiguousarray(vec[:, :, 0]), idx


def tangent_basis(normals: Array) -> tuple[Array, Array]:
    """Two unit vectors (u, v) per unit normal spanning its tangent plane, branch-free (Duff et al.
    2017, "Building an orthonormal basis, revisited"): plain arithmetic, no np.cross."""
    nx, ny, nz = normals[:, 0], normals[:, 1], normals[:, 2]
    sign = np.where(nz >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    u = np.stack([1.0 + sign * nx * nx * a, sign * b, -sign * nx], axis=1)
    v = np.stack([b, sign + ny * ny * a, -ny], axis=1)
    return u, v


def principal_curvature(normals: Array, idx: NDArray[np.intp]) -> tuple[Array, Array]:
    """Principal curvature direction c_max and value k_max per point (section 4.3.3): the
    neighbours' normals (flipped to agree with n^s) projected on the tangent plane (I - n n^T);
    the eigenvector of the largest eigenvalue of their covariance is c_max^s and that eigenvalue
    k_max^s (flat surfaces give k_max close to 0).

    The projected normals lie in the tangent plane, so their 3x3 covariance has n^s as a null
    vector: its top eigenpair is that of the 2x2 covariance in a tangent basis (u, v), in closed
    form (no batched LAPACK call).
    """
    nn = normals[idx]                                        # neighbours' normals (N, k, 3)
    u, v = tangent_basis(normals)
    sign = np.where(np.matmul(nn, normals[:, :, None])[..., 0] < 0, -1.0, 1.0)   # (N, k)
    pu = np.matmul(nn, u[:, :, None])[..., 0] * sign        # tangent coordinates of the flipped normals
    pv = np.matmul(nn, v[:, :, None])[..., 0] * sign
    pu -= pu.mean(axis=1, keepdims=True)
    pv -= pv.mean(axis=1, keepdims=True)
    a, c, b = (pu * pu).mean(axis=1), (pv * pv).mean(axis=1), (pu * pv).mean(axis=1)
    half = 0.5 * (a - c)
    k_max = 0.5 * (a + c) + np.sqrt(half * half + b * b)   # largest eigenvalue of [[a, b], [b, c]]
    theta = 0.5 * np.arctan2(b, half)                        # its eigenvector's angle from u
    c_max = np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * v
    return c_max, np.clip(k_max, 0.0, None)


def normals_and_curvature(points: Array, k: int = 15) -> tuple[Array, Array, Array]:
    """PCA normals over the k nearest neighbours, then principal curvature direction and value.

    Returns (normals (N,3), c_max (N,3), k_max (N,)). Fewer than 3 points gives empty arrays.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(pts) < 3:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    normals, idx = pca_normals(pts, k)
    c_max, k_max = principal_curvature(normals, idx)
    return normals, c_max, k_max
