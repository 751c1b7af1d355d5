"""Search regions (Eqs. 5.16-5.19) and the K_max / S_max bookkeeping."""

import numpy as np
import pytest

from mot_planner_node.core.kalman import MotionModel
from mot_planner_node.core.observation import DetectorGeometry, ObservationModel
from mot_planner_node.core.planner import MctsPlanner, PlannerConfig
from mot_planner_node.core.regions import (
    centre_areas,
    check_action,
    constraint_areas,
    full_frame_region,
    is_feasible,
    region_areas,
    search_regions,
)

G = DetectorGeometry()          # HOG: 64x128, stride 8, step 1.05
SIZE = (640, 480)


def belief(u, v, s, var_c, var_s):
    x = np.array([[u, v, s, 0.0, 0.0, 0.0]])
    P = np.diag([var_c, var_c, var_s, 1.0, 1.0, 0.01])[None]
    return x, P


def test_region_by_hand() -> None:
    # sigma_c = 10, sigma_s = 0.2, alpha_c = 1, alpha_s = 0.5 -> scales [1.9, 2.1];
    # centres [310, 330] x [230, 250]; grown by half the largest window (2.1 * 64 / 2 = 67.2,
    # 2.1 * 128 / 2 = 134.4).
    x, P = belief(320, 240, 2.0, 100.0, 0.04)
    r = search_regions(x, P, G, 1.0, 0.5, SIZE)[0]
    np.testing.assert_allclose(r, [310 - 67.2, 240 - 10 - 134.4, 330 + 67.2, 250 + 134.4, 1.9, 2.1])
    assert region_areas(r[None])[0] == pytest.approx((20 + 134.4) * (20 + 268.8))
    assert centre_areas(x, P, 1.0, SIZE)[0] == pytest.approx(400.0)
    assert constraint_areas(x, P, r[None], 'centres', 1.0, SIZE)[0] == pytest.approx(400.0)
    # 'pixels' charges the integer crop the detector reads: x 242..398, y 95..385.
    assert constraint_areas(x, P, r[None], 'pixels', 1.0, SIZE)[0] == 156 * 290
    # 'scaled': that crop shrunk by its smallest scale, s_lo = 1.9.
    assert constraint_areas(x, P, r[None], 'scaled', 1.0, SIZE)[0] == pytest.approx(
        156 * 290 / 1.9 ** 2)
    with pytest.raises(ValueError, match='area mode'):
        constraint_areas(x, P, r[None], 'other', 1.0, SIZE)


def test_regions_are_clipped_and_scales_floored() -> None:
    x, P = belief(5.0, 470.0, 1.0, 400.0, 1.0)
    r = search_regions(x, P, G, 2.0, 2.0, SIZE)[0]
    assert r[0] == 0.0 and r[3] == 480.0
    assert r[4] == 1.0                                  # never below the smallest window
    assert r[5] == pytest.approx(3.0)
    # Centre box [-35, 45] x [430, 510] clipped: 45 x 50.
    assert centre_areas(x, P, 2.0, SIZE)[0] == pytest.approx(45 * 50)
    full = full_frame_region(SIZE, G)
    assert region_areas(full)[0] == 640 * 480


def test_constraints() -> None:
    areas = np.array([100.0, 200.0, 300.0])
    assert is_feasible([True, True, False], areas, 2, 0.5, 600.0)
    assert not is_feasible([True, True, True], areas, 2, 1.0, 600.0)
    assert not is_feasible([False, True, True], areas, 2, 0.5, 600.0)
    with pytest.raises(ValueError, match='K_max'):
        check_action([True, True, True], areas, 2, 1.0, 600.0)
    with pytest.raises(ValueError, match='S_max'):
        check_action([False, True, True], areas, 3, 0.5, 600.0)
    check_action([False, False, False], areas, 1, 0.01, 600.0)


@pytest.mark.parametrize('area', ['centres', 'pixels'])
@pytest.mark.parametrize('k_max,s_max', [(1, 0.1), (2, 0.05), (3, 0.1), (4, 0.3)])
def test_planner_never_exceeds_k_max_or_s_max(area: str, k_max: int, s_max: float) -> None:
    rng = np.random.default_rng(k_max)
    cfg = PlannerConfig(k_max=k_max, s_max=s_max, area=area, budget_ms=None, max_iterations=60,
                        seed=1)
    planner = MctsPlanner(cfg, MotionModel(), ObservationModel(G))
    for _trial in range(15):
        K = int(rng.integers(0, 14))
        x = np.zeros((K, 6))
        x[:, 0] = rng.uniform(0, 640, K)
        x[:, 1] = rng.uniform(0, 480, K)
        x[:, 2] = rng.uniform(1.0, 1.8, K)
        P = np.zeros((K, 6, 6))
        P[:, [0, 1], [0, 1]] = rng.uniform(1, 60, (K, 1)) ** 2
        P[:, 2, 2] = rng.uniform(0.001, 0.05, K)
        P[:, [3, 4, 5], [3, 4, 5]] = [1.0, 1.0, 0.001]
        plan = planner.plan(x, P, SIZE)
        assert plan.action.shape == (K,)
        assert plan.action.sum() <= k_max
        assert plan.areas[plan.action].sum() <= s_max * 640 * 480 * (1 + 1e-9)
        check_action(plan.action, plan.areas, k_max, s_max, 640 * 480)
        # Maximal: no unattended region would still fit (the pool holds all K <= pool_size).
        if 0 < K <= cfg.pool_size and plan.action.sum() < k_max:
            slack = s_max * 640 * 480 - plan.areas[plan.action].sum()
            assert not np.any(~plan.action & (plan.areas <= slack))
