"""Information measures and the visual-search metrics of thesis section 3.4 (Eqs. 3.45-3.56).

- `information`: pointwise information I(Sigma) = -log |Sigma| (Eq. 3.45), the log-determinant
  of the precision matrix; `average_information` is TI (Eq. 3.46) over the points of one frame,
  or GI_t (Eq. 3.53) over the N_x cells of the ego-sphere.
- `SearchMetrics` accumulates, per saccade t, the reward of the fixated cell and gives the gap
  reduction g_t (Eq. 3.47, with the best reward so far, Eq. 3.49, against the true optimum,
  Eq. 3.48), the cumulative regret R_t (Eq. 3.51) and their per-saccade averages G/S (Eq. 3.50)
  and R/S (Eq. 3.52); GI/S and LI/S (Eqs. 3.54, 3.56) are the same averages of GI_t and LI_t.
- `local_information`: LI_t (Eq. 3.55), the information of the cells whose means lie within
  R_NN = 0.1 m of the target point (averaged when several do; see its docstring otherwise).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .linalg3 import det_inv3


def information(covs: np.ndarray) -> np.ndarray:
    """I(Sigma) = -log|Sigma| (Eq. 3.45) of (N, 3, 3) covariances; NaN where |Sigma| <= 0."""
    det = det_inv3(np.asarray(covs, np.float64))[0]
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(det > 0, -np.log(np.where(det > 0, det, 1.0)), np.nan)


def information_from_precision(info: np.ndarray) -> np.ndarray:
    """I = log|Lambda| from (N, 3, 3) precision matrices (the same as Eq. 3.45, no inverse)."""
    det = det_inv3(np.asarray(info, np.float64))[0]
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(det > 0, np.log(np.where(det > 0, det, 1.0)), np.nan)


def average_information(covs: np.ndarray) -> float:
    """TI (Eq. 3.46) / GI_t (Eq. 3.53): the mean of I over the finite rows; NaN if none."""
    i = information(covs)
    i = i[np.isfinite(i)]
    return float(i.mean()) if i.size else float('nan')


def local_information(means: np.ndarray, covs: np.ndarray, target: np.ndarray,
                      radius: float = 0.1, fallback: int | None = None) -> float:
    """LI_t (Eq. 3.55): mean I of the cells within `radius` (R_NN) of the target.

    When no cell mean is that close (the target not reconstructed yet), the information of cell
    `fallback` (e.g. the cell of the target's direction, still at its prior) or NaN.
    """
    near = np.linalg.norm(np.asarray(means) - np.asarray(target)[None], axis=1) < radius
    if not np.any(near):
        if fallback is None:
            return float('nan')
        near = np.zeros(len(near), bool)
        near[fallback] = True
    i = information(np.asarray(covs)[near])
    i = i[np.isfinite(i)]
    return float(i.mean()) if i.size else float('nan')


@dataclass
class SearchMetrics:
    """Per-saccade rewards of a search run and the metrics of Eqs. 3.47-3.52, 3.54, 3.56.

    `optimum` is mu_r(x*) (Eq. 3.48), the best reward available (e.g. minus the true distance of
    the nearest object). `add(reward, gi, li)` records saccade t's reward mu_r(x_t^{a_t}) with
    GI_t and LI_t.
    """

    optimum: float
    rewards: list[float] = field(default_factory=list)
    gi: list[float] = field(default_factory=list)
    li: list[float] = field(default_factory=list)

    def add(self, reward: float, gi: float = float('nan'), li: float = float('nan')) -> None:
        self.rewards.append(float(reward))
        self.gi.append(float(gi))
        self.li.append(float(li))

    def gap(self) -> np.ndarray:
        """g_t (Eq. 3.47) for t = 1..T: 0 no better than the first fixation, 1 the optimum."""
        r = np.asarray(self.rewards)
        best = np.maximum.accumulate(r)                                # Eq. 3.49
        den = self.optimum - r[0]
        if abs(den) < 1e-12:                                           # started on the optimum
            return np.ones_like(r)
        return (best - r[0]) / den

    def regret(self) -> np.ndarray:
        """R_t (Eq. 3.51): optimum minus the mean reward of the first t fixations."""
        r = np.asarray(self.rewards)
        return self.optimum - np.cumsum(r) / np.arange(1, r.size + 1)

    def summary(self) -> dict[str, float]:
        """G/S, R/S, GI/S, LI/S (Eqs. 3.50, 3.52, 3.54, 3.56); NaN entries of LI are skipped."""
        li = np.asarray(self.li)
        return {'G/S': float(np.mean(self.gap())), 'R/S': float(np.mean(self.regret())),
                'GI/S': float(np.nanmean(self.gi)) if np.any(np.isfinite(self.gi)) else
                float('nan'),
                'LI/S': float(np.nanmean(li)) if np.any(np.isfinite(li)) else float('nan')}
