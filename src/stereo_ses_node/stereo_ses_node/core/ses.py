"""The randomized Sensory Ego-Sphere (thesis section 3.3.3, Eqs. 3.19-3.35).

Cells: N_x unit directions p^i = v^i / ||v^i||, v^i ~ GMM (Eqs. 3.20-3.21), in the egocentric
frame E (head-centred, world-fixed orientation; here z up, as Table 3.1's "top"/"down" say).
Each cell stores a Gaussian estimate x^i ~ N(mu_i, Sigma_i) of the point seen in its direction,
initialized far away with a large covariance ("large mean and covariance", section 3.3.3).

Per frame (`SensoryEgoSphere.fuse`):
1. rigid transform of the observations to E: mu' = R mu + t, Sigma' = R Sigma R^T
   (Eqs. 3.22, 3.26-3.27);
2. association by direction (Eq. 3.23; printed as argmin of the inner product, but the nearest
   direction, as its text says, is the argmax): `SphereLookup` (exact, see below), a scipy
   cKDTree on the unit vectors (chord distance is monotone in the inner product), or the
   chunked brute force `brute_force_associate`, kept as the reference;
3. Gaussian Bayesian fusion per cell (Eqs. 3.34-3.35) in information form: Lambda_i += sum of
   Sigma'_o^-1, eta_i += sum of Sigma'_o^-1 mu'_o over the cell's observations (np.add.at-style
   bincounts), then Sigma_i = Lambda_i^-1, mu_i = Sigma_i eta_i. Fusing a frame at once equals
   applying Eqs. 3.34-3.35 observation by observation (observations are independent, Eq. 3.24).

Bad observations (non-finite, non-symmetric or non-positive-definite covariance, a mean at the
ego origin) are dropped and counted in the returned `FusionReport`; shape errors raise
ValueError before any state changes, so the sphere stays consistent.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from .linalg3 import det_inv3


@dataclass(frozen=True)
class GMM:
    """A 3D Gaussian mixture: weights (M,), means (M, 3), covariances (M, 3, 3)."""

    weights: np.ndarray
    means: np.ndarray
    covs: np.ndarray

    @classmethod
    def create(cls, weights, means, covs) -> GMM:
        """Validated mixture; diagonal covariances may be given as (M, 3) variances."""
        w = np.atleast_1d(np.asarray(weights, np.float64))
        mu = np.atleast_2d(np.asarray(means, np.float64))
        c = np.asarray(covs, np.float64)
        if c.ndim == 2 and c.shape[-1] == 3 and c.shape[0] == mu.shape[0] and c.shape != (3, 3):
            c = np.stack([np.diag(v) for v in c])
        elif c.shape == (3,):
            c = np.diag(c)[None]
        elif c.shape == (3, 3):
            c = c[None]
        m = w.shape[0]
        if mu.shape != (m, 3) or c.shape != (m, 3, 3):
            raise ValueError(f'GMM: {m} weights need means (M, 3) and covariances (M, 3, 3) or '
                             f'(M, 3); got {mu.shape} and {c.shape}')
        if np.any(w < 0) or not w.sum() > 0 or not np.all(np.isfinite(mu)):
            raise ValueError('GMM: weights must be >= 0 with a positive sum; means finite')
        if np.any(np.linalg.eigvalsh(0.5 * (c + c.transpose(0, 2, 1))) <= 0):
            raise ValueError('GMM: covariances must be symmetric positive definite')
        return cls(w / w.sum(), mu, c)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """n i.i.d. samples v ~ sum_m phi^m N(mu^m, Sigma^m) (Eq. 3.21), (n, 3)."""
        comp = rng.choice(len(self.weights), size=n, p=self.weights)
        chol = np.linalg.cholesky(self.covs)
        z = rng.standard_normal((n, 3))
        return self.means[comp] + np.einsum('nij,nj->ni', chol[comp], z)


#: Table 3.1 (mean, diagonal covariance) in the ego frame, z up
BIASES: dict[str, GMM] = {
    'unbiased': GMM.create([1.0], [[0.0, 0.0, 0.0]], [[0.5, 0.5, 0.5]]),
    'top': GMM.create([1.0], [[0.0, 0.0, 1.0]], [[0.5, 0.5, 0.5]]),
    'down': GMM.create([1.0], [[0.0, 0.0, -1.0]], [[0.5, 0.5, 0.5]]),
    'target': GMM.create([1.0], [[0.61, 0.43, -0.67]], [[0.05, 0.05, 0.05]]),
}


def sample_directions(n: int, gmm: GMM | str, rng: np.random.Generator) -> np.ndarray:
    """N_x unit cell directions p^i = v^i / ||v^i|| (Eq. 3.21); redraws the (rare) v ~ 0."""
    if isinstance(gmm, str):
        if gmm not in BIASES:
            raise ValueError(f'unknown bias {gmm!r}; known: {sorted(BIASES)} or a GMM')
        gmm = BIASES[gmm]
    if n <= 0:
        raise ValueError(f'number of cells must be positive, got {n}')
    out = np.empty((0, 3))
    while out.shape[0] < n:
        v = gmm.sample(n - out.shape[0], rng)
        norm = np.linalg.norm(v, axis=1)
        keep = norm > 1e-9
        out = np.concatenate([out, v[keep] / norm[keep, None]])
    return out


def unit_rows(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(directions, ok): rows normalized; ok False where the norm is 0 or non-finite."""
    norm = np.linalg.norm(points, axis=1)
    ok = np.isfinite(norm) & (norm > 1e-12)
    dirs = np.zeros_like(points)
    dirs[ok] = points[ok] / norm[ok, None]
    return dirs, ok


