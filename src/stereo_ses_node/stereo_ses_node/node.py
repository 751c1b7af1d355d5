"""The `stereo_ses` node (thesis chapter 3): foveated stereo into the Sensory Ego-Sphere, and gaze.

Stereo pairs (paired by stamp) -> core.stereo.StereoPipeline (SGBM, mid-point triangulation,
the Unscented Transform) -> core.ses.SensoryEgoSphere.fuse -> the next fixation (UCB / PI / EI,
core.fixation.next_fixation). Callbacks only store messages; a worker thread processes the newest
pair (rig.py: its set-up). Topics (relative names; graph.yaml remaps them):
  in  left|right/image_raw    sensor_msgs/Image rgb8/bgr8 (RELIABLE keep-last 5)
  in  left|right/camera_info  sensor_msgs/CameraInfo: K of each camera
  in  /tf, /tf_static         ego <- left optical frame and left <- right, at each pair's stamp
  in  gaze/state              active_vision_msgs/GazeState: nothing is fused during a saccade
  out stereo/points           sensor_msgs/PointCloud2: UT points and covariances, left optical frame
  out ses/cells               sensor_msgs/PointCloud2: the ego-sphere's cells in `ego_frame`
  out gaze/command            active_vision_msgs/GazeCommand: the chosen fixation (publish_gaze)
  out /diagnostics            diagnostic_msgs/DiagnosticArray: input health (reasons: messages.py)
Parameters: params.py. See docs/stereo_ses.md for the rest.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

import numpy as np

from stereo_ses_node.core.decision import Decision
from stereo_ses_node.core.fixation import SACCADE_START_TIMEOUT_S, FixationPolicy, next_fixation
from stereo_ses_node.core.information import information
from stereo_ses_node.core.multires import DisparityWindow
from stereo_ses_node.core.pairing import Pair, StereoPairer
from stereo_ses_node.core.ses import FusionReport
from stereo_ses_node.core.stereo import StereoPipeline
from stereo_ses_node.core.ut import StereoRig
from stereo_ses_node.messages import (
    CELLS_TOPIC,
    EYES,
    GAZE_COMMAND_TOPIC,
    GAZE_STATE_TOPIC,
    IMAGE_TOPICS,
    IN_SACCADE,
    INFO_TOPICS,
    NO_CAMERA_POSE,
    NO_CORRESPONDENCES,
    NO_PARTNER,
    PAIR_FAILED,
    POINTS_TOPIC,
    RATE_CAP,
    REPEATED_STAMP,
    SOURCE,
    UNUSABLE_K,
    cells_array,
    gaze_command,
    image_problem,
    pair_problem,
    points_array,
)
from stereo_ses_node.params import (
    PARAMETERS,
    PIPELINE_PARAMETERS,
    SES_PARAMETERS,
    check_all,
    check_parameter,
    new_ses,
)
from stereo_ses_node.rig import (
    REPEATED,
    RESTARTED,
    as_rgb,
    geometry_window,
    new_pipeline,
    stamp_verdict,
    stereo_rig,
)
from vizzy_runtime.convert import array_to_pointcloud2, camera_k, image_to_numpy, stamp_seconds
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
# of a 921 KB image, and a stereo pair needs both images (best effort got 35 of 150 VGA pairs,
# reliable 149: docs/stereo_ses.md).
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
        # an exception in a callback is counted as a refusal of its topic (and logged there)
        self._image_subs = {eye: self.create_subscription(Image, IMAGE_TOPICS[eye], guarded(
            self, 'failed on an image', lambda msg, eye=eye: self._on_image(eye, msg),
            topic=self._image_topics[eye]), STEREO_QOS) for eye in EYES}
        self._info_subs = {eye: self.create_subscription(CameraInfo, INFO_TOPICS[eye], guarded(
            self, 'failed on a camera_info', lambda msg, eye=eye: self._on_camera_info(eye, msg),
            topic=self._info_topics[eye]), STEREO_QOS) for eye in EYES}
        self._gaze_state_sub = self.create_subscription(
            GazeState, GAZE_STATE_TOPIC,
            guarded(self, 'failed on a state', self._on_gaze_state,
                    topic=self._gaze_state_topic), 10)
        # guarded: cells racing with Ctrl-C end spin quietly (ExternalShutdownException)
        self._cells_tick = guarded(self, 'ego-sphere cells failed', self._on_cells_timer)
        self._cells_timer = self.create_timer(1.0 / self._p['cells_rate_hz'], self._cells_tick)
        self._worker = LatestWorker('stereo_ses_worker', self._work)
        p, images, infos = self._p, self._image_subs, self._info_subs
        self.get_logger().info(
            f'stereo on {images["left"].topic_name} + {images["right"].topic_name} (camera info '
            f'{infos["left"].topic_name} + {infos["right"].topic_name}) with a {p["sensor"]} '
            f'sensor of {p["n_rf"]}x{p["n_rf"]} RFs at most {p["max_rate_hz"]:g} Hz -> '
            f'{self._points_pub.topic_name}; ego-sphere of {p["n_cells"]} cells ({p["bias"]} '
            f'bias) in {p["ego_frame"]!r} -> {self._cells_pub.topic_name}; gaze '
            f'{p["acquisition"]} on {self._gaze_pub.topic_name}'
            f'{" alpha " + str(p["ucb_alpha"]) if p["acquisition"] == "ucb" else ""} '
            f'{"on" if p["publish_gaze"] else "off"} (priority {p["gaze_priority"]})')

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
        left, right = as_rgb(left, pair.left.encoding), as_rgb(right, pair.right.encoding)
        try:
            rig, ego_left = stereo_rig(self._tf, self._p['ego_frame'], frames, pair.stamp, k,
                                       TF_WAIT_S)
        except (LookupError, ValueError) as exc:
            self._skip(pair, NO_CAMERA_POSE, f'no usable camera poses: {exc}')
            return None
        return left, right, rig, ego_left

    def _pipeline_for(self, width: int, height: int) -> StereoPipeline:
        with self._lock:
            dirty, self._pipeline_dirty = self._pipeline_dirty, False
        pipe = self._pipeline
        if dirty or pipe is None or (pipe.width, pipe.height) != (width, height):
            pipe = self._pipeline = new_pipeline(self._p, width, height)
            n = int(self._p['n_rf'])
            self.get_logger().info(f'stereo pipeline: {self._p["sensor"]} sensor, {n}x{n} RFs on '
                                   f'{width}x{height} images')
        return pipe

    def _window(self, rig: StereoRig, width: int, height: int) -> DisparityWindow | None:
        """The disparities to search on this pair (None: the fixed SGBM parameters' range)."""
        try:
            return geometry_window(self._p, rig, width, height)
        except ValueError as exc:
            self._warn_throttled('window', f'no disparity window from the geometry ({exc}): '
                                           f'searching the fixed min_disparity/num_disparities')
            return None

    def _repeated(self, pair: Pair) -> bool:
        """Is pair stamped at or before the last fused pair (refused, counted, logged)?"""
        last = self._last_fused_stamp
        verdict = stamp_verdict(pair.stamp, last, self._clock_s())
        if verdict == RESTARTED:   # the clock went back: a restarted simulation or bag
            self.get_logger().info(f'time went back ({self._clock_s():.3f} s < last fused pair '
                                   f'{last:.3f} s): fusing from {pair.stamp:.3f} s on')
            self._last_fused_stamp = -math.inf
        if verdict != REPEATED:
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
            rebuild, self._ses_dirty = self._ses_dirty, False
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
        with self._lock:
            refused = list(self._policy.refused)
            inhibited = self._policy.inhibited_directions(now)
            nearer_than = self._policy.nearest_fixated
        chosen = next_fixation(ses, p, refused, inhibited, nearer_than)
        if chosen is None:
            self._warn_throttled('decision', 'no reachable cell above min_z_m: no fixation')
            return
        decision, point = chosen
        cmd = gaze_command(point, p, self.get_clock().now().to_msg())
        publish_from_thread(self, self._gaze_pub, cmd)
        with self._lock:
            self._policy.fixating(now, decision.cell, ses, point, p)
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
