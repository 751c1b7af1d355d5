"""Next-best-view selection over the ego-sphere cells (thesis section 3.3.4, Eqs. 3.36-3.43).

Reward of fixating cell a: r(x^a) = -||x^a|| (Eq. 3.36), Gaussian to first order (Eq. 3.37):
mu_r = -||mu_a|| (Eq. 3.38) and variance J^T Sigma_a J with J = -mu_a / ||mu_a|| (Eqs.
3.39-3.40; the thesis prints J without the minus sign, which the quadratic form ignores).

Acquisition functions (each returns the cell to fixate):
- UCB (Eq. 3.41): argmax mu_r + alpha sigma_r. The thesis writes sigma_r for the variance of
  Eq. 3.39; here sigma_r is its square root (the usual UCB, same units as the reward). alpha = 0
  is greedy, alpha = inf picks the most uncertain cell (pure exploration).
- PI (Eq. 3.42): argmax P(r_a > r*) = Phi((mu_r - r* - xi) / sigma_r).
- EI (Eq. 3.43): argmax E[max(r_a - r*, 0)] = (mu_r - r* - xi) Phi(u) + sigma_r phi(u),
  u = (mu_r - r* - xi) / sigma_r.
r* (the current best) is the best expected reward over the cells, max_a mu_r, unless given.
Ties go to the lowest index (np.argmax).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

_INV_SQRT_2PI = 1.0 / np.sqrt(2.0 * np.pi)

ACQUISITIONS = ('ucb', 'pi', 'ei')


def reward_statistics(means: np.ndarray, covs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mu_r, sigma_r) per cell: Eq. 3.38 and the square root of Eqs. 3.39-3.40."""
    norm = np.linalg.norm(means, axis=1)
    jac = -means / np.maximum(norm, 1e-12)[:, None]
    var = np.einsum('na,nab,nb->n', jac, covs, jac)
    return -norm, np.sqrt(np.maximum(var, 0.0))


def acquisition_scores(mu_r: np.ndarray, sigma_r: np.ndarray, kind: str = 'ucb',
                       alpha: float = 1.0, best: float | None = None,
                       xi: float = 0.0) -> np.ndarray:
    """Score per cell for `kind` in ('ucb', 'pi', 'ei'); higher is better (Eqs. 3.41-3.43)."""
    if kind == 'ucb':
        if not alpha >= 0:
            raise ValueError(f'UCB alpha must be >= 0 (or inf), got {alpha}')
        if np.isinf(alpha):
            return sigma_r.copy()
        return mu_r + alpha * sigma_r
    if kind not in ('pi', 'ei'):
        raise ValueError(f'unknown acquisition {kind!r}; use one of {ACQUISITIONS}')
    r_star = float(np.max(mu_r)) if best is None else float(best)
    gain = mu_r - r_star - xi
    s = np.maximum(sigma_r, 1e-300)
    u = gain / s
    if kind == 'pi':
        return ndtr(u)
    return gain * ndtr(u) + sigma_r * _INV_SQRT_2PI * np.exp(-0.5 * u * u)


def reachable_cells(directions: np.ndarray, azimuth_limit: float,
                    elevation_limits: tuple[float, float]) -> np.ndarray:
    """Cells the head can fixate (the kinematic constraints of Fig. 3.10), (N,) bool.

    directions: (N, 3) unit vectors in the ego frame (x forward, y left, z up); a cell is
    reachable when |azimuth| <= azimuth_limit and elevation lies in elevation_limits [rad].
    """
    d = np.asarray(directions, np.float64)
    az = np.arctan2(d[:, 1], d[:, 0])
    el = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))
    return (np.abs(az) <= azimuth_limit) & (el >= elevation_limits[0]) & (el <= elevation_limits[1])


@dataclass(frozen=True)
class Decision:
    """The chosen cell, its fixation point (ego frame) and its score."""

    cell: int
    fixation: np.ndarray
    score: float


def choose_fixation(means: np.ndarray, covs: np.ndarray, kind: str = 'ucb', alpha: float = 1.0,
                    best: float | None = None, xi: float = 0.0,
                    candidates: np.ndarray | None = None) -> Decision:
    """Pick the next fixation among the cells (or the boolean/int subset `candidates`).

    The fixation point is the chosen cell's mean in the ego frame; the node turns it into a
    GazeCommand (with forward kinematics handled by the gaze controller).
    """
    means = np.asarray(means, np.float64)
    covs = np.asarray(covs, np.float64)
    if means.ndim != 2 or means.shape[1] != 3 or covs.shape != (means.shape[0], 3, 3):
        raise ValueError(f'choose_fixation: means (N, 3) and covs (N, 3, 3) expected, got '
                         f'{means.shape} and {covs.shape}')
    idx = np.arange(means.shape[0]) if candidates is None else np.asarray(candidates)
    if idx.dtype == bool:
        idx = np.nonzero(idx)[0]
    if idx.size == 0:
        raise ValueError('choose_fixation: no candidate cells')
    mu_r, sigma_r = reward_statistics(means[idx], covs[idx])
    score = acquisition_scores(mu_r, sigma_r, kind, alpha, best, xi)
    score = np.where(np.isfinite(score), score, -np.inf)
    k = int(np.argmax(score))
    return Decision(int(idx[k]), means[idx[k]].copy(), float(score[k]))
