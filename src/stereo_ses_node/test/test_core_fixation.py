"""The stereo_ses gaze decision: candidates, inhibition of return, the next fixation."""

from __future__ import annotations

import math

import numpy as np

from stereo_ses_node.core.fixation import FixationPolicy, fixation_candidates, next_fixation
from stereo_ses_node.core.ses import SensoryEgoSphere
from stereo_ses_node.params import PARAMETERS

DEFAULTS = {p.name: p.default for p in PARAMETERS}


def observe(ses: SensoryEgoSphere, direction: np.ndarray, distance: float,
            radius_deg: float = 3.0) -> np.ndarray:
    """Cells within radius_deg of direction: seen at distance with a 1 cm sigma (their mask)."""
    d = direction / np.linalg.norm(direction)
    near = ses.directions @ d >= math.cos(math.radians(radius_deg))
    ses.mean[near] = distance * ses.directions[near]
    ses.cov[near] = np.eye(3) * 1e-4
    ses.n_obs[near] = 5
    ses.n_frames[near] = 5
    return near


def test_candidates_skip_cells_near_an_inhibited_direction_only_while_it_lasts() -> None:
    ses = SensoryEgoSphere(4000, seed=1)
    ahead = np.array([1.0, 0.0, 0.0])
    policy = FixationPolicy('stereo_ses')
    policy.commanded(0.0, 0, 0, 2.0 * ahead, inhibit_s=5.0)
    inhibited = policy.inhibited_directions(1.0)
    assert inhibited.shape == (1, 3) and np.allclose(inhibited[0], ahead)
    args = (ses.mean, ses.directions, -10.0, math.radians(75.0), (-1.0, 1.0), [])
    free = fixation_candidates(*args)
    held = fixation_candidates(*args, inhibited, math.radians(6.0))
    angle = np.degrees(np.arccos(np.clip(ses.directions @ ahead, -1, 1)))
    assert free[angle < 6.0].all()                      # reachable, not refused
    assert not held[angle < 6.0].any()                  # inhibited around the fixation
    assert np.array_equal(held[angle > 6.0], free[angle > 6.0])
    # an angle of 0 switches it off; an expired direction is forgotten
    assert np.array_equal(fixation_candidates(*args, inhibited, 0.0), free)
    assert policy.inhibited_directions(5.0).shape == (0, 3)
    policy.commanded(6.0, 1, 0, ahead, inhibit_s=0.0)   # 0 s: nothing inhibited
    assert policy.inhibited_directions(6.0).shape == (0, 3)


def test_nearest_object_search_moves_on_after_fixating_a_near_object() -> None:
    """The visual-search task (UCB alpha 1, a near prior): the nearest observed object beats
    unobserved space; with inhibition of return, once fixated, the next choice is elsewhere,
    not that object again (without it the head would stare at the first near object)."""
    ses = SensoryEgoSphere(6000, seed=2, init_distance=1.0, init_sigma=0.001)
    near_can = np.array([1.0, 0.3, -0.1])
    nearer_can = np.array([0.5, 1.0, -0.1])        # 63 deg left: out of view so far
    can_cells = observe(ses, near_can, 0.8)
    p = dict(DEFAULTS, ucb_alpha=1.0, inhibition_of_return_deg=6.0, min_z_m=-10.0)
    policy = FixationPolicy('stereo_ses')

    chosen = next_fixation(ses, p, [], policy.inhibited_directions(0.0))
    assert chosen is not None and can_cells[chosen[0].cell]      # the 0.8 m can first
    assert math.isclose(float(np.linalg.norm(chosen[1])), 0.8, rel_tol=1e-6)
    policy.commanded(0.0, chosen[0].cell, 5, ses.directions[chosen[0].cell], inhibit_s=30.0)

    again = next_fixation(ses, dict(p, inhibition_of_return_deg=0.0), [])
    assert again is not None and can_cells[again[0].cell]        # without IoR: the same can
    moved = next_fixation(ses, p, [], policy.inhibited_directions(1.0))
    assert moved is not None and not ses.n_obs[moved[0].cell]    # with IoR: explore
    # the nearer can, once seen, is the next fixation (the search's goal)
    nearer_cells = observe(ses, nearer_can, 0.55)
    found = next_fixation(ses, p, [], policy.inhibited_directions(2.0))
    assert found is not None and nearer_cells[found[0].cell]


