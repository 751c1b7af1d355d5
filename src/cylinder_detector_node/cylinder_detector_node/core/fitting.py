"""Two-stage Hough cylinder fitting (thesis section 4.3.3, after Rabbani & van den Heuvel 2005).

Stage 1: the orientation accumulator votes for the axis (Eq. 4.3 for ours, normals only for the
baseline). Stage 2 (same for both): rotate the points so the axis is z, project the side points
(normal roughly orthogonal to the axis) on the xy plane, and find the circle (centre, radius) by a
circle Hough transform (votes counted with np.bincount), refined by an algebraic least-squares
circle fit on the Hough inliers. Height is the
inliers' extent along the axis; confidence is N_model / N_cluster (Eq. 4.4). normal_agreement is
the fraction of the side inliers whose normal is radial (issue 31: a box's faces pass Eq. 4.4 but
not this); a fit below FitParams.min_normal_agreement gets its axis refined from those normals.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from .accumulator import (
    TABLE_4_1,
    OrientationGMM,
    sample_gmm_directions,
    uniform_directions,
    vote_normals,
    votes_f32,
)
from .geometry import normals_and_curvature, pca_normals

Array = NDArray[np.float64]
METHODS = ('ours', 'rabbani')


@dataclass(frozen=True)
class FitParams:
    """Parameters of the fit. Defaults follow the authors' tabletop settings where the thesis is
    silent."""

    #: 'ours' (GMM accumulator, Eq. 4.3) or 'rabbani' (uniform, normals only)
    method: str = 'ours'
    n_directions: int = 450              #: N_d (section 4.4.1)
    gmm: OrientationGMM = TABLE_4_1['unbiased']
    k_neighbours: int = 15               #: PCA neighbourhood size
    radius_min: float = 0.01             #: m
    radius_max: float = 0.1              #: m
    radius_bins: int = 16
    position_bins: int = 40              #: per axis of the projected plane
    circle_samples: int = 24             #: centres each point votes for, per radius
    #: |dist to axis - r| below this fraction of r (plus noise floor) is an inlier
    inlier_distance: float = 0.15
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
    #: stage 2 keeps points with |n . axis| below this (as the authors' code)
    normal_axis_max_dot: float = 0.5
    #: ours: points voting for every cell in the coarse pass (0 = one full pass)
    coarse_points: int = 100
    candidates: int = 16                 #: ours: best coarse cells re-voted by all points
    #: ours: when the fit's Eq. 4.4 is below retry_below, try this many more peaks
    retry_peaks: int = 8
    retry_below: float = 0.5
    retry_separation_deg: float = 45.0   #: the retried peaks are this far apart (as axes)
    seed: int = 0                        #: seeds the GMM accumulator
    normal_agreement_deg: float = 20.0
    """A side inlier's normal agrees with the fit when it is within this angle of the radial
    direction (a cylinder's normals all point at its axis)."""
    min_normal_agreement: float = 0.7
    """detect_cylinders refuses fits whose side inliers agree less often than this (fit_cylinder
    reports Cylinder.normal_agreement, refines the axis of fits below it (refine_axis) and applies
    Eq. 4.4 only): Eq. 4.4 counts points near the circle, so the two faces of a box corner (normals
    in two directions, a circle of about half the box's width through them) passed it (issue 31);
    0 turns both off."""

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
        if not 0 <= self.min_normal_agreement <= 1:
            problems.append('min_normal_agreement must be in [0, 1]')
        if not 0 < self.normal_agreement_deg < 90:
            problems.append('normal_agreement_deg must be in (0, 90)')
        if problems:
            raise ValueError('FitParams: ' + '; '.join(problems))


def vec3(v: Array) -> tuple[float, float, float]:
    """A 3-vector as a tuple of 3 floats (Cylinder's centre and axis)."""
    x, y, z = map(float, v)
    return x, y, z


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
    #: fraction of the side inliers whose normal is radial (FitParams.normal_agreement_deg)
    normal_agreement: float = 1.0

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def make_directions(params: FitParams) -> Array:
    """The orientation accumulator D for these parameters (Eq. 4.1-4.2, or uniform for the
    baseline)."""
    if params.method == 'rabbani':
        return uniform_directions(params.n_directions)
    return sample_gmm_directions(params.gmm, params.n_directions,
                                 np.random.default_rng(params.seed))


def curvature_weights(k_max: Array, fraction: float | None) -> Array:
    """The k_max factor of Eq. 4.3 as a saturating high-pass: min(k_max / k_sat, 1), k_sat =
    fraction x the cluster's 90th-percentile k_max (scale-free: k_max depends on neighbourhood
    size / radius)."""
    if fraction is None or len(k_max) == 0:
        return k_max
    # the 90th percentile (np.quantile's linear interpolation) from a partial sort: quantile's
    # overhead was a third of this function's time on 600-point clusters
    n = len(k_max)
    pos = 0.9 * (n - 1)
    lo = int(pos)
    hi = min(lo + 1, n - 1)
    part = k_max.copy()
    part.partition((lo, hi))                 # np.partition without its wrapper's overhead
    p_lo, p_hi = float(part[lo]), float(part[hi])
    k_sat = fraction * (p_lo + (pos - lo) * (p_hi - p_lo))
    if k_sat <= 1e-12:
        return np.ones_like(k_max)
    w = k_max / k_sat
    return np.minimum(w, 1.0, out=w)


@lru_cache(maxsize=64)
def even_subset(n: int, m: int) -> NDArray[np.intp]:
    """m evenly spaced indices into n points (the coarse vote's voters), cached: cluster sizes
    repeat (max_points) and np.linspace's overhead is not small against the vote itself."""
    sub = np.linspace(0, n - 1, m).astype(np.intp)
    sub.flags.writeable = False
    return sub


def axis_votes(normals: Array, c_max: Array, k_max: Array, directions: Array, method: str,
               saturation: float | None = 0.05, sharpness: float = 1.0, coarse_points: int = 0,
               candidates: int = 0) -> tuple[int, Array]:
    """Stage 1 votes: (index of the winning cell, votes of every cell) (Eq. 4.3 for 'ours',
    normals only for 'rabbani').

    For 'ours' with coarse_points > 0 and candidates > 0 the vote is coarse to fine: every cell is
    voted by an evenly spaced subset of coarse_points points (the votes returned), then only the
    `candidates` best cells by all points; the winner is the full vote's maximum among them (the
    same as the full accumulator's unless the subset misranks the true peak below `candidates`
    others).
    """
    if method == 'rabbani':
        votes = vote_normals(directions, normals)
        return int(np.argmax(votes)), votes
    w = curvature_weights(k_max, saturation)
    # the votes run in float32 (vote_curvature): convert once for both passes
    n = len(normals)
    feats = np.empty((2, n, 3), np.float32)
    feats[0], feats[1] = normals, c_max
    w32, d32 = w.astype(np.float32), directions.astype(np.float32)
    if 0 < coarse_points < n and 0 < candidates < len(directions):
        sub = even_subset(n, coarse_points)
        coarse = votes_f32(d32, feats[:, sub], w32[sub], sharpness).astype(np.float64)
        cand = coarse.argpartition(-candidates)[-candidates:]
        fine = votes_f32(d32[cand], feats, w32, sharpness)
        return int(cand[int(fine.argmax())]), coarse
    votes = votes_f32(d32, feats, w32, sharpness).astype(np.float64)
    return int(np.argmax(votes)), votes


def estimate_axis(normals: Array, c_max: Array, k_max: Array, directions: Array, method: str,
                  saturation: float | None = 0.05, sharpness: float = 1.0, coarse_points: int = 0,
                  candidates: int = 0) -> Array:
    """Stage 1: the unit direction of the accumulator cell with most votes (see axis_votes)."""
    best, _ = axis_votes(normals, c_max, k_max, directions, method, saturation, sharpness,
                         coarse_points, candidates)
    d = directions[best]
    return d / np.linalg.norm(d)


def separated_peaks(directions: Array, votes: Array, first: int, n: int,
                    min_angle_deg: float) -> list[int]:
    """Up to n cells after `first`, by decreasing votes, each at least min_angle_deg (as axes)
    from every cell already taken (greedy, on a precomputed closeness matrix)."""
    unit = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    order = np.argsort(-votes, kind='stable')
    # (cells by votes, cells)
    close = np.abs(unit[order] @ unit.T) >= np.cos(np.radians(min_angle_deg))
    blocked = close[int(np.flatnonzero(order == first)[0])].copy()
    taken: list[int] = []
    for rank, i in enumerate(order):
        if len(taken) >= n:
            break
        if not blocked[i]:
            taken.append(int(i))
            blocked |= close[rank]
    return taken


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
    # about one vote per point per (cell, radius): a small circle's consecutive samples often share
    # a cell and must not count twice (else small radii win)
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
        pick = np.random.default_rng(params.seed).choice(len(pts), params.max_points, replace=False)
        pts = pts[pick]
    if directions is None:
        directions = make_directions(params)
    if features is not None:
        normals, c_max, k_max = features
    elif params.method == 'rabbani':   # the baseline needs normals only
        normals, _ = pca_normals(pts, params.k_neighbours)
        c_max, k_max = normals, np.zeros(len(pts))
    else:
        normals, c_max, k_max = normals_and_curvature(pts, params.k_neighbours)
    best, votes = axis_votes(normals, c_max, k_max, directions, params.method,
                             params.curvature_saturation, params.vote_sharpness,
                             params.coarse_points, params.candidates)
    fit = fit_with_axis(pts, normals, directions[best] / np.linalg.norm(directions[best]), params)
    if (params.method == 'ours' and params.retry_peaks > 0
            and (fit is None or fit.confidence < params.retry_below)):
        # A weak fit: try the next well-separated accumulator peaks (short capped cylinders, whose
        # lid rims outvote the side, get their true axis back this way). Candidates are compared
        # by the curvature-weighted inlier fraction (the Eq. 4.3 weights: flat lid points count
        # for nothing), not by Eq. 4.4, which wrong axes through big lids can win; they are scored
        # on every 3rd point and only the winner is refitted on all points.
        w = curvature_weights(k_max, params.curvature_saturation)
        sub = slice(None, None, 3) if len(pts) >= 3 * params.min_points else slice(None)
        best_score = -1.0 if fit is None else weighted_inliers(pts, w, fit, params)
        best_axis = None
        for i in separated_peaks(directions, votes, best, params.retry_peaks,
                                 params.retry_separation_deg):
            axis = directions[i] / np.linalg.norm(directions[i])
            other = fit_with_axis(pts[sub], normals[sub], axis, params)
            score = -1.0 if other is None else weighted_inliers(pts[sub], w[sub], other, params)
            if score > best_score:
                best_score, best_axis = score, axis
        if best_axis is not None:
            other = fit_with_axis(pts, normals, best_axis, params)
            if other is not None:
                fit = other
    if fit is not None and fit.normal_agreement < params.min_normal_agreement:
        # N_d = 450 cells lie ~10 deg apart: a lying pipe's axis can be off by that much, and its
        # normals then look tilted from radial. A cylinder's normals are all orthogonal to its
        # axis, so the normals of the side inliers give the axis (their scatter's least
        # eigenvector); a box's face normals already are orthogonal to the axis and gain nothing.
        # Kept only if Eq. 4.4 does not fall too (else lid-heavy clusters' axes got worse).
        for _ in range(2):
            refined = refine_axis(pts, normals, fit, params)
            if (refined is None or refined.normal_agreement <= fit.normal_agreement
                    or refined.confidence < fit.confidence):
                break
            fit = refined
    if fit is None or fit.confidence < params.min_confidence:
        return None
    return fit


def refine_axis(pts: Array, normals: Array, cyl: Cylinder, params: FitParams) -> Cylinder | None:
    """Stage 2 again about the axis the side inliers' normals are most orthogonal to."""
    a, c = np.asarray(cyl.axis), np.asarray(cyl.centre)
    v = pts - c
    dist = np.linalg.norm(v - np.outer(v @ a, a), axis=1)
    inl = ((np.abs(dist - cyl.radius) < params.inlier_distance * cyl.radius + params.inlier_floor)
           & (np.abs(normals @ a) < params.normal_axis_max_dot))
    if inl.sum() < params.min_points:
        return None
    n = normals[inl]
    _, vecs = np.linalg.eigh(n.T @ n)
    axis = vecs[:, 0] if vecs[:, 0] @ a >= 0 else -vecs[:, 0]
    return fit_with_axis(pts, normals, axis, params)


def weighted_inliers(pts: Array, weights: Array, cyl: Cylinder, params: FitParams) -> float:
    """Fraction of the weight of the points on cyl's surface (the Eq. 4.4 inlier test)."""
    a, c = np.asarray(cyl.axis), np.asarray(cyl.centre)
    v = pts - c
    dist = np.linalg.norm(v - np.outer(v @ a, a), axis=1)
    inl = np.abs(dist - cyl.radius) < params.inlier_distance * cyl.radius + params.inlier_floor
    total = float(weights.sum())
    return float(weights[inl].sum()) / total if total > 0 else 0.0


def fit_with_axis(pts: Array, normals: Array, axis: Array, params: FitParams) -> Cylinder | None:
    """Stage 2 for a given axis: circle Hough on the side points projected along it, least-squares
    refinement, height from the inliers, confidence N_model / N_cluster (Eq. 4.4, not
    thresholded)."""
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
    if n_in < 3:
        return None
    z = q[inl, 2]
    z0, z1 = float(z.min()), float(z.max())
    centre = rot.T @ np.array([centre_xy[0], centre_xy[1], 0.5 * (z0 + z1)])
    return Cylinder(vec3(centre), vec3(axis), float(radius), z1 - z0,
                    float(n_in / len(pts)), n_in, len(pts),
                    normal_agreement(q[inl & side, :2] - centre_xy, normals[inl & side] @ rot.T,
                                     params.normal_agreement_deg))


def normal_agreement(radial_xy: Array, normals: Array, max_angle_deg: float) -> float:
    """Fraction of surface points (radial_xy: their offset from the axis, in the frame where the
    axis is z; normals in that frame) whose normal lies within max_angle_deg of the radial
    direction, either sign (PCA normals are unsigned). A cylinder's normals are radial; a flat
    face's are not, except where it touches the circle (the test PCL's normal-distance cylinder
    model makes, as a separate check on the fit rather than a change to Eq. 4.4)."""
    if len(radial_xy) == 0:
        return 0.0
    r = np.linalg.norm(radial_xy, axis=1)
    n = np.linalg.norm(normals, axis=1)
    ok = (r > 0) & (n > 0)
    if not ok.any():
        return 0.0
    cos = np.abs(np.einsum('ij,ij->i', radial_xy[ok], normals[ok, :2])) / (r[ok] * n[ok])
    return float(np.count_nonzero(cos >= np.cos(np.radians(max_angle_deg)))) / len(radial_xy)
