"""Unscented Transform of stereo correspondences to 3D (thesis Eqs. 3.6-3.18), with references.

A correspondence s = (x_l, y_l, x_r, y_r) is Gaussian (Eqs. 3.6-3.7) with
Sigma_s = diag(sigma_l^2, sigma_l^2, sigma_r^2, sigma_r^2), the RF supports. Its 3D point is
z = tau(s), the mid-point triangulation of Eq. 3.8 (`geometry.triangulate_midpoint`).

UT (defaults from the authors' foveated_stereo_ros: L = 4, alpha = 0.25, beta = 2, kappa = 3):
lambda = alpha^2 (L + kappa) - L; 2L + 1 sigma points X_0 = mu (Eq. 3.10),
X_j = mu +- (sqrt((L + lambda) Sigma))_j (Eqs. 3.11-3.12); weights (Eqs. 3.14-3.16)
w_m0 = lambda / (L + lambda), w_c0 = w_m0 + 1 - alpha^2 + beta, w_j = 1 / (2 (L + lambda));
mean and covariance of tau(X_j) by Eqs. 3.17-3.18.

Since Sigma_s is diagonal, its square root is diag(sqrt(L + lambda) sigma) and the 4D sigma
points split into a left and a right part that depend on one RF each. `SigmaPointTable`
precomputes those offsets per RF, stored as (N_rf, 2L + 1, 2) arrays (the thesis: "computed
offline and stored in a linear array"); a frame only gathers rows for its RF pairs. The mean of
each pair is the measured (sub-pixel) correspondence; with RF centres as measurements it is
exactly Eq. 3.10.

References for validation: `linearized_triangulate` (first-order: mean tau(mu), covariance
J Sigma J^T, J by central differences) and `monte_carlo_triangulate` (sampling).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import check_intrinsics, check_pose, triangulate_midpoint, triangulate_uv
from .sensors import RFSensor

L_DIM = 4   # a correspondence has 4 coordinates
# correspondences per block of `SigmaPointTable.transform` (a multiple of 64, so that BLAS's
# matrix-vector kernels treat every row as in one call: the result is the same bits)
UT_CHUNK = 2048


@dataclass(frozen=True)
class UTParams:
    """UT scaling (Eqs. 3.14-3.16); defaults of foveated_stereo_ros."""

    alpha: float = 0.25
    beta: float = 2.0
    kappa: float = 3.0
    L: int = L_DIM

    def __post_init__(self) -> None:
        if self.L != L_DIM:
            raise ValueError(f'L must be {L_DIM} (x_l, y_l, x_r, y_r), got {self.L}')
        if not self.alpha > 0 or self.L + self.lam <= 0:
            raise ValueError(f'UT needs alpha > 0 and L + lambda > 0 (alpha={self.alpha}, '
                             f'kappa={self.kappa})')

    @property
    def lam(self) -> float:
        """lambda = alpha^2 (L + kappa) - L."""
        return self.alpha ** 2 * (self.L + self.kappa) - self.L

    def weights(self) -> tuple[np.ndarray, np.ndarray]:
        """(w_m, w_c), each (2L + 1,): Eqs. 3.14-3.16."""
        n = 2 * self.L + 1
        wm = np.full(n, 1.0 / (2.0 * (self.L + self.lam)))
        wc = wm.copy()
        wm[0] = self.lam / (self.L + self.lam)
        wc[0] = wm[0] + 1.0 - self.alpha ** 2 + self.beta
        return wm, wc


@dataclass(frozen=True)
class StereoRig:
    """Intrinsics and 4x4 optical-frame poses (in the reference frame) of the two cameras."""

    k_left: np.ndarray
    k_right: np.ndarray
    pose_left: np.ndarray
    pose_right: np.ndarray

    @classmethod
    def create(cls, k_left: np.ndarray, k_right: np.ndarray, pose_left: np.ndarray,
               pose_right: np.ndarray) -> StereoRig:
        """Validated rig; ValueError names the bad argument."""
        rig = cls(check_intrinsics('k_left', k_left), check_intrinsics('k_right', k_right),
                  check_pose('pose_left', pose_left), check_pose('pose_right', pose_right))
        if np.linalg.norm(rig.pose_left[:3, 3] - rig.pose_right[:3, 3]) < 1e-9:
            raise ValueError('camera centres coincide: zero baseline')
        return rig

    def triangulate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """tau (Eq. 3.8) of correspondences s (..., 4) -> (points (..., 3), valid (...))."""
        return triangulate_midpoint(s[..., :2], s[..., 2:], self.k_left, self.k_right,
                                    self.pose_left, self.pose_right)


class SigmaPointTable:
    """Per-RF sigma-point offsets of a left and a right sensor (Eqs. 3.9-3.12), precomputed.

    Sigma point j of a correspondence is its mean plus an offset along one coordinate: +h_l of
    its left RF on x_l (j = 1) or y_l (j = 2), -h_l for j = L+1, L+2, and +-h_r of its right RF on
    x_r, y_r (j = 3, 4, L+3, L+4), h = sqrt(L + lambda) sigma (the diagonal square root of
    Eq. 3.11-3.12). The table stores h per RF (`scaled_left`, `scaled_right`, (N_rf,)): the
    (N_rf, 2L+1, 2) offset arrays (`offsets_left`, `offsets_right`, built on demand) are zero but
    for those entries, and keeping them cost 23 MB for 40,000 RFs (issue 27).
    """

    def __init__(self, left: RFSensor, right: RFSensor, params: UTParams = UTParams()) -> None:
        self.params = params
        self.wm, self.wc = params.weights()
        self.scale = float(np.sqrt(params.L + params.lam))
        self.sigma_left = left.sigmas
        self.sigma_right = right.sigmas
        self.scaled_left = self.scale * left.sigmas
        # one sensor on both sides (StereoPipeline): one array
        self.scaled_right = (self.scaled_left if right.sigmas is left.sigmas
                             else self.scale * right.sigmas)

    @property
    def offsets_left(self) -> np.ndarray:
        """(N_rf, 2L+1, 2) offsets of the left RFs' sigma points (non-zero for j = 1, 2, L+1,
        L+2)."""
        return self._offsets(self.scaled_left, (1, 2))

    @property
    def offsets_right(self) -> np.ndarray:
        """(N_rf, 2L+1, 2) offsets of the right RFs' sigma points (j = 3, 4, L+3, L+4)."""
        return self._offsets(self.scaled_right, (3, 4))

    def _offsets(self, scaled: np.ndarray, axes: tuple[int, int]) -> np.ndarray:
        n, L = scaled.shape[0], self.params.L
        off = np.zeros((n, 2 * L + 1, 2))
        for c, j in enumerate(axes):
            off[:, j, c] = scaled
            off[:, j + L, c] = -scaled
        return off

    def sigma_points(self, uv_left: np.ndarray, uv_right: np.ndarray, idx_left: np.ndarray,
                     idx_right: np.ndarray) -> np.ndarray:
        """(N, 2L + 1, 4) sigma points of N correspondences in RF pairs (idx_left, idx_right)."""
        coords = self._coordinates(uv_left, uv_right, idx_left, idx_right)
        return np.stack(coords, axis=-1)

    def _coordinates(self, uv_left: np.ndarray, uv_right: np.ndarray, idx_left: np.ndarray,
                     idx_right: np.ndarray) -> list[np.ndarray]:
        """x_l, y_l, x_r, y_r of the sigma points, each (N, 2L+1): the mean in every column,
        +-h on the columns that move that coordinate (the same sums as mean + offset)."""
        L = self.params.L
        hl = np.take(self.scaled_left, idx_left)
        hr = np.take(self.scaled_right, idx_right)
        coords = []
        for uv, h, first in ((uv_left, hl, 1), (uv_right, hr, 3)):
            for c in range(2):
                col = np.repeat(np.asarray(uv[:, c], np.float64)[:, None], 2 * L + 1, axis=1)
                col[:, first + c] += h
                col[:, first + c + L] -= h
                coords.append(col)
        return coords

    def transform(self, rig: StereoRig, uv_left: np.ndarray, uv_right: np.ndarray,
                  idx_left: np.ndarray, idx_right: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """UT (Eqs. 3.10-3.18) of N correspondences, gathering the stored sigma points by row.

        Same result as `unscented_transform(rig, self.sigma_points(...), wm, wc)`, without
        building the (N, 2L+1, 4) array: each coordinate is an (N, 2L+1) array, UT_CHUNK rows
        at a time (rows are independent): the ~40 temporaries of a chunk stay in the CPU's cache
        and a frame's transient memory is ~5 MB instead of ~70 MB for 26,000 points (issue 27).
        """
        n = uv_left.shape[0]
        mean = np.empty((n, 3))
        cov = np.empty((n, 3, 3))
        valid = np.empty(n, bool)
        for s in range(0, max(n, 1), UT_CHUNK):
            e = min(n, s + UT_CHUNK)
            ul, vl, ur, vr = self._coordinates(uv_left[s:e], uv_right[s:e], idx_left[s:e],
                                               idx_right[s:e])
            *comp, ok = triangulate_uv(ul, vl, ur, vr, rig.k_left, rig.k_right, rig.pose_left,
                                       rig.pose_right)
            mean[s:e], cov[s:e], valid[s:e] = _ut_moments(comp, ok, self.wm, self.wc)
        return mean, cov, valid

    def std(self, idx_left: np.ndarray, idx_right: np.ndarray) -> np.ndarray:
        """(N, 4) standard deviations diag(Sigma_s)^(1/2) of the RF pairs (Eq. 3.7)."""
        sl, sr = self.sigma_left[idx_left], self.sigma_right[idx_right]
        return np.stack([sl, sl, sr, sr], axis=-1)


def unscented_transform(rig: StereoRig, sigma_points: np.ndarray, wm: np.ndarray,
                        wc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eqs. 3.17-3.18 over N correspondences: (mean (N, 3), cov (N, 3, 3), valid (N,)).

    A correspondence is valid only if all its sigma points triangulate (in front of both
    cameras, rays not parallel); invalid rows are NaN.
    """
    sp = sigma_points
    *comp, ok = triangulate_uv(sp[..., 0], sp[..., 1], sp[..., 2], sp[..., 3], rig.k_left,
                               rig.k_right, rig.pose_left, rig.pose_right)   # 3 x (N, 2L+1)
    return _ut_moments(comp, ok, wm, wc)


def _ut_moments(comp: list[np.ndarray], ok: np.ndarray, wm: np.ndarray, wc: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eqs. 3.17-3.18 from the triangulated sigma points' components, each (N, 2L+1)."""
    valid = np.all(ok, axis=1)
    with np.errstate(invalid='ignore', over='ignore'):   # invalid rows are NaN'd below
        mean = np.stack([c @ wm for c in comp], axis=-1)             # Eq. 3.17
        dev = [c - m[:, None] for c, m in zip(comp, mean.T, strict=True)]
        cov = np.empty((ok.shape[0], 3, 3))
        for a in range(3):                                           # Eq. 3.18
            for b in range(a, 3):
                cov[:, a, b] = cov[:, b, a] = (dev[a] * dev[b]) @ wc
    mean[~valid] = np.nan
    cov[~valid] = np.nan
    return mean, cov, valid


def linearized_triangulate(rig: StereoRig, mu: np.ndarray, std: np.ndarray,
                           step: float = 1e-3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First-order propagation: mean tau(mu), cov J diag(std^2) J^T (central differences)."""
    mu = np.asarray(mu, np.float64)
    eye = np.eye(4) * step
    pts = np.concatenate([mu[:, None, :], mu[:, None, :] + eye, mu[:, None, :] - eye], axis=1)
    z, ok = rig.triangulate(pts)                              # (N, 9, 3)
    jac = (z[:, 1:5] - z[:, 5:9]) / (2.0 * step)              # (N, 4, 3): d z / d s_k
    js = jac * std[:, :, None]
    cov = np.einsum('nka,nkb->nab', js, js)
    return z[:, 0], cov, np.all(ok, axis=1)


def monte_carlo_triangulate(rig: StereoRig, mu: np.ndarray, std: np.ndarray, samples: int,
                            rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, float]:
    """Sample mean and covariance of tau(s), s ~ N(mu, diag(std^2)), for ONE correspondence.

    Returns (mean (3,), cov (3, 3), fraction of samples that triangulated).
    """
    s = mu + std * rng.standard_normal((samples, 4))
    z, ok = rig.triangulate(s)
    z = z[ok]
    return z.mean(axis=0), np.cov(z.T), float(ok.mean())