def brute_force_associate(dirs: np.ndarray, cells: np.ndarray, chunk: int = 2048) -> np.ndarray:
    """Reference association (Eq. 3.23): argmax_j <p^j, d> by chunked inner-product matrices."""
    out = np.empty(dirs.shape[0], np.int64)
    for s in range(0, dirs.shape[0], chunk):
        out[s:s + chunk] = np.argmax(dirs[s:s + chunk] @ cells.T, axis=1)
    return out


def _cube_face(d: np.ndarray, g: int) -> np.ndarray:
    """Cube-map bin index of unit directions (face * g * g + row * g + col)."""
    ax = np.argmax(np.abs(d), axis=1)
    rows = np.arange(d.shape[0])
    major = d[rows, ax]
    face = 2 * ax + (major < 0)
    ua = (ax + 1) % 3
    va = (ax + 2) % 3
    u = d[rows, ua] / np.abs(major)
    v = d[rows, va] / np.abs(major)
    iu = np.clip(((u + 1.0) * 0.5 * g).astype(np.int64), 0, g - 1)
    iv = np.clip(((v + 1.0) * 0.5 * g).astype(np.int64), 0, g - 1)
    return (face * g + iv) * g + iu


def _face_directions(ax: int, sign: float, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit directions through the points (u, v) of the cube face at coordinate ax = sign."""
    out = np.zeros(u.shape + (3,))
    out[..., ax] = sign
    out[..., (ax + 1) % 3] = u
    out[..., (ax + 2) % 3] = v
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def _bin_geometry(g: int) -> tuple[np.ndarray, np.ndarray]:
    """Centres (6 g^2, 3) and angular radii (6 g^2,) of the cube-map bins."""
    edges = np.linspace(-1.0, 1.0, g + 1)
    mids = 0.5 * (edges[1:] + edges[:-1])
    centers, radii = [], []
    for face in range(6):
        ax, neg = divmod(face, 2)
        sign = -1.0 if neg else 1.0
        vv, uu = np.meshgrid(mids, mids, indexing='ij')
        c = _face_directions(ax, sign, uu, vv)
        r = np.zeros(uu.shape)
        for du in (0, 1):
            for dv in (0, 1):
                cv, cu = np.meshgrid(edges[dv:g + dv], edges[du:g + du], indexing='ij')
                cos = np.clip(np.sum(_face_directions(ax, sign, cu, cv) * c, axis=-1), -1.0, 1.0)
                r = np.maximum(r, np.arccos(cos))
        centers.append(c.reshape(-1, 3))
        radii.append(r.ravel())
    return np.concatenate(centers), np.concatenate(radii)


class SphereLookup:
    """Exact nearest-direction lookup: a cube-map grid of candidate lists, KD-tree fallback.

    For a bin with centre c and angular radius r_b, let theta_c be the angle from c to its
    nearest cell. Any direction q in the bin has its nearest cell within theta_c + r_b of q,
    hence within theta_c + 2 r_b of c; those cells are the bin's candidates, so the argmax of
    <p, q> over the candidates is the global argmax (Eq. 3.23). Bins are grouped by candidate
    count and each group is evaluated as one padded (n, K, 3) inner product; bins with more
    than `max_candidates` candidates (very dense, biased regions) go to the KD-tree.

    Memory: each bin's candidates are stored once, in the table of its own padded width (int32
    indices and float64 coordinates per axis, the bin's row in `bin_row`): 16 MB for 20000 cells
    instead of 92 MB when every width's table held every bin (issue 27). The coordinates stay
    float64, so the argmax is that of the brute force, bit for bit.
    """

    def __init__(self, cells: np.ndarray, tree: cKDTree | None = None,
                 bins_per_cell: float = 3.0, max_candidates: int = 24) -> None:
        self.cells = cells
        self.tree = tree if tree is not None else cKDTree(cells)
        self.g = max(1, int(np.sqrt(bins_per_cell * cells.shape[0] / 6.0)))
        centers, radii = _bin_geometry(self.g)
        dist, _ = self.tree.query(centers)
        theta = 2.0 * np.arcsin(np.clip(dist / 2.0, 0.0, 1.0))
        reach = np.minimum(theta + 2.0 * radii + 1e-9, np.pi)
        lists = self.tree.query_ball_point(centers, 2.0 * np.sin(reach / 2.0) + 1e-12)
        counts = np.array([len(x) for x in lists])
        self.max_candidates = max_candidates
        self.bin_k = np.where(counts <= max_candidates, counts, 0)    # 0: use the tree
        # groups of bins padded to a multiple of 8 candidates (0: the tree)
        self.bin_group = np.where(self.bin_k > 0, (self.bin_k + 7) // 8, 0).astype(np.int8)
        # a bin's row in its group's table
        self.bin_row = np.zeros(centers.shape[0], np.int32)
        index_dtype = np.int32 if cells.shape[0] < 2 ** 31 else np.int64
        # per padded width k: contiguous (bins of the group, k) candidate indices (padded with
        # the first candidate) and coordinates per axis, so a query gathers whole rows (np.take)
        self.tables: dict[int, tuple[np.ndarray, ...]] = {}
        for g in np.unique(self.bin_group):
            if g == 0:
                continue
            k = 8 * int(g)
            members = np.nonzero(self.bin_group == g)[0]
            self.bin_row[members] = np.arange(members.size, dtype=np.int32)
            cand = np.empty((members.size, k), index_dtype)
            for row, b in enumerate(members):
                lst = lists[b]
                cand[row, :len(lst)] = lst
                cand[row, len(lst):] = lst[0]
            self.tables[k] = (cand, *(np.ascontiguousarray(cells[cand, a]) for a in range(3)))

    def query(self, dirs: np.ndarray) -> np.ndarray:
        """Nearest cell index per unit direction (n, 3) -> (n,)."""
        bins = _cube_face(dirs, self.g)
        grp = self.bin_group[bins]
        out = np.empty(dirs.shape[0], np.int64)
        for gi in np.unique(grp):
            sel = np.nonzero(grp == gi)[0]
            if gi == 0:
                out[sel] = self.tree.query(dirs[sel], workers=-1)[1]
                continue
            rows = self.bin_row[bins[sel]]
            q = dirs[sel]
            idx, cx, cy, cz = (np.take(t, rows, axis=0) for t in self.tables[8 * int(gi)])
            dots = cx * q[:, :1] + cy * q[:, 1:2] + cz * q[:, 2:3]         # (n, K)
            out[sel] = idx[np.arange(sel.size), np.argmax(dots, axis=1)]
        return out


@dataclass
class FusionReport:
    """What `SensoryEgoSphere.fuse` did with a frame."""

    received: int = 0
    fused: int = 0
    rejected: dict[str, int] = field(default_factory=dict)
    cells_updated: int = 0

    def summary(self) -> str:
        bad = ', '.join(f'{k}: {v}' for k, v in self.rejected.items() if v) or 'none'
        return (f'{self.fused}/{self.received} observations fused into {self.cells_updated} '
                f'cells; rejected: {bad}')


def valid_covariances(cov: np.ndarray, rel_tol: float = 1e-6,
                      return_inverse: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Finite, symmetric, positive-definite 3x3 matrices (Sylvester's criterion), (n,) bool.

    With return_inverse, also the inverses (n, 3, 3) (meaningful for the valid rows only): the
    determinant for the test costs most of an inverse anyway.
    """
    fin = np.all(np.isfinite(cov.reshape(cov.shape[0], -1)), axis=1)
    c = np.where(fin[:, None, None], cov, np.eye(3))
    scale = np.abs(c).max(axis=(1, 2)) + 1e-300
    sym = np.all(np.abs(c - c.transpose(0, 2, 1)) <= rel_tol * scale[:, None, None], axis=(1, 2))
    m1 = c[:, 0, 0]
    m2 = c[:, 0, 0] * c[:, 1, 1] - c[:, 0, 1] * c[:, 1, 0]
    m3, inv = det_inv3(c)
    ok = fin & sym & (m1 > 0) & (m2 > 0) & (m3 > 0)
    return (ok, inv) if return_inverse else ok


class SensoryEgoSphere:
    """N_x cells with Gaussian point estimates, fused in information form (Eqs. 3.34-3.35)."""

    def __init__(self, n_cells: int = 20000, bias: GMM | str = 'unbiased', seed: int = 0,
                 init_distance: float = 10.0, init_sigma: float = 10.0,
                 association: str = 'grid') -> None:
        if not (init_distance > 0 and init_sigma > 0):
            raise ValueError('init_distance and init_sigma must be > 0')
        if association not in ('grid', 'kdtree', 'brute'):
            raise ValueError(f"association must be 'grid', 'kdtree' or 'brute', got "
                             f'{association!r}')
        self.association = association
        self.directions = sample_directions(n_cells, bias, np.random.default_rng(seed))
        self.tree = cKDTree(self.directions)
        self.lookup = SphereLookup(self.directions, self.tree)
        n = n_cells
        self.info = np.broadcast_to(np.eye(3) / init_sigma ** 2, (n, 3, 3)).copy()
        self.info_vec = np.einsum('nab,nb->na', self.info, init_distance * self.directions)
        self.mean = init_distance * self.directions
        self.cov = np.broadcast_to(np.eye(3) * init_sigma ** 2, (n, 3, 3)).copy()
        self.n_obs = np.zeros(n, np.int64)
        self.n_frames = np.zeros(n, np.int64)      # fuse calls (frames) that observed the cell

    @property
    def n_cells(self) -> int:
        return int(self.directions.shape[0])

    def associate(self, points: np.ndarray, method: str | None = None) -> np.ndarray:
        """Cell index of each ego-frame point (Eq. 3.23); rows must have non-zero norm."""
        dirs, ok = unit_rows(np.asarray(points, np.float64))
        if not np.all(ok):
            raise ValueError('associate: points must be finite and away from the ego origin')
        return self._associate_directions(dirs, method)

    def _associate_directions(self, dirs: np.ndarray, method: str | None = None) -> np.ndarray:
        method = method or self.association
        if method == 'grid':
            return self.lookup.query(dirs)
        if method == 'kdtree':
            return self.tree.query(dirs, workers=-1)[1]
        if method == 'brute':
            return brute_force_associate(dirs, self.directions)
        raise ValueError(f'unknown association method {method!r}')

    def fuse(self, means: np.ndarray, covs: np.ndarray,
             ego_from_ref: np.ndarray | None = None) -> FusionReport:
        """Fuse N observations (means (N, 3), covs (N, 3, 3), in the frame of `ego_from_ref`).

        Eqs. 3.26-3.27 then 3.23 then 3.34-3.35. Invalid rows are skipped (see `FusionReport`);
        shape errors raise ValueError and leave the sphere unchanged.
        """
        mu = np.asarray(means, np.float64)
        cov = np.asarray(covs, np.float64)
        if mu.ndim != 2 or mu.shape[1] != 3 or cov.shape != (mu.shape[0], 3, 3):
            raise ValueError(f'fuse: expected means (N, 3) and covariances (N, 3, 3), got '
                             f'{mu.shape} and {cov.shape}')
        report = FusionReport(received=mu.shape[0])
        if ego_from_ref is not None:
            t = np.asarray(ego_from_ref, np.float64)
            if t.shape != (4, 4) or not np.all(np.isfinite(t)) or \
                    not np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-6):
                raise ValueError('fuse: ego_from_ref must be a finite 4x4 rigid transform')
            r = t[:3, :3]
            mu = mu @ r.T + t[:3, 3]                                   # Eq. 3.26
            cov = r @ cov @ r.T                                        # Eq. 3.27
        fin = np.all(np.isfinite(mu), axis=1)
        good_cov, inv = valid_covariances(cov, return_inverse=True)
        dirs, nonzero = unit_rows(np.where(fin[:, None], mu, 0.0))
        report.rejected = {'non-finite mean': int(np.sum(~fin)),
                           'bad covariance': int(np.sum(fin & ~good_cov)),
                           'at ego origin': int(np.sum(fin & good_cov & ~nonzero))}
        keep = fin & good_cov & nonzero
        all_kept = bool(keep.all())          # the usual case: no copies
        mu = mu if all_kept else mu[keep]
        report.fused = int(mu.shape[0])
        if report.fused == 0:
            return report
        cell = self._associate_directions(dirs if all_kept else dirs[keep])
        lam = inv if all_kept else inv[keep]                           # Sigma_z'^-1
        eta = np.einsum('nab,nb->na', lam, mu)
        n = self.n_cells
        d_info = np.stack([np.bincount(cell, lam.reshape(-1, 9)[:, k], n) for k in range(9)],
                          axis=1).reshape(n, 3, 3)
        d_vec = np.stack([np.bincount(cell, eta[:, k], n) for k in range(3)], axis=1)
        counts = np.bincount(cell, minlength=n)
        touched = np.nonzero(counts)[0]
        self.info += d_info                                            # Eq. 3.34 (inverse)
        self.info_vec += d_vec
        self.n_obs += counts
        self.n_frames[touched] += 1
        self.cov[touched] = det_inv3(self.info[touched])[1]            # Eq. 3.34
        self.mean[touched] = np.einsum('nab,nb->na', self.cov[touched],
                                       self.info_vec[touched])        # Eq. 3.35
        report.cells_updated = int(touched.size)
        return report
