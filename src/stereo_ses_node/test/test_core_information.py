"""Information (Eqs. 3.45-3.46, 3.53, 3.55) and the search metrics (Eqs. 3.47-3.52)."""

import math

import numpy as np
import pytest

from stereo_ses_node.core.information import (
    SearchMetrics,
    average_information,
    information,
    information_from_precision,
    local_information,
)


def test_information_is_minus_log_det():
    covs = np.stack([np.diag([0.01, 0.04, 0.25]), 100.0 * np.eye(3), np.zeros((3, 3))])
    i = information(covs)
    assert i[0] == pytest.approx(-math.log(0.01 * 0.04 * 0.25))
    assert i[1] == pytest.approx(-math.log(1e6))             # a prior cell: -13.8
    assert np.isnan(i[2])                                     # singular: no information
    assert np.allclose(information_from_precision(np.linalg.inv(covs[:2])), i[:2])
    # shrinking a covariance k times in every direction adds 3 log k
    assert information(covs[:1] / 4.0)[0] == pytest.approx(i[0] + 3 * math.log(4.0))
    assert average_information(covs) == pytest.approx(np.mean(i[:2]))     # NaN rows skipped


def test_local_information_near_the_target_or_fallback():
    means = np.array([[1.0, 0.0, 0.0], [1.05, 0.0, 0.0], [0.0, 3.0, 0.0]])
    covs = np.stack([0.01 * np.eye(3), 0.04 * np.eye(3), np.eye(3)])
    li = local_information(means, covs, np.array([1.02, 0.0, 0.0]), radius=0.1)
    assert li == pytest.approx(np.mean(information(covs[:2])))
    far = np.array([5.0, 5.0, 5.0])
    assert math.isnan(local_information(means, covs, far))
    assert local_information(means, covs, far, fallback=2) == pytest.approx(0.0)


def test_gap_and_regret_follow_the_definitions():
    m = SearchMetrics(optimum=-0.5)
    for r in (-3.0, -2.0, -4.0, -0.5, -1.0):
        m.add(r, gi=1.0, li=float('nan'))
    # g_t = (best so far - r_1) / (r* - r_1), r_1 = -3, r* = -0.5
    assert np.allclose(m.gap(), [0.0, 0.4, 0.4, 1.0, 1.0])
    # R_t = r* - mean of the first t rewards
    assert np.allclose(m.regret(), [2.5, 2.0, 2.5, 1.875, 1.6])
    s = m.summary()
    assert s['G/S'] == pytest.approx(0.56) and s['R/S'] == pytest.approx(np.mean(m.regret()))
    assert s['GI/S'] == 1.0 and math.isnan(s['LI/S'])
    start = SearchMetrics(optimum=-1.0)
    start.add(-1.0)
    assert start.gap()[0] == 1.0                              # started on the optimum
