"""The `foveation` node (thesis chapter 2): smooth foveal vision of the left camera stream.

Topic names are relative (`image_raw`, `camera_info`, `gaze/state` in; `~/image`, ... out); the
graph remaps image_raw and camera_info to the left camera's, so below are the resolved defaults.

Subscribes /vizzy/left/image_raw (sensor data QoS, rgb8 or bgr8), foveates each image at the
current fixation with core.foveation.Foveator (section 2.3.1) and publishes

  /foveation/image             sensor_msgs/Image, same encoding and header as the input
  /foveation/image/compressed  sensor_msgs/CompressedImage, JPEG (cv2.imencode at
                               jpeg_quality), same header; format '<encoding>; jpeg compressed
                               bgr8' as image_transport's compressed transport writes it

Every ~10 s it logs the bandwidth: the foveated frame's JPEG against the raw frame's JPEG at the
same quality (the raw one is encoded only for that one frame, not for every frame).

Fixation: (fixation_u, fixation_v) px, a negative coordinate meaning the image centre. With
follow_gaze, the fixation is the left camera's principal point (from /vizzy/left/camera_info):
the gaze controller points the optical axes at the fixation point of /gaze/state, so that point
projects onto the principal point; for the simulator's ideal cameras this is the image centre,
i.e. the default is already right for a head that fixates.

While /gaze/state says in_saccade, frames are dropped (saccadic suppression) if
suppress_during_saccades (counted in frames_suppressed and as held 'in saccade' on /diagnostics,
not as refusals). /diagnostics turns WARN when no foveated image went out for OUTPUT_STALL_S
although images kept arriving (a saccade that never ends), naming what happened to them.

Refused inputs are counted by vizzy_runtime.input_health.InputHealth (self.input_health; logging
and /diagnostics as its docstring says). The reasons (IMAGE_REASONS, FIXATION_OUTSIDE,
TOO_SMALL_FOR_LEVELS, UNUSABLE_K): on /vizzy/left/image_raw 'unsupported encoding' (not
rgb8/bgr8), 'empty image' (zero width or height), 'too large' (beyond max_width x max_height),
'step shorter than a row', 'size inconsistent with data' (fewer data bytes than height x step),
'fixation outside image', 'too small for levels' (min(width, height) < 2^levels); on
/vizzy/left/camera_info 'unusable K' (not 9 finite values with fx, fy in [1, 1e6] px; the
last good one stays in use); and, for an exception escaping a callback (node_tools.guarded),
'failed on an image: <ExcType>' (or a camera_info, a state). The refused frame is skipped and the
node keeps running.

Recognition (section 2.3.2, Fig. 2.5; core.recognition): at most recognition_rate_hz in the
images' own time (their stamps: sim time in the graph, so a loaded machine recognises the same
frames, later, instead of fewer), the newest frame goes to a worker thread (at most one
recognition in flight; a frame arriving while it is busy replaces the waiting one), which runs
the two passes on the raw frame foveated at the fixation and at each pass-1 box centre, and
publishes

  /foveation/detections        active_vision_msgs/FoveatedDetectionArray, one per pass
                               (pass_index 0, then 1), the frame's header
  /foveation/detections_2d     vision_msgs/Detection2DArray (reliable, depth 10): one Detection2D
                               per pass-2 detection (messages.detection_2d_array), the frame's
                               header; results at most top_k ObjectHypothesisWithPose
  /foveation/overlay           sensor_msgs/Image rgb8 (if publish_overlay), the frame foveated at
                               its fixation with both passes' boxes (core.overlay), its header

and, with saccades_enabled, a GazeCommand on /gaze/command (MODE_FIXATION_POINT,
MOTION_SACCADE, source 'foveation', priority 30, hold_time saccade_hold_time_s) toward the
best pass-2 object: its box centre back-projected through /vizzy/left/camera_info to
saccade_distance_m along the ray, in the frame's frame_id (the optical frame). No command while
in a saccade, for a frame taken before the last saccade began, within saccade_min_interval_s of
the previous one, for a score below saccade_min_score or a box centre within
saccade_min_offset_px of the principal point. model_path / labels_path
(a TorchScript classifier and its labels; the default window model): see parameters.py.
Algorithms live in foveation_node.core; this module only wires them to topics and parameters.
"""

from __future__ import annotations

import math
import time
from typing import Any

import cv2
import numpy as np

