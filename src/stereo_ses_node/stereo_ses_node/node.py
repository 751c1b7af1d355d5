"""The `stereo_ses` node (thesis chapter 3): foveated stereo into the Sensory Ego-Sphere, and gaze.

Topic names are relative (in: `left/image_raw`, `left/camera_info`, `right/...`, `gaze/state`);
the graph remaps the camera inputs to the simulator's, so below are the resolved defaults.

Subscribes
  /vizzy/{left,right}/image_raw   sensor_msgs/Image rgb8/bgr8 (RELIABLE keep-last 5, see QoS
                                  below), paired by stamp
  /vizzy/{left,right}/camera_info sensor_msgs/CameraInfo: K of each camera
  /tf, /tf_static                 camera poses at each pair's stamp (the left image's):
                                  left optical frame in `ego_frame`, right in left
                                  (vizzy_runtime.tf, each /tf edge interpolated at the stamp; the
                                  worker waits up to TF_WAIT_S for /tf that covers it)
  /gaze/state                     active_vision_msgs/GazeState: nothing is fused while in_saccade
                                  (nor pairs stamped before the last saccade ended)

Per stereo pair (core.stereo.StereoPipeline): SGBM at the resolution the sensor needs (the
Cartesian RF grid; for the log-polar sensor full resolution in its fovea and coarser pyramid
levels outward, core.multires.FoveatedSGBM) over the disparities of points at depth_range_m
(disparity_range 'geometry', from camera_info and tf; or the fixed min/num_disparities),
narrowed coarse-to-fine; matches off the epipolar line (a verged pair's periphery) dropped;
mid-point triangulation (Eq. 3.8) and the Unscented Transform (Eqs. 3.9-3.18) in the LEFT
camera's optical frame; then
SensoryEgoSphere.fuse with the ego <- left transform (Eqs. 3.22-3.35). Publishes

  /stereo/points  sensor_msgs/PointCloud2, frame = the left image's frame_id (the left camera
                  optical frame), the image's stamp; fields x y z [m] (float32), rgb (float32
                  packed 0x00RRGGBB, PCL style), cxx cxy cxz cyy cyz czz [m^2] (float32, the UT
                  covariance, Eq. 3.18, same frame), information (-log|Sigma|, Eq. 3.45)
  /ses/cells      sensor_msgs/PointCloud2, frame `ego_frame`; fields x y z [m] (the cell means),
                  information (-log|Sigma|, Eq. 3.45; colour by it), sigma_r [m] (the reward
                  standard deviation of Eq. 3.39, square-rooted), observations (float32 count);
                  the observed cells only unless publish_unobserved_cells; at cells_rate_hz
  /gaze/command   active_vision_msgs/GazeCommand (if publish_gaze): MODE_FIXATION_POINT in
                  `ego_frame`, MOTION_SACCADE, source 'stereo_ses', priority gaze_priority (20),
                  hold_time: the chosen cell (core.decision.choose_fixation, UCB / PI / EI) once
                  decision_period_s has passed since the last command AND frames_per_fixation
                  frames were fused since the last saccade settled
  /diagnostics    diagnostic_msgs/DiagnosticArray, about 1 Hz: the node's input health (below)

Processing never blocks the executor: callbacks only store messages; a worker thread takes the
newest complete pair (older pairs are dropped: newest wins, one in flight) at most max_rate_hz
times a second of the images' own time (their stamps; sim time in the graph), so the node
leaves CPU to the rest of the graph (a 640x480 log-polar pair costs about 85 ms of one core,
mostly the UT of ~34,000 points; the matching about 13 ms). Bad input
is refused and the ego-sphere stays consistent (SensoryEgoSphere.fuse validates everything
before it changes state; degenerate geometry and NaN disparities inside a frame are dropped
point by point, StereoFrame.rejected).

Refused inputs are counted by vizzy_runtime.input_health.InputHealth (self.input_health;
logging and /diagnostics as its docstring says). The reasons (counter keys):
  on /vizzy/{left,right}/image_raw, one image at a time (IMAGE_REASONS): 'unsupported encoding'
    (not rgb8/bgr8), 'empty image', 'step shorter than a row', 'size inconsistent with data'
    (fewer data bytes than height x step); 'no partner image' (no image of the other eye came
    within max_stamp_skew_s of its stamp: dropped unpaired, images_unpaired);
  on both image topics, once per image of a pair the worker took (PAIR_REASONS): 'left and right
    sizes differ', 'no camera_info' (none usable yet for an eye), 'size differs from
    camera_info', 'no frame_id', 'no camera pose' (tf lacks ego <- left or left <- right, or the
    rig is degenerate), 'no valid correspondences' (e.g. textureless: NaN disparities),
    'failed on a pair: <ExcType>' (an exception in the worker); these count in frames_skipped;
    'not newer than the last fused pair' (REPEATED_STAMP: a pair stamped at or before the last
    fused one, e.g. the same pair sent twice: one observation is fused once; counted in
    pairs_repeated, not frames_skipped; when the node's clock itself went back before that
    stamp, a restarted simulation or bag, it is fused);
  on /vizzy/{left,right}/camera_info: 'unusable K' (not 9 finite values with fx, fy in
    [1, 1e6] px; the last good K stays in use);
  for an exception escaping a subscription callback (node_tools.guarded): 'failed on an image:
    <ExcType>' (or a camera_info, a state) on that callback's topic.
A pair's images are accepted when it was fused; held (not refused) when deliberately not fused:
'in saccade' (frames_in_saccade) or 'max_rate_hz' (the rate limit, pairs_dropped); a pair
replaced by a newer one before the worker took it (pairs_dropped) is neither. /diagnostics turns
WARN when /stereo/points has not gone out for OUTPUT_STALL_S (or three capped pairs) while images
arrive. Gaze states are always accepted.

QoS: unlike REP 2003's sensor-data default, the four stereo inputs subscribe RELIABLE keep-last 5:
best effort lost most pairs of fragmented VGA images (35 of 150 pairs vs 149 reliable, measured).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from stereo_ses_node.core.decision import (
    ACQUISITIONS,
    Decision,
    choose_fixation,
    reachable_cells,
    reward_statistics,
)
from stereo_ses_node.core.information import information, information_from_precision
from stereo_ses_node.core.multires import DisparityWindow, disparity_window
from stereo_ses_node.core.ses import BIASES, GMM, FusionReport, SensoryEgoSphere
from stereo_ses_node.core.stereo import SGBMParams, StereoFrame, StereoPipeline
from stereo_ses_node.core.ut import StereoRig, UTParams
from vizzy_runtime.convert import (  # noqa: F401 (re-exported: the image reasons are this
    # node's counter keys too)
    EMPTY_IMAGE,
    IMAGE_REASONS,
    SHORT_DATA,
    SHORT_STEP,
    TOO_LARGE,
    UNCONVERTIBLE,
    UNSUPPORTED_ENCODING,
    ConversionError,
    array_to_pointcloud2,
    camera_k,
    image_refusal,
    image_to_numpy,
    stamp_seconds,
)
from vizzy_runtime.input_health import InputHealth, ThrottledWarnings
from vizzy_runtime.node_tools import (
    LatestWorker,
    Param,
    declare_parameters,
    guarded,
    main_for,
    publish_from_thread,
    replace_timer,
)
from vizzy_runtime.rate_gate import RateGate
from vizzy_runtime.ros import ExternalShutdownException, Node, QoSProfile, message
from vizzy_runtime.tf import TransformBuffer, TransformListener
from vizzy_vision.pointcloud import pack_rgb

Header = message('std_msgs/msg/Header')
Image = message('sensor_msgs/msg/Image')
CameraInfo = message('sensor_msgs/msg/CameraInfo')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')
GazeCommand = message('active_vision_msgs/msg/GazeCommand')
GazeState = message('active_vision_msgs/msg/GazeState')

EYES = ('left', 'right')
# Relative names: the graph remaps the generic inputs (left/image_raw:=vizzy/left/image_raw, ...)
# and the node's namespace places everything; logs print the resolved names.
IMAGE_TOPICS = {'left': 'left/image_raw', 'right': 'right/image_raw'}
INFO_TOPICS = {'left': 'left/camera_info', 'right': 'right/camera_info'}
GAZE_STATE_TOPIC = 'gaze/state'
GAZE_COMMAND_TOPIC = 'gaze/command'
POINTS_TOPIC = 'stereo/points'
CELLS_TOPIC = 'ses/cells'
# Reliable, not sensor data (REP 2003's default): a best-effort reader never repairs a lost fragment
# of a 921 KB image, and a stereo pair needs both images (module docstring).
STEREO_QOS = QoSProfile(depth=5)
SOURCE = 'stereo_ses'
ENCODINGS = ('rgb8', 'bgr8')
# Refusal reasons (InputHealth counter keys: short and stable; the values go in the detail).
NO_PARTNER = 'no partner image'
# a pair the worker could not fuse: counted on both image topics
SIZES_DIFFER = 'left and right sizes differ'
NO_CAMERA_INFO = 'no camera_info'
INFO_SIZE_MISMATCH = 'size differs from camera_info'
NO_FRAME_ID = 'no frame_id'
NO_CAMERA_POSE = 'no camera pose'
NO_CORRESPONDENCES = 'no valid correspondences'
PAIR_FAILED = 'failed on a pair'           # + ': <ExcType>'
PAIR_REASONS = (SIZES_DIFFER, NO_CAMERA_INFO, INFO_SIZE_MISMATCH, NO_FRAME_ID, NO_CAMERA_POSE,
                NO_CORRESPONDENCES)
REPEATED_STAMP = 'not newer than the last fused pair'
# The worker waits this long [s] for the /tf that covers a pair's stamp (it may arrive just after
# the images); then the pair is skipped ('no camera pose').
TF_WAIT_S = 0.5
UNUSABLE_K = 'unusable K'
# Held, not refused (the pair is set aside by design; /diagnostics shows `held (<reason>)`).
IN_SACCADE = 'in saccade'
RATE_CAP = 'max_rate_hz'
# /stereo/points silent this long (node clock) while images arrive: a /diagnostics WARN
OUTPUT_STALL_S = 3.0
WARN_PERIOD_S = 5.0                        # throttle of the warnings that are no refusals
# After a gaze command, frames do not count towards frames_per_fixation until the saccade has
# started (in_saccade seen) or this long has passed (a tiny or refused movement).
SACCADE_START_TIMEOUT_S = 1.0
# Images of one eye kept waiting for the other eye's image with the same stamp.
UNPAIRED_KEPT = 3

POINT_DTYPE = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('rgb', '<f4'),
                        ('cxx', '<f4'), ('cxy', '<f4'), ('cxz', '<f4'), ('cyy', '<f4'),
                        ('cyz', '<f4'), ('czz', '<f4'), ('information', '<f4')])
CELL_DTYPE = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('information', '<f4'),
                       ('sigma_r', '<f4'), ('observations', '<f4')])

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


def image_problem(msg: Any) -> tuple[str, str] | None:
    """(reason, detail) of why an input image cannot be used, or None if it can (reason: one of
    IMAGE_REASONS, a counter key)."""
    return image_refusal(msg, dict.fromkeys(ENCODINGS, 3))


def points_array(frame: StereoFrame, info: np.ndarray) -> np.ndarray:
    """The /stereo/points structured array of a frame (left optical frame)."""
    out = np.empty(frame.means.shape[0], POINT_DTYPE)
    for i, axis in enumerate('xyz'):
        out[axis] = frame.means[:, i]
    out['rgb'] = pack_rgb(frame.colors)
    for name, (a, b) in (('cxx', (0, 0)), ('cxy', (0, 1)), ('cxz', (0, 2)), ('cyy', (1, 1)),
                         ('cyz', (1, 2)), ('czz', (2, 2))):
        out[name] = frame.covs[:, a, b]
    out['information'] = info
    return out


def cells_array(ses: SensoryEgoSphere, observed_only: bool) -> np.ndarray:
    """The /ses/cells structured array (ego frame)."""
    idx = np.nonzero(ses.n_obs > 0)[0] if observed_only else np.arange(ses.n_cells)
    out = np.empty(idx.size, CELL_DTYPE)
    mean = ses.mean[idx]
    for i, axis in enumerate('xyz'):
        out[axis] = mean[:, i]
    out['information'] = information_from_precision(ses.info[idx])
    out['sigma_r'] = reward_statistics(mean, ses.cov[idx])[1]
    out['observations'] = ses.n_obs[idx]
    return out


@dataclass
class Pair:
    """A left and a right image with the same stamp (within max_stamp_skew_s); stamp: the left
    image's [s]."""

    left: Any
    right: Any
    stamp: float


