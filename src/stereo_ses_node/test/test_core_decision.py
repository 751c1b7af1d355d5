"""Decision (Eqs. 3.36-3.43): reward statistics and UCB / PI / EI acquisition."""

import numpy as np
import pytest

from stereo_ses_node.core.decision import (
    acquisition_scores,
    choose_fixation,
    reachable_cells,
    reward_statistics,
)


def cells():
    means = np.array([[1.0, 0, 0], [0, 2.0, 0], [0, 0, 5.0], [3.0, 0, 0]])
    covs = np.stack([np.eye(3) * s for s in (1e-4, 1e-4, 9.0, 0.25)])
    return means, covs


def test_reward_first_order_statistics():
    means, covs = cells()
    covs[1] = np.diag([0.5, 0.04, 7.0])
    mu, sd = reward_statistics(means, covs)
    np.testing.assert_allclose(mu, [-1, -2, -5, -3])                 # Eq. 3.38
    np.testing.assert_allclose(sd ** 2, [1e-4, 0.04, 9.0, 0.25])      # Eqs. 3.39-3.40 (radial)


def test_ucb_alpha_zero_is_greedy_and_large_alpha_explores():
    means, covs = cells()
    assert choose_fixation(means, covs, 'ucb', 0.0).cell == 0          # nearest
    assert choose_fixation(means, covs, 'ucb', np.inf).cell == 2       # most uncertain
    assert choose_fixation(means, covs, 'ucb', 100.0).cell == 2
    d = choose_fixation(means, covs, 'ucb', 0.0)
    np.testing.assert_allclose(d.fixation, means[0])


def test_pi_and_ei():
    means, covs = cells()
    mu, sd = reward_statistics(means, covs)
    pi = acquisition_scores(mu, sd, 'pi')
    assert pi[0] == pytest.approx(0.5)                 # the best itself: P = 1/2
    assert choose_fixation(means, covs, 'pi').cell == 0
    # EI trades magnitude: the far but very uncertain cell beats the near, certain one
    ei = acquisition_scores(mu, sd, 'ei')
    assert np.all(ei >= 0) and np.argmax(ei) == 2
    assert choose_fixation(means, covs, 'ei').cell == 2


def test_bad_inputs_rejected():
    means, covs = cells()
    with pytest.raises(ValueError, match='unknown acquisition'):
        choose_fixation(means, covs, 'thompson')
    with pytest.raises(ValueError, match='alpha'):
        choose_fixation(means, covs, 'ucb', -1.0)
    with pytest.raises(ValueError, match='covs'):
        choose_fixation(means, covs[:2])
    with pytest.raises(ValueError, match='no candidate'):
        choose_fixation(means, covs, candidates=np.zeros(4, bool))
    assert choose_fixation(means, covs, 'ucb', 0.0, candidates=np.array([1, 3])).cell == 1


def test_reachable_cells_follow_azimuth_and_elevation_limits():
    az = np.radians([0.0, 70.0, -85.0, 180.0, 0.0, 0.0])
    el = np.radians([0.0, 10.0, 0.0, 0.0, 70.0, -45.0])
    d = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    ok = reachable_cells(d, np.radians(80.0), (np.radians(-50.0), np.radians(60.0)))
    assert ok.tolist() == [True, True, False, False, False, True]