from foveation_node.core.fixation import fixation_for, unfoveated
from foveation_node.core.foveation import PYRAMID_SIGMA_1, Foveator  # noqa: F401 (tests)
from foveation_node.core.overlay import draw_overlay
from foveation_node.core.recognition import (
    Classifier,
    Detection,
    ModelError,
    TwoPassResult,
    grid_recognition,
    saccade_target,
    two_pass,
)
from foveation_node.messages import (
    ENCODINGS,
    CompressedImage,
    Detection2DArray,
    FoveatedDetectionArray,
    GazeCommand,
    camera_k,
    compressed_image,
    detection_2d_array,
    detection_array,
    encode_jpeg,
    image_problem,
    k_text,
    overlay_boxes,
    saccade_command,
)
from foveation_node.parameters import (  # noqa: F401 (re-exported: tests and scripts use them)
    CAMERA_INFO_TOPIC,
    COMPRESSED_TOPIC,
    DEFAULT_LABELS,
    DEFAULT_MODEL,
    DETECTIONS_2D_TOPIC,
    DETECTIONS_TOPIC,
    FOVEATOR_PARAMETERS,
    GAZE_COMMAND_TOPIC,
    GAZE_PRIORITY,
    GAZE_SOURCE,
    GAZE_STATE_TOPIC,
    INPUT_TOPIC,
    MODEL_PARAMETERS,
    OUTPUT_TOPIC,
    OVERLAY_TOPIC,
    PARAMETERS,
    check_parameter,
    resolve_path,
)
from vizzy_runtime.convert import IMAGE_REASONS, image_to_numpy, numpy_to_image, stamp_seconds  # noqa: F401 (IMAGE_REASONS re-exported)
from vizzy_runtime.input_health import InputHealth, ThrottledWarnings
from vizzy_runtime.node_tools import (
    LatestWorker,
    declare_parameters,
    guarded,
    has_subscribers,
    main_for,
    publish_from_thread,
)
from vizzy_runtime.rate_gate import RateGate
from vizzy_runtime.ros import Node, message, qos_profile_sensor_data
from vizzy_vision.image_checks import check_fixation
from vizzy_vision.rays import back_project

Image = message('sensor_msgs/msg/Image')
CameraInfo = message('sensor_msgs/msg/CameraInfo')
GazeState = message('active_vision_msgs/msg/GazeState')

# Refusal reasons (InputHealth counter keys: short and stable; the values go in the detail).
FIXATION_OUTSIDE = 'fixation outside image'
TOO_SMALL_FOR_LEVELS = 'too small for levels'
UNUSABLE_K = 'unusable K'
IN_SACCADE = 'in saccade'        # held, not refused: saccadic suppression
# A saccade lasts well under a second: no foveated image this long while images arrive is a stall.
OUTPUT_STALL_S = 3.0
BANDWIDTH_LOG_PERIOD_S = 10.0
WARN_PERIOD_S = 5.0