def test_an_observed_cell_is_fixated_at_the_middle_of_its_surface() -> None:
    """fixation_cluster_m: the chosen cell on the rim of a near object is fixated at the mean of
    the observed cells about it (the object's middle), not at its own mean; 0 keeps the cell's
    own mean; unobserved space is fixated at the cell's prior mean either way."""
    ses = SensoryEgoSphere(6000, seed=3, init_distance=1.0, init_sigma=0.001)
    centre = np.array([0.5, 0.0, 0.0])
    cells = observe(ses, centre, 0.5, radius_deg=5.0)
    # the nearest point: a cell on the rim, pulled 2 cm nearer than the rest of the surface
    rim = np.flatnonzero(cells)[np.argmin(ses.directions[cells] @ centre)]
    ses.mean[rim] *= 0.96
    p = dict(DEFAULTS, ucb_alpha=1.0, min_z_m=-10.0)
    own = next_fixation(ses, p, [])
    assert own is not None and own[0].cell == rim and np.allclose(own[1], ses.mean[rim])
    middle = next_fixation(ses, dict(p, fixation_cluster_m=0.06), [])
    assert middle is not None and middle[0].cell == rim
    off_own = math.degrees(math.acos(own[1] @ centre / np.linalg.norm(own[1]) / 0.5))
    off_middle = math.degrees(math.acos(middle[1] @ centre / np.linalg.norm(middle[1]) / 0.5))
    assert off_own > 4.0 and off_middle < 1.0, (off_own, off_middle)
    ses.n_obs[:] = 0                                      # nothing observed: the prior mean
    ses.n_frames[:] = 0
    ses.mean[:] = ses.directions
    unobserved = next_fixation(ses, dict(p, fixation_cluster_m=0.06), [])
    assert unobserved is not None
    assert np.allclose(unobserved[1], ses.directions[unobserved[0].cell])


def test_a_cell_seen_fewer_than_min_observations_times_is_scored_by_its_prior() -> None:
    """A cell seen in one frame (stereo mismatches 0.4 m in front of the eyes, many points) is
    the nearest thing there is for min_observations 1; with 3 it counts as unobserved and a
    surface seen in 5 frames at 0.8 m is chosen instead."""
    ses = SensoryEgoSphere(6000, seed=4, init_distance=1.0, init_sigma=10.0)
    ahead = ses.directions[np.argmax(ses.directions @ np.array([0.98, 0.0, 0.2]))]
    lone = observe(ses, ahead, 0.4, radius_deg=1.0)       # that one cell
    assert lone.sum() == 1
    ses.n_obs[lone] = 40          # many points, one frame
    ses.n_frames[lone] = 1
    surface = observe(ses, np.array([1.0, -0.5, 0.0]), 0.8)
    p = dict(DEFAULTS, ucb_alpha=0.01, prior_distance_m=1.0, prior_sigma_m=10.0, min_z_m=-10.0)
    greedy = next_fixation(ses, p, [])
    assert greedy is not None and lone[greedy[0].cell]
    robust = next_fixation(ses, dict(p, min_observations=3), [])
    assert robust is not None and surface[robust[0].cell]


def test_search_nearest_looks_again_only_where_it_can_improve() -> None:
    """search_nearest: after fixating an object 0.8 m away, a surface 0.9 m away (a stand, say)
    no longer beats unobserved space, which is explored instead; a surface seen nearer than
    0.8 m is fixated next."""
    ses = SensoryEgoSphere(6000, seed=5, init_distance=1.0, init_sigma=0.001)
    can = observe(ses, np.array([1.0, 0.0, -0.2]), 0.8)
    stand = observe(ses, np.array([1.0, 0.0, -0.6]), 0.9)
    p = dict(DEFAULTS, ucb_alpha=1.0, min_z_m=-10.0, inhibition_of_return_deg=6.0,
             search_nearest=True)
    policy = FixationPolicy('stereo_ses')
    first = next_fixation(ses, p, [], policy.inhibited_directions(0.0), policy.nearest_fixated)
    assert first is not None and can[first[0].cell]
    policy.fixating(0.0, first[0].cell, ses, first[1], p)
    assert math.isclose(policy.nearest_fixated, 0.8, rel_tol=1e-6)
    args = ([], policy.inhibited_directions(1.0))
    plain = next_fixation(ses, dict(p, search_nearest=False), *args, policy.nearest_fixated)
    assert plain is not None and stand[plain[0].cell]             # the UCB alone: the stand
    search = next_fixation(ses, p, *args, policy.nearest_fixated)
    assert search is not None and ses.n_frames[search[0].cell] == 0   # unobserved space
    target = observe(ses, np.array([0.4, 1.0, 0.0]), 0.55)
    found = next_fixation(ses, p, *args, policy.nearest_fixated)
    assert found is not None and target[found[0].cell]


def test_exploration_goes_to_the_widest_unobserved_view() -> None:
    """explore_coverage_deg: with everything ahead and to the right observed, the next look at
    unobserved space goes left, into the widest unexplored view, not to the first unobserved
    cell in index order."""
    ses = SensoryEgoSphere(6000, seed=6, init_distance=1.0, init_sigma=0.001)
    az = np.degrees(np.arctan2(ses.directions[:, 1], ses.directions[:, 0]))
    el = np.degrees(np.arcsin(ses.directions[:, 2]))
    seen = (az < 40.0) | (el > 30.0) | (el < -30.0)           # all but a wedge on the left
    ses.mean[seen] *= 3.0                                       # far walls
    ses.n_obs[seen] = ses.n_frames[seen] = 5
    p = dict(DEFAULTS, ucb_alpha=1.0, min_z_m=-10.0)
    wide = next_fixation(ses, dict(p, explore_coverage_deg=30.0), [])
    assert wide is not None and not seen[wide[0].cell]
    assert 45.0 <= az[wide[0].cell] <= 75.0 and abs(el[wide[0].cell]) <= 20.0