class StereoSesNode(Node):
    """Stereo pairs -> UT points -> the Sensory Ego-Sphere -> next fixation."""

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__('stereo_ses', **node_kwargs)
        self._p = declare_parameters(self, PARAMETERS, check_parameter, check_all=check_all,
                                     on_change=self._on_parameters_changed)
        # refused inputs, per topic and reason; /diagnostics (before any subscription)
        self.input_health = InputHealth(self)
        self._lock = threading.Lock()
        self._ses_lock = threading.Lock()
        self._unpaired: dict[str, list[Any]] = {e: [] for e in EYES}   # waiting, oldest first
        self._k: dict[str, np.ndarray] = {}
        self._info_size: dict[str, tuple[int, int]] = {}
        self._in_saccade = False
        self._settled_at = -math.inf                  # stamp of the last saccade's end
        self._awaiting_saccade_until = -math.inf      # node-clock deadline after a command
        self._frames_since_settle = 0
        self._last_command = -math.inf                # node clock [s] (sim time in the graph)
        self._pair_gate = RateGate()                  # max_rate_hz in the pairs' stamps
        self._pipeline: StereoPipeline | None = None
        self._pipeline_dirty = False
        self._ses = self._new_ses()
        self._ses_dirty = False
        self._refused: set[int] = set()   # cells not to choose: refused, or fixating gave nothing
        self._fixated: tuple[int, int] | None = None   # (cell, its n_obs) of the last command
        self._own_saccade = False         # the saccade under way is this node's
        self._served = False              # the gaze controller served the last command
        self._warn_throttled = ThrottledWarnings(self, WARN_PERIOD_S)  # what is no refusal
        # counters (read by tests and the periodic log)
        self.pairs_received = 0
        self.images_unpaired = 0          # dropped: no partner with a matching stamp
        self.pairs_processed = 0          # fused, skipped or suppressed
        self.pairs_dropped = 0            # replaced by a newer pair before processing
        self.frames_fused = 0
        self.frames_skipped = 0
        self.frames_in_saccade = 0
        self.pairs_repeated = 0           # refused: stamp not newer than the last fused pair's
        self._last_fused_stamp = -math.inf
        self.gaze_commands = 0
        self.last_report: FusionReport | None = None
        self.last_decision: Decision | None = None
        self.processing_s: list[float] = []

        self._tf = TransformBuffer()
        self._tf_listener = TransformListener(self._tf, self)
        self._points_pub = self.create_publisher(PointCloud2, POINTS_TOPIC, 10)
        self._cells_pub = self.create_publisher(PointCloud2, CELLS_TOPIC, 10)
        self._gaze_pub = self.create_publisher(GazeCommand, GAZE_COMMAND_TOPIC, 10)
        # resolved names, for log lines
        self._image_topics = {e: self.resolve_topic_name(IMAGE_TOPICS[e]) for e in EYES}
        self.input_health.watch_output(self._points_pub.topic_name,
                                       list(self._image_topics.values()), self._output_stall_s)
        self._info_topics = {e: self.resolve_topic_name(INFO_TOPICS[e]) for e in EYES}
        self._gaze_state_topic = self.resolve_topic_name(GAZE_STATE_TOPIC)
        self._image_subs: dict[str, Any] = {}
        self._info_subs: dict[str, Any] = {}
        # an exception in a callback is counted as a refusal of its topic (and logged there)
        for eye in EYES:
            self._image_subs[eye] = self.create_subscription(
                Image, IMAGE_TOPICS[eye],
                guarded(self, 'failed on an image',
                        lambda msg, eye=eye: self._on_image(eye, msg),
                        topic=self._image_topics[eye]),
                STEREO_QOS)
            self._info_subs[eye] = self.create_subscription(
                CameraInfo, INFO_TOPICS[eye],
                guarded(self, 'failed on a camera_info',
                        lambda msg, eye=eye: self._on_camera_info(eye, msg),
                        topic=self._info_topics[eye]),
                STEREO_QOS)
        self._gaze_state_sub = self.create_subscription(
            GazeState, GAZE_STATE_TOPIC,
            guarded(self, 'failed on a state', self._on_gaze_state,
                    topic=self._gaze_state_topic), 10)
        # guarded: cells racing with Ctrl-C end spin quietly (ExternalShutdownException)
        self._cells_tick = guarded(self, 'ego-sphere cells failed', self._on_cells_timer)
        self._cells_timer = self.create_timer(1.0 / self._p['cells_rate_hz'], self._cells_tick)
        self._worker = LatestWorker('stereo_ses_worker', self._work)
        p = self._p
        self.get_logger().info(
            f'stereo on {self._image_subs["left"].topic_name} + '
            f'{self._image_subs["right"].topic_name} (camera info '
            f'{self._info_subs["left"].topic_name} + {self._info_subs["right"].topic_name}) '
            f'with a {p["sensor"]} '
            f'sensor of {p["n_rf"]}x{p["n_rf"]} RFs at most {p["max_rate_hz"]:g} Hz -> '
            f'{self._points_pub.topic_name}; ego-sphere of {p["n_cells"]} cells ({p["bias"]} '
            f'bias) in {p["ego_frame"]!r} -> {self._cells_pub.topic_name}; gaze '
            f'{p["acquisition"]} on {self._gaze_pub.topic_name}'
            f'{" alpha " + str(p["ucb_alpha"]) if p["acquisition"] == "ucb" else ""} '
            f'{"on" if p["publish_gaze"] else "off"} (priority {p["gaze_priority"]})')

    # --- set-up ---------------------------------------------------------------------------------

    def _new_ses(self) -> SensoryEgoSphere:
        p = self._p
        bias: GMM | str = user_gmm(p) if p['bias'] == 'user' else p['bias']
        return SensoryEgoSphere(int(p['n_cells']), bias, seed=int(p['seed']),
                                init_distance=float(p['prior_distance_m']),
                                init_sigma=float(p['prior_sigma_m']))

    def _on_parameters_changed(self, changed: dict[str, Any]) -> None:
        with self._lock:
            if any(n in changed for n in PIPELINE_PARAMETERS):
                self._pipeline_dirty = True
            if any(n in changed for n in SES_PARAMETERS):
                self._ses_dirty = True
        if 'cells_rate_hz' in changed:
            self._cells_timer = replace_timer(self, self._cells_timer,
                                              1.0 / changed['cells_rate_hz'], self._cells_tick)


    # --- inputs (executor thread: store only) ---------------------------------------------------

    def _on_camera_info(self, eye: str, msg: Any) -> None:
        k = camera_k(msg)
        if k is None:       # the last usable one (if any) stays in use
            self.input_health.refuse(self._info_topics[eye], UNUSABLE_K, f'K {list(msg.k)}')
            return
        with self._lock:
            self._k[eye] = k
            self._info_size[eye] = (int(msg.width), int(msg.height))
        self.input_health.accept(self._info_topics[eye])

    def _on_gaze_state(self, msg: Any) -> None:
        with self._lock:
            saccade = bool(msg.in_saccade)
            if saccade:
                self._awaiting_saccade_until = -math.inf
                if msg.active_source == SOURCE:
                    self._own_saccade = True         # our command moves the eyes
                    self._served = True
            if self._in_saccade and not saccade:
                # pairs stamped before this were taken before or during the movement
                # (blurred; saccadic suppression)
                self._settled_at = stamp_seconds(msg.header.stamp)
                if self._own_saccade:
                    # our own saccade settled: count the frames of its fixation. Other sources'
                    # saccades (the object map's looks every ~1.1 s, foveation's) do not restart
                    # the count: their frames are observations too, and restarting on them left
                    # this node one decision in 30 s of the deployed graph (issue 26)
                    self._own_saccade = False
                    self._frames_since_settle = 0
            self._in_saccade = saccade
        self.input_health.accept(self._gaze_state_topic)
        if msg.status in (GazeState.STATUS_REJECTED_NAN, GazeState.STATUS_REJECTED_UNKNOWN_FRAME,
                          GazeState.STATUS_REJECTED_UNREACHABLE,
                          GazeState.STATUS_REJECTED_INVALID) and self.last_decision is not None \
                and self._clock_s() - self._last_command < SACCADE_START_TIMEOUT_S:
            # the status of the command just sent (the controller answers at once)
            with self._lock:        # not chosen again (until the ego-sphere is rebuilt)
                self._refused.add(self.last_decision.cell)
            self._warn_throttled('gaze_status', f'{self._gaze_state_topic}: a gaze command was '
                                                f'refused: {msg.status_message}')

    def _on_image(self, eye: str, msg: Any) -> None:
        problem = image_problem(msg)
        if problem:
            self.input_health.refuse(self._image_topics[eye], *problem)
            return
        other_eye = 'right' if eye == 'left' else 'left'
        t = stamp_seconds(msg.header.stamp)
        skew = self._p['max_stamp_skew_s']
        with self._lock:
            mine, others = self._unpaired[eye], self._unpaired[other_eye]
            match = next((m for m in others if abs(stamp_seconds(m.header.stamp) - t) <= skew),
                         None)
            if match is None:
                # wait for the partner (the eyes' images may arrive interleaved); the oldest
                # waiting image goes when too many wait: its partner was lost
                mine.append(msg)
                unpaired = {eye: mine[:-UNPAIRED_KEPT]}
                del mine[:-UNPAIRED_KEPT]
            else:
                # pair; older images of either eye can no longer win (newest pair wins)
                t_other = stamp_seconds(match.header.stamp)
                unpaired = {eye: list(mine), other_eye: [
                    m for m in others if stamp_seconds(m.header.stamp) < t_other]}
                others[:] = [m for m in others if stamp_seconds(m.header.stamp) > t_other]
                mine.clear()
                left_msg, right_msg = (msg, match) if eye == 'left' else (match, msg)
                pair = Pair(left_msg, right_msg, stamp_seconds(left_msg.header.stamp))
                self.pairs_received += 1
                # max_rate_hz in the images' own time (sim time in the graph): a loaded
                # machine fuses the same pairs, later, not fewer per second of video
                if not self._pair_gate.take(t, self._p['max_rate_hz']):
                    self.pairs_dropped += 1
                    self._hold(RATE_CAP)
                else:
                    if self._worker.put(pair):
                        self.pairs_dropped += 1   # the worker is busy: newest pair wins
            self.images_unpaired += sum(len(gone) for gone in unpaired.values())
        for gone_eye, gone in unpaired.items():
            partner = 'right' if gone_eye == 'left' else 'left'
            for m in gone:
                self.input_health.refuse(
                    self._image_topics[gone_eye], NO_PARTNER,
                    f'image stamped {stamp_seconds(m.header.stamp):.3f} s dropped: no {partner} '
                    f'image within max_stamp_skew_s {skew:g} s (left/right stamps differ, or its '
                    f'partner was lost)')

    # --- the worker -----------------------------------------------------------------------------

    def _work(self, pair: Pair) -> None:
        try:
            self._process(pair)
        except ExternalShutdownException:  # the node is going away: LatestWorker ends quietly
            raise
        except Exception as exc:  # one bad pair never stops the worker
            self._skip(pair, f'{PAIR_FAILED}: {type(exc).__name__}', str(exc))
        self.pairs_processed += 1

    def _skip(self, pair: Pair, reason: str, detail: str) -> None:
        """A pair not fused: both its images are refused (counted and logged per topic)."""
        self.frames_skipped += 1
        for eye in EYES:
            self.input_health.refuse(self._image_topics[eye], reason,
                                     f'pair stamped {pair.stamp:.3f} s skipped: {detail}')

    def _accept(self) -> None:
        for eye in EYES:
            self.input_health.accept(self._image_topics[eye])

    def _hold(self, reason: str) -> None:
        """A pair the node set aside by design (a saccade, the rate cap): held, not refused."""
        for eye in EYES:
            self.input_health.hold(self._image_topics[eye], reason)

    def _output_stall_s(self) -> float:
        """How long /stereo/points may be silent while images arrive: three capped pairs, 3 s at
        least (a saccade and its settling)."""
        return max(OUTPUT_STALL_S, 3.0 / self._p['max_rate_hz'])

    def _prepare(self, pair: Pair) -> tuple[np.ndarray, np.ndarray, StereoRig, np.ndarray] | None:
        """(left, right, rig in the left optical frame, ego <- left) or None (skipped, logged)."""
        left, right = image_to_numpy(pair.left), image_to_numpy(pair.right)
        if left.shape != right.shape:
            self._skip(pair, SIZES_DIFFER, f'left image {left.shape[1]}x{left.shape[0]} and '
                                           f'right {right.shape[1]}x{right.shape[0]} differ')
            return None
        # the pipeline's colours and grey conversion expect RGB
        left = left[..., ::-1] if pair.left.encoding == 'bgr8' else left
        right = right[..., ::-1] if pair.right.encoding == 'bgr8' else right
        with self._lock:
            k = dict(self._k)
            sizes = dict(self._info_size)
        missing = [e for e in EYES if e not in k]
        if missing:
            self._skip(pair, NO_CAMERA_INFO,
                       f'waiting for {" and ".join(self._info_topics[e] for e in missing)}')
            return None
        h, w = left.shape[:2]
        for eye in EYES:
            if sizes[eye] not in ((w, h), (0, 0)):
                self._skip(pair, INFO_SIZE_MISMATCH, f'{self._info_topics[eye]} is for '
                                                     f'{sizes[eye][0]}x{sizes[eye][1]} images, '
                                                     f'got {w}x{h}')
                return None
        frames = {e: getattr(pair, e).header.frame_id for e in EYES}
        if not all(frames.values()):
            self._skip(pair, NO_FRAME_ID, 'an image has no frame_id: no camera pose')
            return None
        try:
            # the poses when the images were taken, not the latest: the head may have moved on
            # (1 rad/s of pursuit is 2.9 deg per 50 ms); both at the left image's stamp (the
            # right one's is within max_stamp_skew_s)
            ego_left = self._tf.lookup_transform(self._p['ego_frame'], frames['left'],
                                                 pair.stamp, timeout_s=TF_WAIT_S)
            left_right = self._tf.lookup_transform(frames['left'], frames['right'], pair.stamp,
                                                   timeout_s=TF_WAIT_S)
            rig = StereoRig.create(k['left'], k['right'], np.eye(4), left_right)
        except (LookupError, ValueError) as exc:
            self._skip(pair, NO_CAMERA_POSE, f'no usable camera poses: {exc}')
            return None
        return np.ascontiguousarray(left), np.ascontiguousarray(right), rig, ego_left

    def _pipeline_for(self, width: int, height: int) -> StereoPipeline:
        with self._lock:
            dirty, self._pipeline_dirty = self._pipeline_dirty, False
        pipe = self._pipeline
        if dirty or pipe is None or (pipe.width, pipe.height) != (width, height):
            p = self._p
            n = int(p['n_rf'])
            pipe = StereoPipeline(width, height, p['sensor'], (n, n),
                                  sgbm=SGBMParams(num_disparities=int(p['num_disparities']),
                                                  min_disparity=int(p['min_disparity'])),
                                  ut=UTParams(float(p['ut_alpha']), float(p['ut_beta']),
                                              float(p['ut_kappa'])))
            self._pipeline = pipe
            self.get_logger().info(f'stereo pipeline: {p["sensor"]} sensor, {n}x{n} RFs on '
                                   f'{width}x{height} images')
        return pipe

    def _window(self, rig: StereoRig, width: int, height: int) -> DisparityWindow | None:
        """The disparities to search on this pair (None: the fixed SGBM parameters' range)."""
        p = self._p
        if p['disparity_range'] != 'geometry':
            return None
        near, far = (float(v) for v in p['depth_range_m'])
        try:
            return disparity_window(rig.k_left, rig.k_right, rig.pose_left, rig.pose_right,
                                    width, height, near, far)
        except ValueError as exc:
            self._warn_throttled('window', f'no disparity window from the geometry ({exc}): '
                                           f'searching the fixed min_disparity/num_disparities')
            return None

    def _repeated(self, pair: Pair) -> bool:
        """Is pair stamped at or before the last fused pair (refused, counted, logged)?"""
        last = self._last_fused_stamp
        if pair.stamp > last:
            return False
        if self._clock_s() < last:
            # the node's clock went back before the last fused stamp: the simulation or a bag
            # restarted, so these are new observations
            self.get_logger().info(f'time went back ({self._clock_s():.3f} s < last fused pair '
                                   f'{last:.3f} s): fusing from {pair.stamp:.3f} s on')
            self._last_fused_stamp = -math.inf
            return False
        self.pairs_repeated += 1
        for eye in EYES:
            self.input_health.refuse(
                self._image_topics[eye], REPEATED_STAMP,
                f'pair stamped {pair.stamp:.3f} s refused: the last fused pair was stamped '
                f'{last:.3f} s (one observation is fused once)')
        return True

    def _process(self, pair: Pair) -> None:
        t0 = time.monotonic()
        if self._repeated(pair):
            return
        with self._lock:
            in_saccade = self._in_saccade or pair.stamp < self._settled_at
            if self._ses_dirty:
                self._ses_dirty = False
                rebuild = True
            else:
                rebuild = False
        if rebuild:
            ses = self._new_ses()
            with self._ses_lock:
                self._ses = ses
            with self._lock:
                self._refused.clear()
                self._fixated = None
            self.get_logger().info(f'ego-sphere rebuilt: {self._ses.n_cells} cells, '
                                   f'{self._p["bias"]} bias (memory reset)')
        if in_saccade:                 # saccadic suppression: the image is blurred, poses move
            self.frames_in_saccade += 1
            self._hold(IN_SACCADE)     # not a refusal: the pair is ignored by design
            return
        prepared = self._prepare(pair)
        if prepared is None:
            return
        left, right, rig, ego_left = prepared
        pipe = self._pipeline_for(left.shape[1], left.shape[0])
        frame = pipe.process(left, right, rig, self._window(rig, left.shape[1], left.shape[0]))
        if frame.means.shape[0] == 0:
            self._skip(pair, NO_CORRESPONDENCES, f'rejected {frame.rejected}')
            return
        info = information(frame.covs)                                  # Eq. 3.45
        header = Header(stamp=pair.left.header.stamp, frame_id=pair.left.header.frame_id)
        publish_from_thread(self, self._points_pub,
                            array_to_pointcloud2(points_array(frame, info), header))
        self.input_health.published(self._points_pub.topic_name)
        with self._ses_lock:
            report = self._ses.fuse(frame.means, frame.covs, ego_left)
        self._last_fused_stamp = pair.stamp
        self.last_report = report
        self.frames_fused += 1
        self._accept()
        bad = {k: v for k, v in {**frame.rejected, **report.rejected}.items() if v}
        if bad:
            self.get_logger().debug(f'frame: {report.summary()}; stereo rejected {bad}')
        with self._lock:
            if self._clock_s() >= self._awaiting_saccade_until:
                self._frames_since_settle += 1
            fixated = self._fixated
            if (fixated is not None
                    and self._frames_since_settle >= self._p['frames_per_fixation']):
                cell, seen = fixated
                self._fixated = None
                if self._served and self._ses.n_obs[cell] == seen:
                    # the fixation gave its cell no observation (the eyes sit in front of ego,
                    # so the fixated point may fall in a neighbouring cell): without this, an
                    # unobserved cell keeps its prior and would be chosen for ever
                    self._refused.add(cell)
        self.processing_s.append(time.monotonic() - t0)
        del self.processing_s[:-50]
        if len(self.processing_s) == 50 and self.frames_fused % 50 == 0:
            self.get_logger().info(
                f'{self.frames_fused} frames fused; {1e3 * np.median(self.processing_s):.0f} ms '
                f'per pair (median); {self.pairs_dropped} pairs dropped (newest wins), '
                f'{self.frames_in_saccade} in saccades, {self.frames_skipped} skipped; last: '
                f'{report.summary()}')
        self._decide()

    # --- decision and outputs -------------------------------------------------------------------

    def _clock_s(self) -> float:
        """The node's clock [s]: sim time in the graph (decisions follow the simulation, not
        the machine's speed)."""
        return self.get_clock().now().nanoseconds * 1e-9

    def _decide(self) -> None:
        p = self._p
        if not p['publish_gaze']:
            return
        now = self._clock_s()
        with self._lock:
            ready = (not self._in_saccade and now >= self._awaiting_saccade_until
                     and self._frames_since_settle >= p['frames_per_fixation']
                     and now - self._last_command >= p['decision_period_s'])
        if not ready:
            return
        ses = self._ses
        el = np.radians(p['elevation_limits_deg'])
        candidates = (ses.mean[:, 2] >= p['min_z_m']) & reachable_cells(
            ses.directions, math.radians(p['azimuth_limit_deg']), (el[0], el[1]))
        with self._lock:
            refused = list(self._refused)
        candidates[refused] = False
        if not np.any(candidates):
            self._warn_throttled('decision', 'no reachable cell above min_z_m: no fixation')
            return
        decision = choose_fixation(ses.mean, ses.cov, p['acquisition'], float(p['ucb_alpha']),
                                   candidates=candidates)
        dmin, dmax = p['fixation_distance_m']
        point = decision.fixation
        dist = float(np.linalg.norm(point))
        point = point * (min(max(dist, dmin), dmax) / max(dist, 1e-9))
        cmd = GazeCommand(mode=GazeCommand.MODE_FIXATION_POINT, motion=GazeCommand.MOTION_SACCADE,
                          source=SOURCE, priority=int(p['gaze_priority']),
                          hold_time=float(p['hold_time']))
        cmd.header.frame_id = p['ego_frame']
        cmd.header.stamp = self.get_clock().now().to_msg()
        cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z = (float(v)
                                                                            for v in point)
        publish_from_thread(self, self._gaze_pub, cmd)
        with self._lock:
            self._last_command = now
            self._awaiting_saccade_until = now + SACCADE_START_TIMEOUT_S
            self._frames_since_settle = 0
            self._fixated = (decision.cell, int(ses.n_obs[decision.cell]))
            self._served = False          # a pre-empted command fixated nothing: no refusal
        self.gaze_commands += 1
        self.last_decision = decision
        self.get_logger().debug(f'fixation: cell {decision.cell} at {np.round(point, 3)} '
                                f'(score {decision.score:.4g}, {int(ses.n_obs[decision.cell])} '
                                f'observations)')

    def _on_cells_timer(self) -> None:
        header = Header(stamp=self.get_clock().now().to_msg(), frame_id=self._p['ego_frame'])
        with self._ses_lock:        # not a torn read while the worker fuses
            cells = cells_array(self._ses, not self._p['publish_unobserved_cells'])
        self._cells_pub.publish(array_to_pointcloud2(cells, header))

    def destroy_node(self) -> Any:
        worker = getattr(self, '_worker', None)  # None: __init__ failed before it started
        if worker is not None:
            worker.close()
        return super().destroy_node()


main = main_for(StereoSesNode)


if __name__ == '__main__':
    main()
