"""Resource-constrained attention planning by Monte Carlo Tree Search (sections 5.3.3-5.3.5).

The POMDP (Eq. 5.23's problem): each frame choose a binary activation a^k per search region
(Eq. 5.20), at most K_max of them and at most S_max of the image area, to maximize the
discounted sum over a horizon T of the belief-dependent reward ``-log |Sigma^k|`` (Eq. 5.24)
summed over targets. An attended region updates its belief with the observation model's
expected noise (Eqs. 5.21-5.22); an unattended one only predicts.

Why the search is cheap: with independent linear-Gaussian targets the covariance after t
steps depends only on *which* of those steps updated it, not on the observed values, so the
planner precomputes, per target, depth and update history (2^d codes at depth d), the
predicted region area, the predicted entropy and the posterior log-determinant
(:func:`belief_tables`, vectorized over targets and histories). The tree then works on
integer history codes and table look-ups. The observation outcome that stays random is
whether the detector finds an attended target (probability ``p_detect``): a miss leaves the
belief at its prediction.

Rewards are reported as information gain ``log|Sigma_pred only| - log|Sigma|`` per target:
``-log|Sigma|`` plus a constant that does not depend on the action (so the same argmax),
on a scale UCT's exploration constant can be set for. MCTS (section 5.3.5): UCT selection
(Eq. 5.25) with progressive widening over actions ordered by their immediate expected gain,
expansion of one node per run, rollouts that sample regions with probability rising with
their predicted entropy (``exp(H / temperature)``), back-propagation of discounted returns;
runs until the time budget (a wall-clock deadline with an adaptive reserve) or the iteration
cap. Only maximal feasible actions are considered: attending never increases a covariance,
so an action that could still take one more region is dominated by the one that takes it.
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from .kalman import MotionModel, logdet_sigma, update_covariance
from .observation import DetectorGeometry, ObservationModel
from .regions import (
    AREA_MODES,
    READ_MODES,
    centre_areas,
    constraint_areas,
    read_areas,
    search_regions,
)

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

RECENT_RUNS = 8       # MCTS runs whose slowest estimates the next one's cost (deadline)
RESERVE_STEP = 0.05   # reserve adaptation step, fraction of the budget
MAX_RESERVE = 0.5     # the reserve leaves at least half the budget to the search


@dataclass(frozen=True)
class PlannerConfig:
    """Parameters of the planner (thesis values as defaults where it gives them).

    k_max, s_max: the constraints of section 5.3.4 (regions, fraction of the image area).
    area: what a region's area is, 'pixels' or 'centres' (:data:`.regions.AREA_MODES`).
    alpha_c, alpha_s: search-region widths of Eqs. 5.18-5.19 (thesis: 1, 1).
    depth, gamma: planning horizon T and discount (thesis: 3, 0.9).
    budget_ms: wall-clock budget per plan (thesis: 10 ms); None = iterations only.
    max_iterations: cap on MCTS runs (None = budget only); set with seed for determinism.
    exploration: c of Eq. 5.25, on returns normalized by their upper bound.
    p_detect: probability the detector finds an attended target (the random outcome).
    pool_size: the planner considers the pool_size highest-entropy attendable targets.
    widening, widening_exp: progressive widening, a node tries at most
        ceil(widening * visits^widening_exp) actions.
    rollout_temperature: rollout picks region k with probability ~ exp(H_k / temperature).
    expectation_points: scales sampled per region for Eq. 5.22.
    miss_rate: the share of plans allowed to end past budget_ms; a reserve before the budget
        adapts to it (None: no reserve, the search runs up to the budget).
    seed: random seed of the planner's generator.
    """

    k_max: int = 3
    s_max: float = 0.1
    area: str = 'centres'
    alpha_c: float = 1.0
    alpha_s: float = 1.0
    depth: int = 3
    gamma: float = 0.9
    budget_ms: float | None = 10.0
    max_iterations: int | None = None
    exploration: float = 0.5
    p_detect: float = 0.9
    pool_size: int = 10
    widening: float = 2.0
    widening_exp: float = 0.5
    rollout_temperature: float = 1.0
    expectation_points: int = 5
    miss_rate: float | None = 0.05
    seed: int | None = None

    def __post_init__(self) -> None:
        problems = []
        if self.k_max < 1:
            problems.append(f'k_max must be >= 1, got {self.k_max}')
        if not 0.0 < self.s_max <= 1.0:
            problems.append(f's_max must be in (0, 1], got {self.s_max}')
        if self.area not in AREA_MODES:
            problems.append(f'area must be one of {AREA_MODES}, got {self.area!r}')
        if self.alpha_c < 0 or self.alpha_s < 0:
            problems.append(f'alpha_c, alpha_s must be >= 0, got {self.alpha_c}, {self.alpha_s}')
        if not 1 <= self.depth <= 8:
            problems.append(f'depth must be in [1, 8], got {self.depth}')
        if not 0.0 < self.gamma <= 1.0:
            problems.append(f'gamma must be in (0, 1], got {self.gamma}')
        if self.budget_ms is not None and not self.budget_ms > 0:
            problems.append(f'budget_ms must be > 0 or None, got {self.budget_ms}')
        if self.max_iterations is not None and self.max_iterations < 1:
            problems.append(f'max_iterations must be >= 1 or None, got {self.max_iterations}')
        if self.budget_ms is None and self.max_iterations is None:
            problems.append('give budget_ms or max_iterations (or both)')
        if not 0.0 < self.p_detect <= 1.0:
            problems.append(f'p_detect must be in (0, 1], got {self.p_detect}')
        if not 1 <= self.pool_size <= 20:
            problems.append(f'pool_size must be in [1, 20], got {self.pool_size}')
        if self.miss_rate is not None and not 0.0 < self.miss_rate < 1.0:
            problems.append(f'miss_rate must be in (0, 1) or None, got {self.miss_rate}')
        if self.rollout_temperature <= 0:
            problems.append(f'rollout_temperature must be > 0, got {self.rollout_temperature}')
        if problems:
            raise ValueError('PlannerConfig: ' + '; '.join(problems))


@dataclass
class BeliefTables:
    """Per-target look-up tables over the horizon (index d = 0 is the current frame).

    pool: (M,) indices of the targets the tables describe.
    area: (M, D, 2^(D-1)) region area |u| at depth d for the history code before d.
    entropy: (M, D, 2^(D-1)) ``0.5 log|Sigma|`` of the predicted belief (entropy up to a constant).
    gain: (M, D, 2^D) information gain after depth d for the history code including d
        (code = 2 * previous code + 1 if updated at d).
    """

    pool: IntArray
    area: FloatArray
    entropy: FloatArray
    gain: FloatArray


def belief_tables(x: FloatArray, P: FloatArray, pool: IntArray, motion: MotionModel,
                  observation: ObservationModel, cfg: PlannerConfig,
                  image_size: tuple[int, int],
                  shrink: FloatArray | None = None) -> BeliefTables:
    """Roll the predicted beliefs (x, P at the current frame) of the pool targets over the
    horizon for every update history (Eqs. 5.3, 5.18-5.22, 5.24), vectorized. shrink (M,):
    per pool target, the factor on alpha_c, alpha_s its regions are read with (1: as
    configured; see :meth:`MctsPlanner.fit_regions`)."""
    M, D = len(pool), cfg.depth
    geometry = observation.geometry
    area = np.zeros((M, D, 2 ** (D - 1)))
    entropy = np.zeros((M, D, 2 ** (D - 1)))
    gain = np.zeros((M, D, 2 ** D))
    f = motion.F
    xbar = x[pool]
    p_post = P[pool][:, None]                                    # (M, 1, 6, 6)
    for d in range(D):
        n = 2 ** d
        if d == 0:
            p_bar = p_post
        else:
            xbar = xbar @ f.T
            p_bar = f @ p_post @ f.T + motion.Q(xbar[:, 2])[:, None]
        k = np.ones((M, 1)) if shrink is None else np.asarray(shrink, float).reshape(M, 1)
        if cfg.area == 'centres':
            area[:, d, :n] = centre_areas(xbar[:, None, :], p_bar, cfg.alpha_c, image_size)
        else:
            regions = search_regions(xbar[:, None, :], p_bar, geometry, cfg.alpha_c * k,
                                     cfg.alpha_s * k, image_size)
            area[:, d, :n] = read_areas(regions, cfg.area, image_size,
                                        observation.geometry.upsample)
        entropy[:, d, :n] = 0.5 * logdet_sigma(p_bar)
        s_mean = np.broadcast_to(xbar[:, None, 2], (M, n))
        r_eff = observation.expected_covariance(s_mean, np.sqrt(np.maximum(p_bar[..., 2, 2], 0)),
                                                cfg.alpha_s, cfg.expectation_points)
        p_upd = update_covariance(p_bar, r_eff)
        p_post = np.stack([p_bar, p_upd], axis=2).reshape(M, 2 * n, 6, 6)
        ld = logdet_sigma(p_post)
        gain[:, d, :2 * n] = ld[:, :1] - ld
    return BeliefTables(pool=pool, area=area, entropy=entropy, gain=gain)


@dataclass
class Plan:
    """The planner's choice for the current frame.

    action: (K,) binary activation per target (Eq. 5.20).
    regions: (K, 6) every target's search region now (Eqs. 5.18-5.19).
    areas: (K,) their areas as the S_max constraint counts them (PlannerConfig.area).
    iterations: MCTS runs made; plan_s: wall time of plan(); expected_return: the chosen
    action's mean simulated return (information gain, discounted).
    """

    action: BoolArray
    regions: FloatArray
    areas: FloatArray
    iterations: int = 0
    plan_s: float = 0.0
    expected_return: float = 0.0


@dataclass
class _Node:
    depth: int
    codes: IntArray
    visits: int = 0
    order: IntArray = field(default_factory=lambda: np.zeros(0, np.int64))
    n_a: FloatArray = field(default_factory=lambda: np.zeros(0))
    w_a: FloatArray = field(default_factory=lambda: np.zeros(0))
    expanded: int = 0
    children: dict[tuple[int, int], _Node] = field(default_factory=dict)


class MctsPlanner:
    """Online MCTS/UCT solver of the resource-constrained POMDP (sections 5.3.4-5.3.5)."""

    def __init__(self, cfg: PlannerConfig, motion: MotionModel,
                 observation: ObservationModel) -> None:
        self.cfg = cfg
        self.motion = motion
        self.observation = observation
        self.rng = np.random.default_rng(cfg.seed)
        self._subsets_cache: dict[tuple[int, int], BoolArray] = {}
        self.reserve_s = 0.0      # the search stops this long before the budget (load)

    @property
    def geometry(self) -> DetectorGeometry:
        return self.observation.geometry

    def regions(self, x: FloatArray, P: FloatArray, image_size: tuple[int, int]) -> FloatArray:
        """Search regions (K, 6) of the current beliefs (Eqs. 5.18-5.19)."""
        return search_regions(x, P, self.geometry, self.cfg.alpha_c, self.cfg.alpha_s,
                              image_size)

    def reset(self) -> None:
        """Back to the state after construction (the seed's generator, no reserve)."""
        self.rng = np.random.default_rng(self.cfg.seed)
        self.reserve_s = 0.0

    def fit_regions(self, x: FloatArray, P: FloatArray, image_size: tuple[int, int],
                    budget: float, steps: int = 12) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Regions that fit the budget on their own, for the read modes of the constraint.

        A region whose read area exceeds ``budget`` is narrowed: alpha_c and alpha_s are
        scaled by the largest factor k in [0, 1] that fits (bisection, vectorized over targets),
        down to the bare detector window at the predicted centre and scale (k = 0). Returns
        (regions (K, 6), areas (K,), k (K,)); a target whose bare window does not fit keeps
        k = 0 and an area above the budget (it cannot be attended)."""
        cfg, g = self.cfg, self.geometry

        def at(k: FloatArray) -> tuple[FloatArray, FloatArray]:
            r = search_regions(x, P, g, cfg.alpha_c * k, cfg.alpha_s * k, image_size)
            return r, read_areas(r, cfg.area, image_size, self.geometry.upsample)

        K = x.shape[0]
        regions, areas = at(np.ones(K))
        k = np.ones(K)
        over = areas > budget
        if over.any():
            lo, hi = np.zeros(K), np.ones(K)
            for _ in range(steps):
                mid = 0.5 * (lo + hi)
                fits = at(mid)[1] <= budget
                lo, hi = np.where(fits, mid, lo), np.where(fits, hi, mid)
            k = np.where(over, lo, 1.0)
            regions, areas = at(k)
        return regions, areas, k

    def plan(self, x: FloatArray, P: FloatArray, image_size: tuple[int, int],
             budget: float | None = None) -> Plan:
        """Choose the regions to attend now, given the predicted beliefs x (K, 6), P (K, 6, 6)
        of the current frame and the image size (width, height). budget: the area the
        regions may take together (default S_max of the image), as ``cfg.area`` counts it."""
        t0 = time.perf_counter()
        cfg = self.cfg
        K = x.shape[0]
        if budget is None:
            budget = cfg.s_max * float(image_size[0]) * float(image_size[1])
        shrink = np.ones(K)
        if cfg.area in READ_MODES:
            regions, areas, shrink = self.fit_regions(x, P, image_size, budget)
        else:
            regions = self.regions(x, P, image_size)
            areas = constraint_areas(x, P, regions, cfg.area, cfg.alpha_c, image_size,
                                     self.geometry.upsample)
        action = np.zeros(K, dtype=bool)
        attendable = np.flatnonzero(areas <= budget)
        if attendable.size == 0:
            return Plan(action, regions, areas, 0, time.perf_counter() - t0)
        ent = 0.5 * logdet_sigma(P[attendable])
        pool = attendable[np.argsort(-ent, kind='stable')][:cfg.pool_size]
        if pool.size <= cfg.k_max and areas[pool].sum() <= budget:
            action[pool] = True                  # the only maximal feasible action
            return Plan(action, regions, areas, 0, time.perf_counter() - t0)
        tables = belief_tables(x, P, pool, self.motion, self.observation, cfg, image_size,
                               shrink[pool])
        if cfg.area in READ_MODES:
            tables.area[:, 0, 0] = areas[pool]       # now: exactly the fitted regions
        best, iterations, value = self._search(tables, budget, t0)
        action[pool[best]] = True
        plan_s = time.perf_counter() - t0
        self._adapt_reserve(plan_s)
        return Plan(action, regions, areas, iterations, plan_s, value)

    def _adapt_reserve(self, plan_s: float) -> None:
        """Track the reserve that makes plans miss the budget at rate cfg.miss_rate.

        A Robbins-Monro quantile tracker: each searched plan moves the reserve up by
        step (1 - q) when it ended late and down by step q when it did not, which balances at
        P(late) = q. On an idle machine plans end in time and the reserve decays to zero; when
        the OS preempts the planner (load) it grows to about the preemptions' length."""
        cfg = self.cfg
        if cfg.budget_ms is None or cfg.miss_rate is None:
            return
        budget_s = cfg.budget_ms / 1000.0
        late = plan_s > budget_s
        self.reserve_s += RESERVE_STEP * budget_s * (float(late) - cfg.miss_rate)
        self.reserve_s = min(max(self.reserve_s, 0.0), MAX_RESERVE * budget_s)

    # --- MCTS -----------------------------------------------------------------------------

    def _subsets(self, m: int) -> BoolArray:
        """All subsets of m pool members with at most k_max elements (C, m), the empty one first."""
        key = (m, self.cfg.k_max)
        if key not in self._subsets_cache:
            rows = [np.zeros(m, dtype=bool)]
            for size in range(1, min(self.cfg.k_max, m) + 1):
                for combo in combinations(range(m), size):
                    row = np.zeros(m, dtype=bool)
                    row[list(combo)] = True
                    rows.append(row)
            self._subsets_cache[key] = np.array(rows)
        return self._subsets_cache[key]

    def _search(self, tables: BeliefTables, budget: float,
                t0: float) -> tuple[BoolArray, int, float]:
        cfg = self.cfg
        M, D = len(tables.pool), cfg.depth
        subsets = self._subsets(M)
        subsets_f = subsets.astype(float)
        sizes = subsets.sum(axis=1)
        idx_m = np.arange(M)
        pow2 = (1 << np.arange(M)).astype(np.int64)
        gammas = cfg.gamma ** np.arange(1, D + 1)
        # Upper bound of a return: every step, the k_max best updates (for UCT's scale).
        best_gain = np.sort(tables.gain[:, :, 1::2].max(axis=2), axis=0)[::-1][:cfg.k_max]
        scale = max(float((best_gain.sum(axis=0) * gammas).sum()), 1e-9)
        rng = self.rng
        deadline = (None if cfg.budget_ms is None
                    else t0 + cfg.budget_ms / 1000.0 - self.reserve_s)
        t_init = time.perf_counter()
        max_iter = cfg.max_iterations if cfg.max_iterations is not None else 1 << 62

        def init_node(node: _Node) -> None:
            d, codes = node.depth, node.codes
            a_area = tables.area[idx_m, d, codes]
            sub_area = subsets_f @ a_area
            slack = budget - sub_area
            feasible = slack >= -1e-9 * budget
            addable = ((~subsets) & (a_area[None, :] <= slack[:, None] + 1e-9 * budget)).any(1)
            maximal = feasible & ((sizes >= cfg.k_max) | ~addable)
            cand = np.flatnonzero(maximal)
            g1 = (tables.gain[idx_m, d, 2 * codes + 1] - tables.gain[idx_m, d, 2 * codes])
            prior = subsets_f[cand] @ g1
            node.order = cand[np.argsort(-prior, kind='stable')]
            node.n_a = np.zeros(len(cand))
            node.w_a = np.zeros(len(cand))

        def step(d: int, codes: IntArray, chosen: BoolArray) -> tuple[IntArray, float, int]:
            det = chosen & (rng.random(M) < cfg.p_detect)
            nxt = 2 * codes + det
            return nxt, gammas[d] * float(tables.gain[idx_m, d, nxt].sum()), int(pow2[det].sum())

        logw = tables.entropy / cfg.rollout_temperature

        def rollout(d: int, codes: IntArray) -> float:
            # Weighted sampling without replacement among the regions that still fit, by
            # the Gumbel-top-k trick: visit regions in order of log w + Gumbel noise and take
            # each that fits (an item that does not fit never fits later: the slack shrinks).
            total = 0.0
            while d < D:
                a_area = tables.area[idx_m, d, codes].tolist()
                keys = logw[idx_m, d, codes] + rng.gumbel(size=M)
                chosen = np.zeros(M, dtype=bool)
                remaining, count = budget * (1.0 + 1e-9), 0
                for k in np.argsort(-keys).tolist():
                    if a_area[k] <= remaining:
                        chosen[k] = True
                        remaining -= a_area[k]
                        count += 1
                        if count == cfg.k_max:
                            break
                codes, r, _ = step(d, codes, chosen)
                total += r
                d += 1
            return total

        root = _Node(0, np.zeros(M, dtype=np.int64))
        init_node(root)
        iterations = 0
        # Deadline control, checked before every run: stop when the next run is expected to
        # end past the deadline (t0 + budget - reserve: the set-up before the search counts,
        # and the reserve absorbs the OS's preemptions, see _adapt_reserve). A run's
        # cost is estimated by the slowest of the last RECENT_RUNS runs, not their mean: runs
        # that expand a node cost more than the others, and on a loaded machine the OS takes
        # the CPU away for milliseconds; both show up in recent runs first. With no time
        # left after the set-up the search makes no run and the greedy action is taken.
        recent: deque[float] = deque(maxlen=RECENT_RUNS)
        t_prev = time.perf_counter()
        if deadline is not None:
            recent.append(t_prev - t_init)      # first estimate: the root's initialization
        while iterations < max_iter:
            if deadline is not None:
                now = time.perf_counter()
                if iterations:
                    recent.append(now - t_prev)
                t_prev = now
                if now + max(recent) >= deadline:
                    break
            iterations += 1
            node, path, tail = root, [], 0.0
            while True:
                allowed = math.ceil(cfg.widening * max(node.visits, 1) ** cfg.widening_exp)
                if node.expanded < min(allowed, len(node.order)):
                    j = node.expanded
                    node.expanded += 1
                else:
                    n_a = node.n_a[:node.expanded]
                    ucb = (node.w_a[:node.expanded] / (n_a * scale)
                           + cfg.exploration * np.sqrt(math.log(max(node.visits, 1)) / n_a))
                    j = int(np.argmax(ucb))
                codes, r, outcome = step(node.depth, node.codes, subsets[node.order[j]])
                path.append((node, j, r))
                if node.depth + 1 >= D:
                    break
                child = node.children.get((j, outcome))
                if child is None:
                    child = _Node(node.depth + 1, codes)
                    init_node(child)
                    node.children[(j, outcome)] = child
                    tail = rollout(node.depth + 1, codes)
                    break
                node = child
            ret = tail
            for node, j, r in reversed(path):
                ret += r
                node.visits += 1
                node.n_a[j] += 1
                node.w_a[j] += ret
        if root.expanded == 0:                  # no run fitted: the best immediate gain
            return subsets[root.order[0]], 0, 0.0
        n_a = root.n_a[:root.expanded]
        mean = root.w_a[:root.expanded] / np.maximum(n_a, 1)
        j = int(np.lexsort((-mean, -n_a))[0])          # most visits, then best mean
        return subsets[root.order[j]], iterations, float(mean[j])
