"""Two-stage Hough cylinder fitting (thesis section 4.3.3, after Rabbani & van den Heuvel 2005).

Stage 1: the orientation accumulator votes for the axis (Eq. 4.3 for ours, normals only for the
baseline). Stage 2 (same for both): rotate the points so the axis is z, project the side points
(normal roughly orthogonal to the axis) on the xy plane, and find the circle (centre, radius) by a
circle Hough transform (votes counted with np.bincount), refined by an algebraic least-squares
circle fit on the Hough inliers. Height is the
inliers' extent along the axis; confidence is N_model / N_cluster (Eq. 4.4).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from .accumulator import TABLE_4_1, OrientationGMM, sample_gmm_directions, uniform_directions, vote_curvature, vote_normals
from .geometry import normals_and_curvature

Array = NDArray[np.float64]
METHODS = ('ours', 'rabbani')


@dataclass(frozen=True)
class FitParams:
    """Parameters of the fit. Defaults follow the authors' tabletop settings where the thesis is silent."""

    method: str = 'ours'                 #: 'ours' (GMM accumulator, Eq. 4.3) or 'rabbani' (uniform, normals only)
    n_directions: int = 450              #: N_d (section 4.4.1)
    gmm: OrientationGMM = TABLE_4_1['unbiased']
    k_neighbours: int = 15               #: PCA neighbourhood size
    radius_min: float = 0.01             #: m
    radius_max: float = 0.1              #: m
    radius_bins: int = 16
    position_bins: int = 40              #: per axis of the projected plane
    circle_samples: int = 24             #: centres each point votes for, per radius
    inlier_distance: float = 0.15        #: |dist to axis - r| below this fraction of r (plus noise floor) is an inlier
    inlier_floor: float = 0.003          #: m, absolute inlier tolerance added to the relative one
    min_points: int = 20                 #: clusters with fewer points are not fitted
    max_points: int = 600                #: larger clusters are randomly subsampled to this many
    min_confidence: float = 0.5          #: Eq. 4.4 threshold
    curvature_saturation: float | None = 0.05
    """Curvature weight of Eq. 4.3 as min(k_max / k_sat, 1), k_sat = this fraction of the cluster's
    90th-percentile k_max (a scale-free high-pass); None uses the raw k_max (then sharp lid rims,
    k_max ~ 0.17 against ~0.03 on the side, outvote the side and the axis tilts under lids)."""
    vote_sharpness: float = 8.0
    """Exponent on each Eq. 4.3 vote (1 = as printed); > 1 concentrates votes on the cell each point
    supports, so cap rims (locally cylinders along the rim tangent) spread over the equator instead
    of outvoting the side."""
    normal_axis_max_dot: float = 0.5     #: stage 2 keeps points with |n . axis| below this (as the authors' code)
    seed: int = 0                        #: seeds the GMM accumulator

    def __post_init__(self) -> None:
        problems = []
        if self.method not in METHODS:
            problems.append(f'method must be one of {METHODS}, got {self.method!r}')
        if self.n_directions < 1:
            problems.append('n_directions must be >= 1')
        if not 0 < self.radius_min < self.radius_max:
            problems.append('need 0 < radius_min < radius_max')
        if self.radius_bins < 1 or self.position_bins < 2 or self.circle_samples < 4:
            problems.append('radius_bins >= 1, position_bins >= 2, circle_samples >= 4')
        if self.k_neighbours < 3 or self.min_points < 3:
            problems.append('k_neighbours and min_points must be >= 3')
        q = self.curvature_saturation
        if q is not None and not 0 < q <= 1:
            problems.append('curvature_saturation must be in (0, 1] or None')
        if not 0 < self.normal_axis_max_dot <= 1:
            problems.append('normal_axis_max_dot must be in (0, 1]')
        if not 0 <= self.min_confidence <= 1:
            problems.append('min_confidence must be in [0, 1]')
        if problems:
            raise ValueError('FitParams: ' + '; '.join(problems))


@dataclass(frozen=True)
class Cylinder:
    """A fitted cylinder: centre (m), unit axis, radius (m), height (m), confidence (Eq. 4.4)."""

    centre: tuple[float, float, float]
    axis: tuple[float, float, float]
    radius: float
    height: float
    confidence: float
    n_inliers: int
    n_points: int

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def make_directions(params: FitParams) -> Array:
    """The orientation accumulator D for these parameters (Eq. 4.1-4.2, or uniform for the baseline)."""
    if params.method == 'rabbani':
        return uniform_directions(params.n_directions)
    return sample_gmm_directions(params.gmm, params.n_directions, np.random.default_rng(params.seed))


def curvature_weights(k_max: Array, fraction: float | None) -> Array:
    """The k_max factor of Eq. 4.3 as a saturating high-pass: min(k_max / k_sat, 1), k_sat = fraction
    x the cluster's 90th-percentile k_max (scale-free: k_max depends on neighbourhood size / radius)."""
    if fraction is None or len(k_max) == 0:
        return k_max
    k_sat = fraction * float(np.quantile(k_max, 0.9))
    if k_sat <= 1e-12:
        return np.ones_like(k_max)
    return np.minimum(k_max / k_sat, 1.0)


