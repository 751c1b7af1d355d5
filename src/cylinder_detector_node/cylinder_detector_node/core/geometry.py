"""Per-point surface normals and principal curvature (thesis section 4.3.3, Fig. 4.3).

Both are batched: one k-d tree query and one batched 3x3 eigendecomposition (whose eigenvectors
give the normal and a tangent basis), then the curvature in closed form from the same neighbours.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

Array = NDArray[np.float64]


def neighbourhood_pca(points: Array, k: int = 15) -> tuple[Array, NDArray[np.intp]]:
    """Eigenvectors of every point's k-neighbourhood covariance, ascending eigenvalues in columns
    (N, 3, 3): column 0 is the PCA normal, columns 1-2 span the tangent plane. Also the neighbour
    indices (N, k). One cKDTree query, one batched eigh."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    kk = int(min(max(k, 3), len(pts)))
    _, idx = cKDTree(pts).query(pts, k=kk)
    # (N, k, 3); take is ~3x faster than pts[idx]
    nb = np.take(pts, idx, axis=0)
    centred = nb - nb.mean(axis=1, keepdims=True)
    # (N, 3, 3); the 1/k scale is irrelevant
    cov = np.matmul(centred.transpose(0, 2, 1), centred)
    _, vec = np.linalg.eigh(cov)
    return vec, idx


def pca_normals(points: Array, k: int = 15) -> tuple[Array, NDArray[np.intp]]:
    """PCA normals over the k nearest neighbours: the eigenvector of the smallest eigenvalue of the
    neighbourhood covariance. Returns (normals (N, 3), neighbour indices (N, k)); the baseline of
    Rabbani & van den Heuvel needs only these."""
    vec, idx = neighbourhood_pca(points, k)
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


def principal_curvature(normals: Array, idx: NDArray[np.intp],
                        basis: tuple[Array, Array] | None = None) -> tuple[Array, Array]:
    """Principal curvature direction c_max and value k_max per point (section 4.3.3): the
    neighbours' normals (flipped to agree with n^s) projected on the tangent plane (I - n n^T);
    the eigenvector of the largest eigenvalue of their covariance is c_max^s and that eigenvalue
    k_max^s (flat surfaces give k_max close to 0).

    The projected normals lie in the tangent plane, so their 3x3 covariance has n^s as a null
    vector: its top eigenpair is that of the 2x2 covariance [[a, b], [b, c]] in a tangent basis
    (u, v), in closed form. `basis` is any orthonormal tangent basis per point (the PCA's other
    two eigenvectors in normals_and_curvature; default the branch-free one of `tangent_basis`):
    k_max does not depend on it, c_max only up to sign, which the votes ignore.
    """
    u, v = tangent_basis(normals) if basis is None else basis
    return frame_curvature(np.stack([normals.T, u.T, v.T]), idx)


def frame_curvature(frames: Array, idx: NDArray[np.intp]) -> tuple[Array, Array]:
    """principal_curvature given every point's frame (n, u, v) as component rows: frames
    (3, 3, N) = (n, u, v) x (x, y, z) x points; idx (N, k) the neighbours.

    Vectorized over (point, neighbour) pairs as (k, N) planes, one per component, so that every
    elementwise step runs along the N points (numpy's batched matmul of (k x 3) by (3 x 3)
    matrices, and loops along a length-k axis, cost more than the arithmetic). The covariance
    comes from the neighbour means of the tangent coordinates and of their products (one
    matrix-vector product for all five), and its top eigenvector from the 2x2 entries without
    trigonometry.
    """
    k = idx.shape[1]
    nt, ut, vt = frames
    # (3, k, N): neighbours' normal components
    g = np.take(nt, idx.T, axis=1)
    tmp = np.empty(idx.T.shape)
    dn = g[0] * nt[0]                                        # n^s . n^j: the flips
    dn += np.multiply(g[1], nt[1], out=tmp)
    dn += np.multiply(g[2], nt[2], out=tmp)
    w = np.empty((5, *tmp.shape))                            # pu, pv, pu^2, pv^2, pu pv
    pu, pv = w[0], w[1]
    # tangent coordinates of the neighbours' normals
    np.multiply(g[0], ut[0], out=pu)
    pu += np.multiply(g[1], ut[1], out=tmp)
    pu += np.multiply(g[2], ut[2], out=tmp)
    np.multiply(g[0], vt[0], out=pv)
    pv += np.multiply(g[1], vt[1], out=tmp)
    pv += np.multiply(g[2], vt[2], out=tmp)
    np.multiply(pu, pu, out=w[2])                            # squares and product: the flip cancels
    np.multiply(pv, pv, out=w[3])
    np.multiply(pu, pv, out=w[4])
    # -1 where dn < 0 (+ 0.0 turns -0.0 into 0.0)
    flip = np.copysign(1.0, dn + 0.0)
    # flip neighbours' normals to agree with n^s
    pu *= flip
    pv *= flip
    mu, mv, suu, svv, suv = np.full(k, 1.0 / k) @ w          # neighbour means (5, N)
    # covariance [[a, b], [b, c]] of the tangent coordinates
    a, c, b = suu - mu * mu, svv - mv * mv, suv - mu * mv
    half = 0.5 * (a - c)
    r = np.sqrt(half * half + b * b)
    k_max = 0.5 * (a + c) + r                                # its largest eigenvalue
    # its unit eigenvector (cos t, sin t) in (u, v) without trigonometry: (half + r, b), or the
    # parallel (b, r - half) where half < 0 (no cancellation either way); isotropic points get u
    pos = half >= 0
    e0 = np.where(pos, half + r, b)
    e1 = np.where(pos, b, r - half)
    norm = np.sqrt(e0 * e0 + e1 * e1)
    flat = norm == 0.0
    if flat.any():
        e0[flat], norm[flat] = 1.0, 1.0
    e0 /= norm
    e1 /= norm
    c_max = (e0 * ut + e1 * vt).T
    return c_max, np.maximum(k_max, 0.0, out=k_max)


def normals_and_curvature(points: Array, k: int = 15) -> tuple[Array, Array, Array]:
    """PCA normals over the k nearest neighbours, then principal curvature direction and value,
    from the same neighbourhoods and eigendecomposition (its tangent eigenvectors as the basis).

    Returns (normals (N,3), c_max (N,3), k_max (N,)). Fewer than 3 points gives empty arrays.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(pts) < 3:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    vec, idx = neighbourhood_pca(pts, k)
    frames = np.ascontiguousarray(vec.transpose(2, 1, 0))   # (n, u, v) x (x, y, z) x points
    c_max, k_max = frame_curvature(frames, idx)
    return np.ascontiguousarray(vec[:, :, 0]), c_max, k_max