class FoveationNode(Node):
    """Foveates left images at the fixation; publishes them raw and as JPEG."""

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__('foveation', **node_kwargs)
        self._p = declare_parameters(self, PARAMETERS, check_parameter,
                                     on_change=self._on_parameters_changed)
        self._foveator: Foveator | None = None
        self._in_saccade = False
        self._principal_point: tuple[float, float] | None = None
        self._warn_throttled = ThrottledWarnings(self, WARN_PERIOD_S)  # what is no refusal
        # refused inputs, per topic and reason; /diagnostics (before any subscription)
        self.input_health = InputHealth(self)
        self.frames_published = 0
        self.frames_suppressed = 0
        self._last_bandwidth_log = -math.inf
        self.last_bandwidth: tuple[int, int] | None = None   # (foveated, raw) JPEG bytes

        self._pub = self.create_publisher(Image, OUTPUT_TOPIC, qos_profile_sensor_data)
        self._jpeg_pub = self.create_publisher(CompressedImage, COMPRESSED_TOPIC,
                                               qos_profile_sensor_data)
        # resolved names, for log lines
        self._image_topic = self.resolve_topic_name(INPUT_TOPIC)
        self._info_topic = self.resolve_topic_name(CAMERA_INFO_TOPIC)
        self._gaze_state_topic = self.resolve_topic_name(GAZE_STATE_TOPIC)
        self.input_health.watch_output(self._jpeg_pub.topic_name, [self._image_topic],
                                       OUTPUT_STALL_S)
        # an exception in a callback is counted as a refusal of its topic (and logged there)
        self._image_sub = self.create_subscription(
            Image, INPUT_TOPIC,
            guarded(self, 'failed on an image', self._on_image, topic=self._image_topic),
            qos_profile_sensor_data)
        self._gaze_state_sub = self.create_subscription(
            GazeState, GAZE_STATE_TOPIC,
            guarded(self, 'failed on a state', self._on_gaze_state,
                    topic=self._gaze_state_topic), 10)
        self._info_sub = self.create_subscription(
            CameraInfo, CAMERA_INFO_TOPIC,
            guarded(self, 'failed on a camera_info', self._on_camera_info,
                    topic=self._info_topic),
            qos_profile_sensor_data)
        p = self._p
        self.get_logger().info(
            f'foveating {"/".join(ENCODINGS)} images from {self._image_sub.topic_name} (camera '
            f'info {self._info_sub.topic_name}, gaze {self._gaze_state_sub.topic_name}) onto '
            f'{self._pub.topic_name} and {self._jpeg_pub.topic_name}: {p["levels"]} levels, '
            f'f0 {p["f0"]:g} px, sigma_1 '
            f'{p["sigma_1"]:.4g} px, JPEG quality {p["jpeg_quality"]}')

        # recognition (Fig. 2.5) in a worker thread; saccades on /gaze/command
        self._camera_k: tuple[float, ...] | None = None
        self._camera_size: tuple[int, int] | None = None
        self._saccade_epoch = 0                 # +1 whenever a saccade starts
        self._last_saccade = -math.inf          # node clock [s] of our last command
        self._recognition_gate = RateGate()    # recognition_rate_hz in the frames' stamps
        self._classifier: Classifier | None = None
        self._rec_foveator: Foveator | None = None
        self.recognitions = 0
        self.last_result: TwoPassResult | None = None
        self.last_recognition_ms: float | None = None
        self.saccades_sent = 0
        self._det_pub = self.create_publisher(FoveatedDetectionArray, DETECTIONS_TOPIC, 10)
        self._det2d_pub = self.create_publisher(Detection2DArray, DETECTIONS_2D_TOPIC, 10)
        self._overlay_pub = self.create_publisher(Image, OVERLAY_TOPIC, qos_profile_sensor_data)
        self._gaze_pub = self.create_publisher(GazeCommand, GAZE_COMMAND_TOPIC, 10)
        self._load_classifier()
        recognise = guarded(self, 'recognition failed on a frame', self.recognise)
        self._worker = LatestWorker('foveation_recognition', lambda job: recognise(*job))

    def destroy_node(self) -> Any:
        worker = getattr(self, '_worker', None)  # None: __init__ failed before it started
        if worker is not None:
            worker.close()
        return super().destroy_node()

    # --- inputs ---------------------------------------------------------------------------------

    def _on_parameters_changed(self, changed: dict[str, Any]) -> None:
        if any(name in changed for name in FOVEATOR_PARAMETERS):
            self._foveator = None   # rebuilt on the next frame, for that frame's size
        if any(name in changed for name in MODEL_PARAMETERS):
            self._load_classifier()

    def _load_classifier(self) -> None:
        """(Re)load model_path + labels_path; on failure log why and leave recognition off."""
        self._classifier = None
        model, labels = self._p['model_path'], self._p['labels_path']
        if not model:
            self.get_logger().info('model_path is empty: recognition off')
            return
        try:
            import torch
            torch.set_num_threads(self._p['recognition_threads'])
            classifier = Classifier(resolve_path(model), resolve_path(labels))
        except (ModelError, OSError) as exc:
            self.get_logger().error(f'recognition off: {exc}')
            return
        self._classifier = classifier
        w, h = classifier.preprocessing.input_size
        saccades = (', saccades on ' + self._gaze_pub.topic_name if self._p['saccades_enabled']
                    else '')
        self.get_logger().info(
            f'recognising {classifier.num_classes} classes ({", ".join(classifier.labels[:8])}'
            f'{", ..." if classifier.num_classes > 8 else ""}) with {model} at {w}x{h}, top-'
            f'{self._p["top_k"]}, th {self._p["saliency_threshold"]:g}, at most '
            f'{self._p["recognition_rate_hz"]:g} Hz; detections on {self._det_pub.topic_name} '
            f'and {self._det2d_pub.topic_name}{saccades}')

    def _on_gaze_state(self, msg: Any) -> None:
        in_saccade = bool(msg.in_saccade)
        if in_saccade and not self._in_saccade:
            self._saccade_epoch += 1            # frames from before it are stale for saccades
        self._in_saccade = in_saccade
        self.input_health.accept(self._gaze_state_topic)

    def _on_camera_info(self, msg: Any) -> None:
        k = camera_k(msg)
        if k is None:       # the last usable one (if any) stays in use
            self.input_health.refuse(self._info_topic, UNUSABLE_K, k_text(msg.k))
            return
        self._principal_point = (k[2], k[5])
        self._camera_k = k
        self._camera_size = (int(msg.width), int(msg.height))
        self.input_health.accept(self._info_topic)


    def _fixation(self, width: int, height: int) -> tuple[float, float]:
        if self._p['follow_gaze'] and self._principal_point is not None:
            return check_fixation(self._principal_point, width, height)
        return fixation_for(width, height, self._p['fixation_u'], self._p['fixation_v'])

    def _get_foveator(self, width: int, height: int) -> Foveator:
        fov = self._foveator
        if fov is None or (fov.width, fov.height) != (width, height):
            fov = Foveator(width, height, self._p['levels'], self._p['f0'], self._p['sigma_1'])
            self._foveator = fov
        return fov

    def _on_image(self, msg: Any) -> None:
        if self._in_saccade and self._p['suppress_during_saccades']:
            self.frames_suppressed += 1
            self.input_health.hold(self._image_topic, IN_SACCADE)
            return
        problem = image_problem(msg, self._p['max_width'], self._p['max_height'])
        if problem:
            self.input_health.refuse(self._image_topic, *problem)
            return
        image = image_to_numpy(msg)
        height, width = image.shape[:2]
        try:
            fixation = self._fixation(width, height)
        except ValueError as exc:
            self.input_health.refuse(self._image_topic, FIXATION_OUTSIDE, str(exc))
            return
        try:
            foveator = self._get_foveator(width, height)
        except ValueError as exc:   # the parameters are checked: only min(W, H) < 2^levels
            self.input_health.refuse(self._image_topic, TOO_SMALL_FOR_LEVELS, str(exc))
            return
        out = foveator.foveate(image, fixation) if self._p['space_variant'] else image
        if has_subscribers(self._pub):       # the uncompressed copy: 0.9 MB a frame at VGA
            self._pub.publish(numpy_to_image(out, msg.encoding, header=msg.header))

        quality = self._p['jpeg_quality']
        jpeg = encode_jpeg(out, msg.encoding, quality)
        self._jpeg_pub.publish(compressed_image(msg.header, msg.encoding, jpeg))
        self.input_health.published(self._jpeg_pub.topic_name)
        self.frames_published += 1
        self.input_health.accept(self._image_topic)
        self._report_bandwidth(image, msg.encoding, len(jpeg), quality, fixation)
        self._offer_recognition(image, out, msg, fixation)

    # --- recognition ----------------------------------------------------------------------------

    def _offer_recognition(self, image: np.ndarray, foveated: np.ndarray, msg: Any,
                           fixation: tuple[float, float]) -> None:
        """Hand the frame (and its foveated image: pass 1's) to the worker, replacing one still
        waiting, at most at the rate."""
        if self._classifier is None:
            return
        # in the images' own time: a slower machine recognises the same frames, later
        if not self._recognition_gate.take(stamp_seconds(msg.header.stamp),
                                           self._p['recognition_rate_hz']):
            return
        # image may view msg's buffer: keep msg alive with it
        self._worker.put((image, msg, fixation, self._saccade_epoch, foveated))

    def _recognition_foveator(self, width: int, height: int) -> Foveator:
        p = self._p
        key = (width, height, p['levels'], p['f0'], p['sigma_1'])
        fov = self._rec_foveator
        if fov is None or (fov.width, fov.height, fov.levels, fov.f0, fov.sigma_1) != key:
            fov = Foveator(width, height, p['levels'], p['f0'], p['sigma_1'])
            self._rec_foveator = fov
        return fov

    def recognise(self, image: np.ndarray, msg: Any, fixation: tuple[float, float],
                  epoch: int, foveated: np.ndarray | None = None) -> TwoPassResult | None:
        """Both passes of Fig. 2.5 on one frame; publish them and maybe saccade (worker thread).
        foveated: the frame foveated at fixation, if the caller has it (pass 1's image)."""
        classifier = self._classifier
        if classifier is None:
            return None
        t0 = time.perf_counter()
        rgb = image if msg.encoding == 'rgb8' else cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
        # foveation treats the channels alike: the foveated BGR frame, reordered, is pass 1's
        first = (None if foveated is None or not self._p['space_variant']
                 else foveated if msg.encoding == 'rgb8'
                 else cv2.cvtColor(foveated, cv2.COLOR_BGR2RGB))
        height, width = rgb.shape[:2]
        try:
            foveator = self._recognition_foveator(width, height)
        except ValueError as exc:
            self._warn_throttled('recognition', f'recognition skipped: {exc}')
            return None
        foveate = foveator.foveate if self._p['space_variant'] else unfoveated
        if not self._p['space_variant'] and classifier.window:
            # uniform resolution everywhere: the window model on a grid over the whole frame
            found, _ = grid_recognition(classifier, rgb, int(self._p['uniform_stride_px']))
            result = TwoPassResult(found, [], np.zeros(classifier.num_classes))
        else:
            result = two_pass(classifier, rgb, fixation, foveate, self._p['top_k'],
                              self._p['saliency_threshold'], first_image=first,
                              foveate_many=foveator.foveate_many
                              if self._p['space_variant'] else None)
        self.last_recognition_ms = 1000.0 * (time.perf_counter() - t0)
        for detections in (result.first, result.second):
            publish_from_thread(self, self._det_pub,
                                detection_array(msg.header, fixation, self._p['f0'], detections))
        publish_from_thread(self, self._det2d_pub, detection_2d_array(
            msg.header, result.second, result.probs_second, classifier.labels, self._p['top_k']))
        if self._p['publish_overlay'] and has_subscribers(self._overlay_pub):
            boxes = overlay_boxes([*result.first, *result.second])
            drawn = draw_overlay(foveate(rgb, fixation) if first is None else first,
                                 boxes, fixation, float(self._p['f0']))
            publish_from_thread(self, self._overlay_pub,
                                numpy_to_image(drawn, 'rgb8', header=msg.header))
        self.recognitions += 1
        self.last_result = result
        self._maybe_saccade(result.second, msg.header.frame_id, epoch, width, height)
        return result

    def _maybe_saccade(self, detections: list[Detection], frame_id: str, epoch: int,
                       width: int, height: int) -> None:
        """A saccade GazeCommand toward the best detection, unless a rule says not now."""
        p = self._p
        if not p['saccades_enabled'] or self._in_saccade or epoch != self._saccade_epoch:
            return                                   # eyes moving, or moved since the frame
        now = self.get_clock().now().nanoseconds * 1e-9      # sim time in the graph
        if 0.0 <= now - self._last_saccade < p['saccade_min_interval_s']:
            return
        k = self._camera_k
        if k is None or self._camera_size != (width, height):
            self._warn_throttled('camera_info', f'no saccade: no {self._info_topic} for '
                                 f'{width}x{height} images yet (have {self._camera_size})')
            return
        if not frame_id:
            self._warn_throttled(
                'frame', f'no saccade: the image from {self._image_topic} has no frame_id')
            return
        target = saccade_target(detections, (k[2], k[5]), p['saccade_min_score'],
                                p['saccade_min_offset_px'])
        if target is None:
            return
        u, v = target.centre
        x, y, z = back_project(u, v, k, p['saccade_distance_m'])
        cmd = saccade_command(self.get_clock().now().to_msg(), frame_id, (x, y, z), GAZE_SOURCE,
                              GAZE_PRIORITY, p['saccade_hold_time_s'])
        publish_from_thread(self, self._gaze_pub, cmd)
        self._last_saccade = now
        self.saccades_sent += 1
        self.get_logger().info(
            f'saccade to {target.label} ({target.score:.2f}) at ({u:.0f}, {v:.0f}) px: '
            f'({x:.3f}, {y:.3f}, {z:.3f}) m in {frame_id}')

    def _report_bandwidth(self, image: np.ndarray, encoding: str, foveated_bytes: int,
                          quality: int, fixation: tuple[float, float]) -> None:
        """Every BANDWIDTH_LOG_PERIOD_S: this frame's JPEG size, foveated vs raw."""
        now = time.monotonic()
        if now - self._last_bandwidth_log < BANDWIDTH_LOG_PERIOD_S:
            return
        self._last_bandwidth_log = now
        raw_bytes = len(encode_jpeg(image, encoding, quality))
        self.last_bandwidth = (foveated_bytes, raw_bytes)
        saved = 100.0 * (1.0 - foveated_bytes / raw_bytes) if raw_bytes else 0.0
        height, width = image.shape[:2]
        self.get_logger().info(
            f'bandwidth: {width}x{height} JPEG q{quality}: foveated {foveated_bytes} B vs raw '
            f'{raw_bytes} B ({saved:.0f}% saved), f0 {self._p["f0"]:g} px at '
            f'({fixation[0]:g}, {fixation[1]:g}); {self.frames_published} frames published, '
            f'{self.frames_suppressed} suppressed during saccades')


main = main_for(FoveationNode)


if __name__ == '__main__':
    main()
