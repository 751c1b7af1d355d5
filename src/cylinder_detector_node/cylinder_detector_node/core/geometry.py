"""Per-point surface normals and principal curvature (thesis section 4.3.3, Fig. 4.3).

Both are batched: one k-d tree query, then one batched 3x3 eigendecomposition per quantity.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

Array = NDArray[np.float64]


def normals_and_curvature(points: Array, k: int = 15) -> tuple[Array, Array, Array]:
    """PCA normals over the k nearest neighbours, then principal curvature direction and value.

    Normal n^s: eigenvector of the smallest eigenvalue of the neighbourhood covariance. Curvature
    (section 4.3.3): the neighbours' normals (flipped to agree with n^s) are projected on the tangent
    plane (I - n n^T); the eigenvector of the largest eigenvalue of their covariance is c_max^s and
    that eigenvalue is k_max^s (flat surfaces give k_max close to 0).

    Returns (normals (N,3), c_max (N,3), k_max (N,)). Fewer than 3 points gives empty arrays.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n_pts = len(pts)
    if n_pts < 3:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    kk = int(min(max(k, 3), n_pts))
    _, idx = cKDTree(pts).query(pts, k=kk)
    nb = pts[idx]                                            # (N, k, 3)
    centred = nb - nb.mean(axis=1, keepdims=True)
    cov = np.einsum('nki,nkj->nij', centred, centred) / kk
    _, vec = np.linalg.eigh(cov)                             # ascending eigenvalues
    normals = vec[:, :, 0]
    nn = normals[idx]                                        # neighbours' normals (N, k, 3)
    sign = np.sign(np.einsum('nkj,nj->nk', nn, normals))
    sign[sign == 0] = 1.0
    nn = nn * sign[..., None]
    proj = nn - np.einsum('nkj,nj->nk', nn, normals)[..., None] * normals[:, None, :]
    proj = proj - proj.mean(axis=1, keepdims=True)
    ccov = np.einsum('nki,nkj->nij', proj, proj) / kk
    cval, cvec = np.linalg.eigh(ccov)
    return normals, cvec[:, :, 2], np.clip(cval[:, 2], 0.0, None)
