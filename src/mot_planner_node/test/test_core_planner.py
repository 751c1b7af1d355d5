"""MCTS planner: belief tables, obvious choices with a fixed seed and iteration cap."""

import numpy as np
import pytest

from mot_planner_node.core.kalman import MotionModel
from mot_planner_node.core.observation import DetectorGeometry, ObservationModel
from mot_planner_node.core.planner import MctsPlanner, PlannerConfig, belief_tables

SIZE = (640, 480)
OBS = ObservationModel(DetectorGeometry())


def beliefs(stds, scales=None, us=None):
    """Targets side by side with the given centre stds (pixels)."""
    K = len(stds)
    x = np.zeros((K, 6))
    x[:, 0] = us if us is not None else np.linspace(80, 560, K)
    x[:, 1] = 240.0
    x[:, 2] = scales if scales is not None else 1.2
    P = np.zeros((K, 6, 6))
    P[:, 0, 0] = P[:, 1, 1] = np.asarray(stds, float) ** 2
    P[:, 2, 2] = 0.01
    P[:, [3, 4, 5], [3, 4, 5]] = [1.0, 1.0, 0.0001]
    return x, P


def planner(**kw) -> MctsPlanner:
    cfg = dict(budget_ms=None, max_iterations=300, seed=7)
    cfg.update(kw)
    return MctsPlanner(PlannerConfig(**cfg), MotionModel(), OBS)


def test_tables() -> None:
    x, P = beliefs([20.0, 2.0])
    cfg = PlannerConfig(depth=3, s_max=1.0)
    t = belief_tables(x, P, np.array([0, 1]), MotionModel(), OBS, cfg, SIZE)
    assert t.gain.shape == (2, 3, 8) and t.area.shape == (2, 3, 4)
    np.testing.assert_allclose(t.gain[:, :, 0], 0.0)            # never updated: no gain
    assert np.all(t.gain[:, 0, 1] > 0)                          # updated now: gain
    assert t.gain[0, 0, 1] > t.gain[1, 0, 1]                    # more to gain where uncertain
    # Never-updated regions grow; an update now shrinks the next region.
    assert t.area[0, 2, 0] > t.area[0, 1, 0] > t.area[0, 0, 0]
    assert t.area[0, 1, 1] < t.area[0, 1, 0]
    assert np.all(np.diff(t.entropy[0, :, 0]) > 0)
    # Updating at every step gains the most at the end of the horizon.
    assert t.gain[0, 2, 7] == t.gain[0, 2, :8].max()


def test_picks_the_uncertain_target() -> None:
    x, P = beliefs([2.0, 40.0, 2.0])
    plan = planner(k_max=1, s_max=1.0).plan(x, P, SIZE)
    assert plan.action.tolist() == [False, True, False]
    assert plan.iterations == 300
    assert plan.expected_return > 0


def test_picks_the_two_uncertain_targets() -> None:
    x, P = beliefs([1.5, 30.0, 2.0, 45.0, 1.0])
    plan = planner(k_max=2, s_max=1.0).plan(x, P, SIZE)
    assert np.flatnonzero(plan.action).tolist() == [1, 3]


def test_area_budget_rules_out_the_big_region() -> None:
    # Target 0 is the most uncertain, but its region alone is over S_max.
    x, P = beliefs([80.0, 15.0, 1.0])
    p = planner(k_max=1, s_max=0.05, area='centres')
    plan = p.plan(x, P, SIZE)
    assert plan.areas[0] > 0.05 * 640 * 480 >= plan.areas[1]
    assert plan.action.tolist() == [False, True, False]


def test_same_seed_same_plan() -> None:
    rng = np.random.default_rng(3)
    x, P = beliefs(rng.uniform(2, 30, 9), us=rng.uniform(50, 590, 9))
    a = planner(k_max=3, s_max=0.2, seed=11).plan(x, P, SIZE)
    b = planner(k_max=3, s_max=0.2, seed=11).plan(x, P, SIZE)
    assert a.action.tolist() == b.action.tolist()
    assert a.expected_return == b.expected_return and a.iterations == b.iterations


def test_trivial_cases_need_no_search() -> None:
    x, P = beliefs([10.0, 12.0])
    plan = planner(k_max=3, s_max=1.0).plan(x, P, SIZE)
    assert plan.action.all() and plan.iterations == 0
    empty = planner().plan(np.zeros((0, 6)), np.zeros((0, 6, 6)), SIZE)
    assert empty.action.shape == (0,) and empty.regions.shape == (0, 6)
    # Nothing fits: nothing attended.
    x, P = beliefs([200.0])
    none = planner(s_max=0.01).plan(x, P, SIZE)
    assert not none.action.any()


def test_time_budget_alone_stops_the_search() -> None:
    x, P = beliefs([5.0, 25.0, 8.0, 30.0, 3.0])
    plan = planner(k_max=1, s_max=1.0, budget_ms=5.0, max_iterations=None).plan(x, P, SIZE)
    # one of the two uncertain targets (how many runs fit in 5 ms depends on the machine;
    # with none, the greedy choice, 3)
    assert plan.action.sum() == 1 and int(np.flatnonzero(plan.action)[0]) in (1, 3)


def test_no_time_left_takes_the_greedy_action() -> None:
    """The budget is spent before the first run: no search, the best immediate gain."""
    x, P = beliefs([5.0, 25.0, 8.0, 30.0, 3.0])
    plan = planner(k_max=2, s_max=1.0, budget_ms=1e-6, max_iterations=None).plan(x, P, SIZE)
    assert plan.iterations == 0 and plan.expected_return == 0.0
    assert plan.action.tolist() == [False, True, False, True, False]


def test_reserve_tracks_the_miss_rate() -> None:
    """Late plans push the search's stop earlier (at most half the budget); plans in time
    let it decay; at the target miss rate (5 %: one late plan in 20) it stays put."""
    p = planner(budget_ms=10.0, max_iterations=None)
    for _ in range(100):
        p._adapt_reserve(0.020)
    assert p.reserve_s == pytest.approx(0.005)
    before = p.reserve_s = 0.002
    for k in range(40):
        p._adapt_reserve(0.011 if k % 20 == 0 else 0.009)
    assert p.reserve_s == pytest.approx(before)
    for _ in range(1000):
        p._adapt_reserve(0.009)
    assert p.reserve_s == 0.0
    fixed = planner(budget_ms=10.0, max_iterations=None, miss_rate=None)
    fixed._adapt_reserve(0.020)
    assert fixed.reserve_s == 0.0


@pytest.mark.parametrize('kw,match', [
    (dict(k_max=0), 'k_max'), (dict(s_max=0.0), 's_max'), (dict(gamma=0.0), 'gamma'),
    (dict(depth=0), 'depth'), (dict(budget_ms=None, max_iterations=None), 'budget_ms'),
    (dict(area='nope'), 'area'), (dict(p_detect=0.0), 'p_detect'),
    (dict(miss_rate=1.0), 'miss_rate')])
def test_bad_config(kw, match) -> None:
    with pytest.raises(ValueError, match=match):
        PlannerConfig(**kw)
