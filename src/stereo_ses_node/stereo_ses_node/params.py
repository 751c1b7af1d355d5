"""The stereo_ses node's parameters: the declared table (names, defaults, ranges, help), the
checks the table's ranges cannot express, the groups whose change rebuilds the pipeline or the
ego-sphere, and the user bias GMM. The node (node.py) declares them and reacts to changes."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from stereo_ses_node.core.decision import ACQUISITIONS
from stereo_ses_node.core.ses import BIASES, GMM, SensoryEgoSphere
from stereo_ses_node.core.stereo import SGBMParams
from stereo_ses_node.core.ut import UTParams
from stereo_ses_node.messages import CELLS_TOPIC, GAZE_COMMAND_TOPIC
from vizzy_runtime.node_tools import Param

SENSORS = ('cartesian', 'logpolar')
DISPARITY_RANGES = ('geometry', 'fixed')
BIAS_NAMES = tuple(BIASES) + ('user',)

# The node declares exactly these; each range is the descriptor's, enforced by the middleware.
PARAMETERS: tuple[Param, ...] = (
    Param('sensor', 'logpolar',
          "Retina: 'cartesian' (uniform grid) or 'logpolar' (section 3.3.2).", choices=SENSORS),
    Param('n_rf', 200, 'Receptive fields per side: an n_rf x n_rf grid (cartesian) or n_rf '
          'rings x n_rf wedges (logpolar); thesis 200. In [16, 512].', '[16, 512]'),
    Param('disparity_range', 'geometry',
          "Disparities SGBM searches: 'geometry' (those of points at depth_range_m along the left "
          "camera's rays, from camera_info and tf, for each pair: verged or parallel rigs alike) "
          "or 'fixed' ([min_disparity, min_disparity + num_disparities)). Either window is first "
          'narrowed on a coarse pyramid level (the log-polar sensor then level by level).',
          choices=DISPARITY_RANGES),
    Param('depth_range_m', [0.3, 20.0], "Nearest and farthest depth [m] searched when "
          "disparity_range is 'geometry'.", constraints='[near, far] with 0 < near < far'),
    Param('min_disparity', SGBMParams.min_disparity,
          "Smallest disparity searched [px] when disparity_range is 'fixed' (SGBM minDisparity), "
          'in [-1024, 1024]. Verging eyes see points beyond the fixation at negative disparity; '
          'a parallel rectified rig needs >= 0.', '[-1024, 1024]'),
    Param('num_disparities', SGBMParams.num_disparities,
          "Disparities searched from min_disparity when disparity_range is 'fixed' (SGBM "
          'numDisparities), a multiple of 16 in [16, 1024].', '[16, 1024]', step=16),
    Param('n_cells', 20000, 'Ego-sphere cells N_x, in [100, 200000]; a change resets the '
          'memory.', '[100, 200000]'),
    Param('bias', 'unbiased', "Ego-sphere cell distribution (Table 3.1): 'unbiased', 'top', "
          "'down', 'target', or 'user' (bias_weights / bias_means / bias_variances). A change "
          'resets the memory.', choices=BIAS_NAMES),
    Param('bias_weights', [1.0], "User GMM ('user' bias): M component weights (>= 0, "
          'positive sum).', constraints='finite, >= 0, positive sum'),
    Param('bias_means', [0.0, 0.0, 0.0], 'User GMM: 3 M means (x y z per component, ego '
          'frame, z up).', constraints='finite, 3 per bias_weights component'),
    Param('bias_variances', [0.5, 0.5, 0.5],
          'User GMM: 3 M diagonal variances (xx yy zz per component), > 0.',
          constraints='finite, > 0, 3 per bias_weights component'),
    Param('seed', 0, 'Seed of the cell sampling, in [0, 2^31).', f'[0, {2 ** 31})'),
    Param('prior_distance_m', 10.0, 'Prior mean distance [m] of a never-observed cell (section '
          '3.3.3: "large mean and covariance"), in [0.05, 100]. With the reward -||x|| it is how '
          'near unobserved space is assumed to be; a change resets the memory.', '[0.05, 100]'),
    Param('prior_sigma_m', 10.0, 'Prior standard deviation [m] of a never-observed cell '
          '(isotropic), in [0.001, 100]; a change resets the memory.', '[0.001, 100]'),
    Param('acquisition', 'ucb', "Next-best-view rule: 'ucb', 'pi' or 'ei' (Eqs. 3.41-3.43).",
          choices=ACQUISITIONS),
    Param('ucb_alpha', 100.0, 'UCB exploration weight alpha (Eq. 3.41), >= 0; 0 is greedy, '
          '.inf pure exploration (thesis: 0, 0.01, 1, 100, inf).', '[0, inf]'),
    Param('ut_alpha', 0.25, 'UT alpha (Eqs. 3.14-3.16), in (0, 10].', '(0, 10]'),
    Param('ut_beta', 2.0, 'UT beta (2 for Gaussians), in [0, 10].', '[0, 10]'),
    Param('ut_kappa', 3.0, 'UT kappa, in [-3.9, 100] (L + lambda must stay > 0).',
          '[-3.9, 100]', constraints='L + lambda > 0 with ut_alpha'),
    Param('max_rate_hz', 2.0, 'Most stereo pairs processed per second, in [0.01, 30] (newest '
          'pair wins).', '[0.01, 30]'),
    Param('max_stamp_skew_s', 0.005, 'Largest left/right stamp difference of a pair [s], in '
          '[0, 1].', '[0, 1]'),
    Param('ego_frame', 'ego', 'Frame of the ego-sphere and of the gaze commands '
          '(head-centred, world-fixed orientation, z up).', constraints='a frame id, not empty'),
    Param('publish_gaze', True, f'Send the chosen fixations on {GAZE_COMMAND_TOPIC}.'),
    Param('gaze_priority', 20, 'Priority of the gaze commands (mot_planner 10 < 20 < '
          'foveation 30), in [0, 1000].', '[0, 1000]'),
    Param('hold_time', 1.0, 'hold_time of the gaze commands [s], in [0, 60].', '[0, 60]'),
    Param('decision_period_s', 2.0, 'Least time between two gaze commands [s], in [0.1, 600].',
          '[0.1, 600]'),
    Param('frames_per_fixation', 2, 'Frames fused after a saccade settles before the next '
          'decision, in [1, 100].', '[1, 100]'),
    Param('inhibition_of_return_deg', 0.0, 'Inhibition of return: cells within this angle '
          '[deg] of a fixation this node chose are not chosen again for inhibition_of_return_s '
          '(0: off, the UCB of section 3.3.4 alone), in [0, 90].', '[0, 90]'),
    Param('inhibition_of_return_s', 10.0, 'How long a fixated direction stays inhibited [s], '
          'in [0, 600].', '[0, 600]'),
    Param('min_observations', 1, 'A cell observed in fewer fused frames than this is scored as '
          'a never-observed one (its prior) when choosing the next fixation, in [1, 1000].',
          '[1, 1000]'),
    Param('search_nearest', False, 'Search for the nearest object: once an observed point has '
          'been fixated, only observed cells nearer than the nearest such point compete with '
          'unobserved space (false: every cell, the UCB of section 3.3.4 alone).'),
    Param('explore_coverage_deg', 0.0, 'When the choice falls on unobserved space, take the '
          'unobserved cell with the most unobserved cells within this angle [deg] (the widest '
          'unexplored view; 0: the UCB\'s own choice, the first of equals), in [0, 90].',
          '[0, 90]'),
    Param('fixation_cluster_m', 0.0, 'An observed cell is fixated at the mean of the observed '
          'cell means within this distance [m] of its own (the middle of the object it lies '
          'on; 0: at its own mean), in [0, 1].', '[0, 1]'),
    Param('min_z_m', -0.7, 'Cells whose mean lies below this ego-frame height [m] (the floor, '
          'at about -0.9 m) are not fixation candidates (section 3.4.2), in [-10, 10].',
          '[-10, 10]'),
    Param('azimuth_limit_deg', 75.0, 'Only cells within this azimuth of straight ahead (ego x) '
          'are fixation candidates (neck pan 53 + eye pan 38 deg, less the vergence), in '
          '(0, 180].', '(0, 180]'),
    Param('elevation_limits_deg', [-40.0, 45.0], 'Only cells within these [min, max] '
          'elevations [deg] are fixation candidates (where the gaze IK reaches at 1-8 m), '
          'within [-90, 90].', constraints='[min, max] with -90 <= min < max <= 90'),
    Param('fixation_distance_m', [0.3, 8.0], 'A chosen cell mean is moved along its direction '
          'into this [min, max] distance [m] (the gaze controller refuses < 0.15 m and > 10 m).',
          constraints='[min, max] with 0.15 <= min < max <= 10'),
    Param('cells_rate_hz', 1.0, f'Rate of {CELLS_TOPIC} [Hz], in [0.01, 30].', '[0.01, 30]'),
    Param('publish_unobserved_cells', False, f'Also publish never-observed cells on '
          f'{CELLS_TOPIC} (at their prior mean, prior_distance_m away).'),
)
# parameters whose change rebuilds the stereo pipeline / the ego-sphere
PIPELINE_PARAMETERS = ('sensor', 'n_rf', 'min_disparity', 'num_disparities', 'ut_alpha', 'ut_beta',
                       'ut_kappa')
SES_PARAMETERS = ('n_cells', 'bias', 'bias_weights', 'bias_means', 'bias_variances', 'seed',
                  'prior_distance_m', 'prior_sigma_m')
_LISTS = ('bias_weights', 'bias_means', 'bias_variances', 'fixation_distance_m',
          'elevation_limits_deg', 'depth_range_m')


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is: the rules the table's
    ranges and choices cannot express (list shapes, a non-empty frame id)."""
    if name == 'ego_frame':
        return None if value.strip('/') else 'ego_frame must be a non-empty frame id'
    if name in _LISTS:
        values = [float(v) for v in value]   # a double array (the descriptor's type)
        if not values or not all(math.isfinite(v) for v in values):
            return f'{name} must be a non-empty list of finite numbers, got {list(value)!r}'
        if name == 'bias_weights' and (min(values) < 0 or sum(values) <= 0):
            return 'bias_weights must be >= 0 with a positive sum'
        if name in ('bias_means', 'bias_variances') and len(values) % 3:
            return f'{name} needs 3 numbers per component, got {len(values)}'
        if name == 'bias_variances' and min(values) <= 0:
            return 'bias_variances must be > 0'
        if name == 'elevation_limits_deg' and not (len(values) == 2
                                                   and -90.0 <= values[0] < values[1] <= 90.0):
            return 'elevation_limits_deg must be [min, max] with -90 <= min < max <= 90'
        if name == 'fixation_distance_m' and not (len(values) == 2
                                                  and 0.15 <= values[0] < values[1] <= 10.0):
            return 'fixation_distance_m must be [min, max] with 0.15 <= min < max <= 10'
        if name == 'depth_range_m' and not (len(values) == 2 and 0.0 < values[0] < values[1]):
            return 'depth_range_m must be [near, far] with 0 < near < far'
    return None


