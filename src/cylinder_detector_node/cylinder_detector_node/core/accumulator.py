"""Orientation Hough accumulators and their voting functions (thesis section 4.3.3).

An accumulator is a set of N_d unit directions d^i (Eq. 4.1). Ours samples them i.i.d. from a 3D
Gaussian mixture and normalizes them (Eq. 4.2); the biases of Table 4.1 are given as presets.
The baseline of Rabbani & van den Heuvel (2005) samples the sphere uniformly and deterministically
(here a Fibonacci lattice). Votes are one matrix product of directions with normals/curvatures.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class OrientationGMM:
    """A Gaussian mixture over R^3 (Eq. 4.2): weights phi^m, means mu^m, covariances Sigma^m."""

    weights: tuple[float, ...] = (1.0,)
    means: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0),)
    covariances: tuple[tuple[float, float, float], ...] = field(default=((0.5, 0.5, 0.5),))
    """Diagonal covariances (xx, yy, zz) as in Table 4.1."""

    def __post_init__(self) -> None:
        m = len(self.weights)
        if m == 0 or len(self.means) != m or len(self.covariances) != m:
            raise ValueError('OrientationGMM: weights, means and covariances need the same '
                             'non-zero length')
        if any(w < 0 for w in self.weights) or sum(self.weights) <= 0:
            raise ValueError('OrientationGMM: weights must be non-negative with a positive sum')
        if any(c <= 0 for cov in self.covariances for c in cov):
            raise ValueError('OrientationGMM: covariances must be positive')


#: Table 4.1 (mean, diagonal covariance) biases; "vertical" is +z of the cloud's frame.
TABLE_4_1: dict[str, OrientationGMM] = {
    'unbiased': OrientationGMM((1.0,), ((0.0, 0.0, 0.0),), ((0.5, 0.5, 0.5),)),
    'mild': OrientationGMM((1.0,), ((0.0, 0.0, 1.0),), ((0.5, 0.5, 0.5),)),
    'strong': OrientationGMM((1.0,), ((0.0, 0.0, 1.0),), ((0.05, 0.05, 0.05),)),
}


def sample_gmm_directions(gmm: OrientationGMM, n_d: int, rng: np.random.Generator) -> Array:
    """N_d unit directions d^i = v^i / ||v^i||, v^i ~ sum_m phi^m N(mu^m, Sigma^m) (Eq. 4.2)."""
    w = np.asarray(gmm.weights, dtype=float)
    comp = rng.choice(len(w), size=n_d, p=w / w.sum())
    mu = np.asarray(gmm.means, dtype=float)[comp]
    std = np.sqrt(np.asarray(gmm.covariances, dtype=float))[comp]
    v = mu + std * rng.standard_normal((n_d, 3))
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    v = np.where(norm > 1e-12, v, np.array([0.0, 0.0, 1.0]))
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)


def uniform_directions(n_d: int) -> Array:
    """N_d deterministic, near-uniform directions on the unit sphere (Fibonacci lattice)."""
    i = np.arange(n_d) + 0.5
    z = 1.0 - 2.0 * i / n_d
    phi = np.pi * (1.0 + 5.0 ** 0.5) * i
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def vote_curvature(directions: Array, normals: Array, c_max: Array, k_max: Array,
                   sharpness: float = 1.0) -> Array:
    """Soft votes A(i) = sum_s k_max^s [(1 - |d^i.c_max^s|)(1 - |d^i.n^s|)]^sharpness (Eq. 4.3).

    sharpness = 1 is Eq. 4.3 as printed. Absolute inner products make the vote independent of the
    (arbitrary) signs of n and c, as an axis is: d and -d are the same orientation.
    """
    # float32: votes need no more, and the (N_d x N) products and powers run twice as fast
    f32 = np.float32
    return votes_f32(directions.astype(f32, copy=False),
                     np.stack([normals, c_max]).astype(f32, copy=False),
                     k_max.astype(f32, copy=False), sharpness).astype(np.float64)


def votes_f32(d: NDArray[np.float32], features: NDArray[np.float32], weights: NDArray[np.float32],
              sharpness: float = 1.0) -> NDArray[np.float32]:
    """vote_curvature on float32 arrays, features (2, N, 3) = (normals, c_max), returning float32.
    Both inner products come from one batched product and the factors are formed in place (no
    fresh (N_d x N) temporary per step)."""
    p = np.matmul(d, features.transpose(0, 2, 1))   # (2, N_d, N): d.n, d.c
    np.abs(p, out=p)
    np.subtract(1.0, p, out=p)                      # 1 - |d.n|, 1 - |d.c|
    v = p[0]
    v *= p[1]
    if sharpness != 1.0:
        e = float(sharpness)
        # 2, 4, 8, ...: repeated squaring
        if e.is_integer() and e > 0 and (int(e) & (int(e) - 1)) == 0:
            for _ in range(int(e).bit_length() - 1):
                v *= v
        else:
            np.power(v, e, out=v)
    return v @ weights


def vote_normals(directions: Array, normals: Array) -> Array:
    """Normals-only soft votes A(i) = sum_s (1 - |d^i.n^s|), the Rabbani baseline's criterion:
    every normal votes for the great circle of directions orthogonal to it."""
    v = directions @ normals.T
    np.abs(v, out=v)                                # in place, as in votes_f32
    np.subtract(1.0, v, out=v)
    return v.sum(axis=1)
