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
logging and /diagnostics as its docstring says); the reasons (counter keys): messages.py.
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
from typing import Any

import numpy as np

from stereo_ses_node.core.decision import Decision, choose_fixation
from stereo_ses_node.core.fixation import (
    SACCADE_START_TIMEOUT_S,
    FixationPolicy,
    clamp_distance,
    fixation_candidates,
)
from stereo_ses_node.core.information import information
from stereo_ses_node.core.multires import DisparityWindow, disparity_window
from stereo_ses_node.core.pairing import Pair, StereoPairer
from stereo_ses_node.core.ses import FusionReport
from stereo_ses_node.core.stereo import SGBMParams, StereoPipeline
from stereo_ses_node.core.ut import StereoRig, UTParams
from stereo_ses_node.messages import (  # noqa: F401 (re-exported: tests read the node's counter
    # keys, topics, message builders and parameter table through this module)
    CELL_DTYPE,
    CELLS_TOPIC,
    ENCODINGS,
    EYES,
    GAZE_COMMAND_TOPIC,
    GAZE_STATE_TOPIC,
    IMAGE_TOPICS,
    IN_SACCADE,
    INFO_SIZE_MISMATCH,
    INFO_TOPICS,
    NO_CAMERA_INFO,
    NO_CAMERA_POSE,
    NO_CORRESPONDENCES,
    NO_FRAME_ID,
    NO_PARTNER,
    PAIR_FAILED,
    PAIR_REASONS,
    POINT_DTYPE,
    POINTS_TOPIC,
    RATE_CAP,
    REPEATED_STAMP,
    SIZES_DIFFER,
    SOURCE,
    UNUSABLE_K,
    cells_array,
    gaze_command,
    image_problem,
    pair_problem,
    points_array,
)
from stereo_ses_node.params import (  # noqa: F401
    BIAS_NAMES,
    DISPARITY_RANGES,
    PARAMETERS,
    PIPELINE_PARAMETERS,
    SENSORS,
    SES_PARAMETERS,
    check_all,
    check_parameter,
    new_ses,
    user_gmm,
)
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
    image_to_numpy,
    stamp_seconds,
)
from vizzy_runtime.input_health import InputHealth, ThrottledWarnings
from vizzy_runtime.node_tools import (
    LatestWorker,
    declare_parameters,
    guarded,
    main_for,
    publish_from_thread,
    replace_timer,
)
from vizzy_runtime.rate_gate import RateGate
from vizzy_runtime.ros import ExternalShutdownException, Node, QoSProfile, message
from vizzy_runtime.tf import TransformBuffer, TransformListener

Header = message('std_msgs/msg/Header')
Image = message('sensor_msgs/msg/Image')
CameraInfo = message('sensor_msgs/msg/CameraInfo')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')
GazeCommand = message('active_vision_msgs/msg/GazeCommand')
GazeState = message('active_vision_msgs/msg/GazeState')