def check_all(values: dict[str, Any]) -> list[str]:
    """Problems of the parameters taken together (the user GMM's sizes, the UT's lambda)."""
    problems = []
    m = len(values['bias_weights'])
    if len(values['bias_means']) != 3 * m or len(values['bias_variances']) != 3 * m:
        problems.append(f'bias_means and bias_variances need 3 x {m} numbers for {m} weights')
    try:
        UTParams(float(values['ut_alpha']), float(values['ut_beta']), float(values['ut_kappa']))
    except ValueError as exc:
        problems.append(str(exc))
    return problems


def user_gmm(values: dict[str, Any]) -> GMM:
    """The 'user' bias GMM from the bias_* parameters."""
    m = len(values['bias_weights'])
    return GMM.create(values['bias_weights'], np.reshape(values['bias_means'], (m, 3)),
                      np.reshape(values['bias_variances'], (m, 3)))


def new_ses(p: dict[str, Any]) -> SensoryEgoSphere:
    """A fresh ego-sphere from the parameters (its memory empty)."""
    bias: GMM | str = user_gmm(p) if p['bias'] == 'user' else p['bias']
    return SensoryEgoSphere(int(p['n_cells']), bias, seed=int(p['seed']),
                            init_distance=float(p['prior_distance_m']),
                            init_sigma=float(p['prior_sigma_m']))
