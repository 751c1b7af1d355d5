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
            raise ValueError('OrientationGMM: weights, means and covariances need the same non-zero length')
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


def vote_curvature(directions: Array, normals: Array, c_max: Array, k_max: Array, sharpness: float = 1.0) -> Array:
    """Soft votes A(i) = sum_s k_max^s [(1 - |d^i.c_max^s|)(1 - |d^i.n^s|)]^sharpness (Eq. 4.3).

    sharpness = 1 is Eq. 4.3 as printed. Absolute inner products make the vote independent of the
    (arbitrary) signs of n and c, as an axis is: d and -d are the same orientation.
    """
    # float32: votes need no more, and the (N_d x N) products and powers run twice as fast
    d32 = directions.astype(np.float32, copy=False)
    dn = np.abs(d32 @ normals.T.astype(np.float32))
    dc = np.abs(d32 @ c_max.T.astype(np.float32))
    v = (1.0 - dc) * (1.0 - dn)
    if sharpness != 1.0:
        e = float(sharpness)
        if e.is_integer() and e > 0 and (int(e) & (int(e) - 1)) == 0:   # 2, 4, 8, ...: repeated squaring
            for _ in range(int(e).bit_length() - 1):
                v *= v
        else:
            v = v ** e
    return (v @ k_max.astype(np.float32)).astype(np.float64)


def vote_normals(directions: Array, normals: Array) -> Array:
    """Normals-only soft votes A(i) = sum_s (1 - |d^i.n^s|), the Rabbani baseline's criterion:
    every normal votes for the great circle of directions orthogonal to it."""
    return (1.0 - np.abs(directions @ normals.T)).sum(axis=1)