# Reliable, not sensor data (REP 2003's default): a best-effort reader never repairs a lost fragment
# of a 921 KB image, and a stereo pair needs both images (module docstring).
STEREO_QOS = QoSProfile(depth=5)
# The worker waits this long [s] for the /tf that covers a pair's stamp (it may arrive just after
# the images); then the pair is skipped ('no camera pose').
TF_WAIT_S = 0.5
# /stereo/points silent this long (node clock) while images arrive: a /diagnostics WARN
OUTPUT_STALL_S = 3.0
WARN_PERIOD_S = 5.0                        # throttle of the warnings that are no refusals


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
        self._pairer = StereoPairer(lambda m: stamp_seconds(m.header.stamp))
        self._unpaired = self._pairer.unpaired     # waiting per eye, oldest first
        self._k: dict[str, np.ndarray] = {}
        self._info_size: dict[str, tuple[int, int]] = {}
        self._policy = FixationPolicy(SOURCE)   # saccades, decision timing, refused cells
        self._pair_gate = RateGate()                  # max_rate_hz in the pairs' stamps
        self._pipeline: StereoPipeline | None = None
        self._pipeline_dirty = False
        self._ses = new_ses(self._p)
        self._ses_dirty = False
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

    # the policy's state, as tests read (and set) it on the node
    @property
    def _in_saccade(self) -> bool:
        return self._policy.in_saccade

    @property
    def _refused(self) -> set[int]:
        return self._policy.refused

    @property
    def _frames_since_settle(self) -> int:
        return self._policy.frames_since_settle

    @_frames_since_settle.setter
    def _frames_since_settle(self, value: int) -> None:
        self._policy.frames_since_settle = value

    # --- set-up ---------------------------------------------------------------------------------

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
            self._policy.on_gaze_state(bool(msg.in_saccade), msg.active_source,
                                       stamp_seconds(msg.header.stamp))
        self.input_health.accept(self._gaze_state_topic)
        if msg.status in (GazeState.STATUS_REJECTED_NAN, GazeState.STATUS_REJECTED_UNKNOWN_FRAME,
                          GazeState.STATUS_REJECTED_UNREACHABLE,
                          GazeState.STATUS_REJECTED_INVALID) and self.last_decision is not None \
                and self._clock_s() - self._policy.last_command < SACCADE_START_TIMEOUT_S:
            # the status of the command just sent (the controller answers at once)
            with self._lock:        # not chosen again (until the ego-sphere is rebuilt)
                self._policy.refused.add(self.last_decision.cell)
            self._warn_throttled('gaze_status', f'{self._gaze_state_topic}: a gaze command was '
                                                f'refused: {msg.status_message}')

    def _on_image(self, eye: str, msg: Any) -> None:
        problem = image_problem(msg)
        if problem:
            self.input_health.refuse(self._image_topics[eye], *problem)
            return
        t = stamp_seconds(msg.header.stamp)
        skew = self._p['max_stamp_skew_s']
        with self._lock:
            pair, unpaired = self._pairer.add(eye, msg, skew)
            if pair is not None:
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
        with self._lock:
            k = dict(self._k)
            sizes = dict(self._info_size)
        frames = {e: getattr(pair, e).header.frame_id for e in EYES}
        problem = pair_problem(left.shape, right.shape, k, sizes, frames, self._info_topics)
        if problem:
            self._skip(pair, *problem)
            return None
        # the pipeline's colours and grey conversion expect RGB
        left = left[..., ::-1] if pair.left.encoding == 'bgr8' else left
        right = right[..., ::-1] if pair.right.encoding == 'bgr8' else right
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
            in_saccade = self._policy.suppressed(pair.stamp)
            if self._ses_dirty:
                self._ses_dirty = False
                rebuild = True
            else:
                rebuild = False
        if rebuild:
            ses = new_ses(self._p)
            with self._ses_lock:
                self._ses = ses
            with self._lock:
                self._policy.reset()
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
            self._policy.on_fused(self._clock_s(), self._p['frames_per_fixation'],
                                  self._ses.n_obs)
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
            ready = self._policy.ready(now, p['frames_per_fixation'], p['decision_period_s'])
        if not ready:
            return
        ses = self._ses
        el = np.radians(p['elevation_limits_deg'])
        with self._lock:
            refused = list(self._policy.refused)
        candidates = fixation_candidates(ses.mean, ses.directions, p['min_z_m'],
                                         math.radians(p['azimuth_limit_deg']), (el[0], el[1]),
                                         refused)
        if not np.any(candidates):
            self._warn_throttled('decision', 'no reachable cell above min_z_m: no fixation')
            return
        decision = choose_fixation(ses.mean, ses.cov, p['acquisition'], float(p['ucb_alpha']),
                                   candidates=candidates)
        dmin, dmax = p['fixation_distance_m']
        point = clamp_distance(decision.fixation, dmin, dmax)
        cmd = gaze_command(point, p, self.get_clock().now().to_msg())
        publish_from_thread(self, self._gaze_pub, cmd)
        with self._lock:
            self._policy.commanded(now, decision.cell, int(ses.n_obs[decision.cell]))
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