def estimate_axis(normals: Array, c_max: Array, k_max: Array, directions: Array, method: str,
                  saturation: float | None = 0.05, sharpness: float = 1.0) -> Array:
    """Stage 1: the accumulator cell with most votes (Eq. 4.3 for 'ours', normals only for 'rabbani')."""
    if method == 'rabbani':
        votes = vote_normals(directions, normals)
    else:
        votes = vote_curvature(directions, normals, c_max, curvature_weights(k_max, saturation), sharpness)
    d = directions[int(np.argmax(votes))]
    return d / np.linalg.norm(d)


def rotation_to_z(axis: Array) -> Array:
    """A rotation matrix R with R @ axis = +z (Rodrigues)."""
    a = axis / np.linalg.norm(axis)
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(a, z)
    c = float(a @ z)
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def circle_hough(xy: Array, params: FitParams) -> tuple[Array, float]:
    """Circle Hough transform on projected points: each point votes for the centres at distance r,
    for every radius bin, in a (position_bins^2 x radius_bins) accumulator. Returns (centre, r)."""
    radii = np.linspace(params.radius_min, params.radius_max, params.radius_bins)
    nb, n_r = params.position_bins, len(radii)
    lo = xy.min(axis=0) - params.radius_max
    hi = xy.max(axis=0) + params.radius_max
    cell = (hi - lo) / nb
    ang = np.linspace(0.0, 2 * np.pi, params.circle_samples, endpoint=False)
    # cell coordinates of every (point, radius, angle) centre; all >= 0 by construction of lo
    du = (radii[:, None] * np.cos(ang)[None] / cell[0]).astype(np.float32)            # (R, T)
    dv = (radii[:, None] * np.sin(ang)[None] / cell[1]).astype(np.float32)
    pu = ((xy[:, 0] - lo[0]) / cell[0]).astype(np.float32)[:, None, None]
    pv = ((xy[:, 1] - lo[1]) / cell[1]).astype(np.float32)[:, None, None]
    iu = np.minimum((pu + du).astype(np.int32), nb - 1)                                # (N, R, T)
    iv = np.minimum((pv + dv).astype(np.int32), nb - 1)
    flat = (iu * nb + iv) * n_r + np.arange(n_r, dtype=np.int32)[None, :, None]
    # about one vote per point per (cell, radius): a small circle's consecutive samples often share a
    # cell and must not count twice (else small radii win)
    keep = flat != np.roll(flat, 1, axis=2)
    acc = np.bincount(flat[keep], minlength=nb * nb * n_r)   # the vectorized np.add.at
    i, j, r = np.unravel_index(int(np.argmax(acc)), (nb, nb, n_r))
    return lo + (np.array([i, j]) + 0.5) * cell, float(radii[r])


def fit_circle_lsq(xy: Array) -> tuple[Array, float] | None:
    """Algebraic (Kasa) least-squares circle: x^2 + y^2 + D x + E y + F = 0."""
    if len(xy) < 3:
        return None
    a = np.column_stack([xy, np.ones(len(xy))])
    b = -(xy ** 2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    c = -0.5 * sol[:2]
    r2 = float(c @ c - sol[2])
    if not np.isfinite(r2) or r2 <= 0:
        return None
    return c, float(np.sqrt(r2))


def fit_cylinder(points: Array, params: FitParams | None = None, directions: Array | None = None,
                 features: tuple[Array, Array, Array] | None = None) -> Cylinder | None:
    """Fit one cylinder to a cluster; None when it is too small or below the Eq. 4.4 threshold.

    `directions` (the accumulator) and `features` (normals, c_max, k_max) may be passed in to reuse
    them across clusters or methods.
    """
    params = params or FitParams()
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) < params.min_points:
        return None
    if len(pts) > params.max_points and features is None:
        pts = pts[np.random.default_rng(params.seed).choice(len(pts), params.max_points, replace=False)]
    if directions is None:
        directions = make_directions(params)
    normals, c_max, k_max = features if features is not None else normals_and_curvature(pts, params.k_neighbours)
    axis = estimate_axis(normals, c_max, k_max, directions, params.method,
                         params.curvature_saturation, params.vote_sharpness)
    rot = rotation_to_z(axis)
    q = pts @ rot.T
    side = np.abs(normals @ axis) < params.normal_axis_max_dot
    if side.sum() < 3:
        return None
    centre_xy, radius = circle_hough(q[side, :2], params)
    tol = params.inlier_distance * radius + params.inlier_floor
    inl = np.abs(np.linalg.norm(q[:, :2] - centre_xy, axis=1) - radius) < tol
    if (inl & side).sum() >= 3:
        refined = fit_circle_lsq(q[inl & side, :2])
        if refined is not None and params.radius_min * 0.5 <= refined[1] <= params.radius_max * 1.5:
            centre_xy, radius = refined
            tol = params.inlier_distance * radius + params.inlier_floor
            inl = np.abs(np.linalg.norm(q[:, :2] - centre_xy, axis=1) - radius) < tol
    n_in = int(inl.sum())
    confidence = n_in / len(pts)
    if n_in < 3 or confidence < params.min_confidence:
        return None
    z = q[inl, 2]
    z0, z1 = float(z.min()), float(z.max())
    centre = rot.T @ np.array([centre_xy[0], centre_xy[1], 0.5 * (z0 + z1)])
    return Cylinder(tuple(map(float, centre)), tuple(map(float, axis)), float(radius), z1 - z0,
                    float(confidence), n_in, len(pts))
