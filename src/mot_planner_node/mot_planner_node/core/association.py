"""Detection-to-track association: Hungarian algorithm on Mahalanobis distance with gating.

Section 5.4: "The association between detections and trackers was performed with the
Hungarian Algorithm using the Mahalanobis distance." Pairs whose squared distance exceeds the
chi-square gate (3 degrees of freedom: u, v, s) are never matched.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from .kalman import MEAS_DIM, mahalanobis_sq

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class Association(NamedTuple):
    """matches (n, 2) [track, detection] index pairs; the unmatched tracks and detections;
    d2 (K, M) the squared Mahalanobis distances."""

    matches: IntArray
    unmatched_tracks: IntArray
    unmatched_detections: IntArray
    d2: FloatArray


def gate_threshold(probability: float) -> float:
    """Squared-distance gate that keeps a true match with the given probability."""
    if not 0.0 < probability < 1.0:
        raise ValueError(f'gate probability must be in (0, 1), got {probability}')
    return float(chi2.ppf(probability, MEAS_DIM))


def associate(x: FloatArray, P: FloatArray, z: FloatArray, R: FloatArray,
              gate: float) -> Association:
    """Match K predicted targets (x, P) to M observations (z (M, 3), R (M, 3, 3))."""
    K, M = x.shape[0], z.shape[0]
    d2 = mahalanobis_sq(x, P, z, R)
    if K == 0 or M == 0:
        return Association(np.zeros((0, 2), np.int64), np.arange(K), np.arange(M), d2)
    big = 1e6 * max(gate, 1.0)
    cost = np.where(d2 <= gate, d2, big)
    rows, cols = linear_sum_assignment(cost)
    ok = cost[rows, cols] < big
    matches = np.stack([rows[ok], cols[ok]], axis=1).astype(np.int64)
    return Association(matches,
                       np.setdiff1d(np.arange(K), matches[:, 0]),
                       np.setdiff1d(np.arange(M), matches[:, 1]), d2)
