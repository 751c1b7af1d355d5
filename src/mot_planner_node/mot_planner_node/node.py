"""The `mot_planner` node (thesis chapter 5): multiple object tracking with an attention budget.

Topic names are relative (in: `image_raw`, `camera_info`, `gaze/state`, `tf`); the graph remaps
the inputs to the left camera's, so below are the resolved defaults.

Subscribes /vizzy/left/image_raw (sensor data QoS, rgb8 or bgr8) and /vizzy/left/camera_info
(intrinsics for the gaze ray and ego-motion), /gaze/state (saccades) and /tf, /tf_static (the
camera's pose, for ego-motion and world-frame gaze). Each image goes through
core.tracker.MotTracker: predict every belief, plan at most k_max regions covering at most
s_max of the image with MCTS within budget_ms, run the detector (HOG by default) only in those
regions, associate and update. New tracks are born from full-frame detections paid from the
S_max budget (core.tracker, new_tracks='budget', the deployed configuration that `evaluate`
also uses by default): the regions may read (1 - birth_share) S_max of the image per frame,
the rest is saved, and a full frame is read once the savings pay for it and at least
full_frame_period frames have passed (and on the first frame). It publishes

  /mot/tracks     active_vision_msgs/TrackArray: the confirmed tracks, image header
  /mot/attention  active_vision_msgs/AttentionRegions: the regions processed this frame and
                  their tracks; budget_fraction is the share of the image the detector read
                  (union of the regions); a full-frame detection is one image-sized region
                  with track_id 0 and budget_fraction 1.0
  /mot/overlay    sensor_msgs/Image rgb8 (if publish_overlay): the image with attended regions
                  (yellow; cyan for a full frame) and track boxes with ids (green)
  /gaze/command   active_vision_msgs/GazeCommand, MOTION_PURSUIT at gaze_priority from source
                  'mot_planner', at most gaze_rate_hz, only while established tracks exist
                  (below), not during a saccade: the fixation point is gaze_depth_m along the
                  ray through their mean centre (needs camera_info), in world_frame through
                  the camera's pose at the image's stamp, or in the image's frame_id when that
                  pose is unknown
  /diagnostics    diagnostic_msgs/DiagnosticArray, about 1 Hz: the node's input health (below)

Ego-motion: with ego_motion on, the node keeps the image frame's orientation in world_frame
(base_link: the waist, which never moves) from /tf and /tf_static, interpolated at each
image's stamp; between two processed images the camera's rotation R gives the pure-rotation
homography H = K R K^-1 (core.egomotion) that moves every belief before prediction, so a
saccade or pursuit step does not throw the tracks out of their search regions. No camera_info
or no transform at all: that frame is tracked without compensation (logged once); when /tf
has no sample around the image's stamp the latest transform stands in for it.

Gaze: only tracks detected at least gaze_min_hits times and at least gaze_min_age frames old
steer the head (a bootstrap detection is a track at once, and a one-off false positive must
not pull the head around), and, with person_check, only tracks that plausibly are people
(core.ground_plane): the ray through the bottom centre of the box meets the floor (floor_z_m
in world_frame) where a person standing there would have a height in person_height_m, on
each of the track's last person_check_frames frames, varying by at most person_height_ratio
(max/min) over them. Objects on a table that the detector
takes for people (HOG on the tabletop scene) imply 0.5-1.2 m, or heights that wander as the
head moves. Such tracks are still tracked and published, with label 'person_implausible'
instead of 'person', and drawn grey in the overlay. Without camera_info or the camera's pose
the check is skipped (logged once).

Rate: with max_rate_hz > 0 the node tracks at most that many frames per second of the images'
stamps (every other frame at half the camera's rate) and drops the others before any work
(frames_skipped): HOG is most of a frame's cost, and the graph's 15 Hz camera is faster than the
tracker needs (the graph runs it at 7.5 Hz).

Track velocities are converted from px/frame to px/s with the frame period measured from the
image stamps (NOMINAL_FPS until two stamped frames arrived). A frame size change resets the
tracker with a warning and bootstraps on the new size.

Refused inputs are counted by vizzy_runtime.input_health.InputHealth (self.input_health; logging
and /diagnostics as its docstring says). The reasons (counter keys; IMAGE_REASONS,
UNUSABLE_FRAME, UNUSABLE_K): on /vizzy/left/image_raw 'unsupported encoding' (not rgb8/bgr8),
'empty image' (zero width or height), 'step shorter than a row', 'size inconsistent with data'
(fewer data bytes than height x step), 'smaller than the detector window' (no person fits: such
a frame does not reset the tracker as a new size would), 'unusable frame' (the tracker's
FrameError); on /vizzy/left/camera_info 'unusable K' (not 9 finite values with fx, fy in
[1, 1e6] px; the last good one stays in use); and, for an exception escaping a callback
(node_tools.guarded), 'failed on an image: <ExcType>' (or a camera_info, a state). A refused
image is dropped (frames_dropped), the tracks untouched. Changing k_max, s_max, alpha_c, alpha_s
or budget_ms keeps the tracks; changing a detector setting restarts the tracker.

The detector comes from the module-level DETECTOR_FACTORY(params) (HOG from the detector
parameters); tests replace it with a stub that needs no real people.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from mot_planner_node import messages
from mot_planner_node.core.bookkeeping import FramePeriod, TrackBook, gaze_point
from mot_planner_node.core.detector import Detector
from mot_planner_node.core.egomotion import rotation_between, rotation_homography
from mot_planner_node.core.ground_plane import ConsistencyGate, implied_size
from mot_planner_node.core.tracker import FrameError, FrameResult, MotTracker, deployed_config
from mot_planner_node.messages import (  # noqa: F401  re-exported: labels, input checks
    ENCODINGS,
    LABEL_IMPLAUSIBLE,
    LABEL_PERSON,
    SOURCE,
    AttentionRegions,
    GazeCommand,
    TrackArray,
    _k_text,
    camera_k,
    image_problem,
)
from mot_planner_node.parameters import (  # noqa: F401  re-exported: the node's parameter table
    DETECTOR_PARAMETERS,
    FLOOR_Z_M,
    GAZE_COMMAND_TOPIC,
    MIN_RATE_HZ,
    OVERLAY_TOPIC,
    PARAMETERS,
    PERSON_PARAMETERS,
    PLANNER_PARAMETERS,
    TRACK_PARAMETERS,
    check_parameter,
    make_hog_detector,
    planner_config,
    track_settings,
)
from vizzy_runtime.convert import (  # noqa: F401  the image reasons: this node's counter keys too
    EMPTY_IMAGE,
    IMAGE_REASONS,
    SHORT_DATA,
    SHORT_STEP,
    TOO_LARGE,
    UNCONVERTIBLE,
    UNSUPPORTED_ENCODING,
    ConversionError,
    image_to_numpy,
    numpy_to_image,
    stamp_seconds,
)
from vizzy_runtime.input_health import InputHealth, ThrottledWarnings
from vizzy_runtime.node_tools import declare_parameters, guarded, has_subscribers, main_for
from vizzy_runtime.rate_gate import RateGate
from vizzy_runtime.ros import Node, message, qos_profile_sensor_data
from vizzy_runtime.tf import FramePoses, TransformBuffer, TransformListener

Image = message('sensor_msgs/msg/Image')
CameraInfo = message('sensor_msgs/msg/CameraInfo')
GazeState = message('active_vision_msgs/msg/GazeState')

# Relative names: the graph remaps the generic inputs (image_raw:=vizzy/left/image_raw, ...) and
# the node's namespace places everything; logs print the resolved names.
IMAGE_TOPIC = 'image_raw'
CAMERA_INFO_TOPIC = 'camera_info'
GAZE_STATE_TOPIC = 'gaze/state'
TRACKS_TOPIC = 'mot/tracks'
ATTENTION_TOPIC = 'mot/attention'
# Refusal reasons (InputHealth counter keys: short and stable; the values go in the detail).
UNUSABLE_FRAME = 'unusable frame'
SMALLER_THAN_WINDOW = 'smaller than the detector window'
UNUSABLE_K = 'unusable K'
RATE_CAP = 'max_rate_hz'           # held, not refused: frames beyond the rate cap
# /mot/tracks silent this long (node clock) while images arrive: a diagnostics WARN
OUTPUT_STALL_S = 3.0
NOMINAL_FPS = 30.0
WARN_PERIOD_S = 5.0
TF_HISTORY_S = 2.0
# max_rate_hz at half the camera's rate takes every other frame, their stamps rounded or not
RATE_SLACK = 0.1


#: params -> Detector. Module-level so that a test (or an integrator) can plug in another one.
DETECTOR_FACTORY: Callable[[dict[str, Any]], Detector] = make_hog_detector


class MotPlannerNode(Node):
    """Tracks people in the left image under an attention budget; publishes tracks and regions."""

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__('mot_planner', **node_kwargs)
        self._p = declare_parameters(self, PARAMETERS, check_parameter,
                                     on_change=self._on_parameters_changed)
        self._tracker = self._new_tracker()
        self._warn_throttled = ThrottledWarnings(self, WARN_PERIOD_S)  # what is no refusal
        # refused inputs, per topic and reason; /diagnostics (before any subscription)
        self.input_health = InputHealth(self)
        self._in_saccade = False
        self._k: list[float] | None = None
        self._frame_period = FramePeriod(1.0 / NOMINAL_FPS)
        self._book = TrackBook()                 # track ages and frames_lost
        self._last_gaze = -math.inf
        self._persons = self._person_gate()
        self.last_implied_heights: dict[int, float] = {}    # track id -> [m], last check
        self._tf = TransformBuffer()
        # the camera's pose in world_frame at each /tf stamp (ego-motion at the image's stamp)
        self._poses = FramePoses(self._tf, self._p['world_frame'], max_age_s=TF_HISTORY_S)
        self._last_pose: np.ndarray | None = None   # camera in world_frame at the last frame
        self._noted: set[str] = set()
        self.frames_processed = 0
        self.frames_compensated = 0
        self.last_ego_rotation_deg = 0.0
        self.frames_dropped = 0
        self.frames_skipped = 0                  # over max_rate_hz
        self._rate_gate = RateGate(slack=RATE_SLACK)
        self.resets = 0
        self.gaze_commands = 0

        self._tracks_pub = self.create_publisher(TrackArray, TRACKS_TOPIC, 10)
        self._attention_pub = self.create_publisher(AttentionRegions, ATTENTION_TOPIC, 10)
        self._overlay_pub = self.create_publisher(Image, OVERLAY_TOPIC, qos_profile_sensor_data)
        self._gaze_pub = self.create_publisher(GazeCommand, GAZE_COMMAND_TOPIC, 10)
        # resolved names, for log lines
        self._image_topic = self.resolve_topic_name(IMAGE_TOPIC)
        self.input_health.watch_output(self._tracks_pub.topic_name, [self._image_topic],
                                       self._output_stall_s)
        self._info_topic = self.resolve_topic_name(CAMERA_INFO_TOPIC)
        self._gaze_state_topic = self.resolve_topic_name(GAZE_STATE_TOPIC)
        # an exception in a callback is counted as a refusal of its topic (and logged there)
        self._image_sub = self.create_subscription(
            Image, IMAGE_TOPIC,
            guarded(self, 'failed on an image', self._on_image, topic=self._image_topic),
            qos_profile_sensor_data)
        self._info_sub = self.create_subscription(
            CameraInfo, CAMERA_INFO_TOPIC,
            guarded(self, 'failed on a camera_info', self._on_camera_info,
                    topic=self._info_topic),
            qos_profile_sensor_data)
        self._gaze_state_sub = self.create_subscription(
            GazeState, GAZE_STATE_TOPIC,
            guarded(self, 'failed on a state', self._on_gaze_state,
                    topic=self._gaze_state_topic), 10)
        # each /tf message also records the camera's pose at its stamp (ego-motion)
        self._tf_listener = TransformListener(self._tf, self, on_update=self._on_tf)
        p = self._p
        self.get_logger().info(
            f'tracking people in {self._image_sub.topic_name} (camera info '
            f'{self._info_sub.topic_name}) onto {self._tracks_pub.topic_name}, '
            f'{self._attention_pub.topic_name}'
            f'{", " + self._overlay_pub.topic_name if p["publish_overlay"] else ""}, gaze on '
            f'{self._gaze_pub.topic_name}: k_max={p["k_max"]}, '
            f's_max={p["s_max"]}, budget {p["budget_ms"]} ms, full frame every '
            f'{p["full_frame_period"]} frames; gaze priority {p["gaze_priority"]}')

    # --- set-up and inputs ------------------------------------------------------------------

    def _new_tracker(self) -> MotTracker:
        cfg = deployed_config(planner_config(self._p), horizon=int(self._p['horizon']),
                              **track_settings(self._p))
        return MotTracker(DETECTOR_FACTORY(dict(self._p)), cfg)

    def _person_gate(self) -> ConsistencyGate:
        p = self._p
        return ConsistencyGate(tuple(p['person_height_m']), int(p['person_check_frames']),
                               float(p['person_height_ratio']))

    def _on_parameters_changed(self, changed: dict[str, Any]) -> None:
        if 'world_frame' in changed:
            self._poses.set_fixed_frame(changed['world_frame'])   # poses recorded anew
        if any(name in changed for name in PERSON_PARAMETERS):
            self._persons = self._person_gate()       # new criteria: judge from scratch
        if any(name in changed for name in DETECTOR_PARAMETERS):
            self._tracker = self._new_tracker()
            self._forget_tracks()
            self.get_logger().info('detector settings changed: tracker restarted')
        elif any(name in changed for name in PLANNER_PARAMETERS + TRACK_PARAMETERS):
            t = self._tracker         # keep the tracks: only the planner's settings change
            t.cfg = replace(t.cfg, planner=planner_config(self._p), **track_settings(self._p))
            t.planner.cfg = t.cfg.planner

    def _on_gaze_state(self, msg: Any) -> None:
        self._in_saccade = bool(msg.in_saccade)
        self.input_health.accept(self._gaze_state_topic)

    def _on_camera_info(self, msg: Any) -> None:
        k = camera_k(msg)
        if k is None:       # the last usable one (if any) stays in use
            self.input_health.refuse(self._info_topic, UNUSABLE_K, _k_text(msg.k))
            return
        self._k = k
        self.input_health.accept(self._info_topic)

    def _on_tf(self, msg: Any) -> None:
        if self._p['ego_motion']:
            self._poses.on_tf(msg)

    @property
    def frames_latest_tf(self) -> int:
        """Frames whose camera pose came from the latest tf, not from their stamp."""
        return self._poses.latest_answers

    def _note_once(self, kind: str, text: str) -> None:
        if kind not in self._noted:
            self._noted.add(kind)
            self.get_logger().info(text)

    def _camera_pose(self, header: Any) -> np.ndarray | None:
        """The image frame's pose (4x4) in world_frame at the image's stamp, or None."""
        return self._poses.pose_at(header.frame_id, stamp_seconds(header.stamp))

    def _ego_homography(self, header: Any) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(H, the camera's pose now): H moves the beliefs from the last processed frame's
        camera to this one's; None when it cannot be known."""
        if not self._p['ego_motion']:
            return None, None
        pose = self._camera_pose(header)
        if pose is None:
            self._note_once('tf', f'no transform {self._p["world_frame"]} -> '
                                  f'{header.frame_id or "(no frame_id)"} at the image stamps: '
                                  'tracking without ego-motion compensation until there is one')
            return None, None
        if self._k is None:
            self._note_once('k', f'no {self._info_topic} yet: tracking without ego-motion '
                                 'compensation until it arrives')
            return None, pose
        if self._last_pose is None:
            return None, pose
        rel = rotation_between(self._last_pose[:3, :3], pose[:3, :3])
        self.last_ego_rotation_deg = float(np.degrees(np.arccos(
            np.clip((np.trace(rel) - 1.0) / 2.0, -1.0, 1.0))))
        return rotation_homography(np.reshape(self._k, (3, 3)), rel), pose


    def _forget_tracks(self) -> None:
        self._book.clear()
        self._persons.clear()

    # --- the frame loop ---------------------------------------------------------------------

    def _on_image(self, msg: Any) -> None:
        if not self._rate_gate.take(stamp_seconds(msg.header.stamp), self._p['max_rate_hz']):
            self.frames_skipped += 1
            self.input_health.hold(self._image_topic, RATE_CAP)
            return
        problem = image_problem(msg)
        if problem:
            self.frames_dropped += 1
            self.input_health.refuse(self._image_topic, *problem)
            return
        image = image_to_numpy(msg)
        # 8-bit: image_problem admits rgb8 and bgr8 only
        bgr = cast(NDArray[np.uint8],
                   cv2.cvtColor(image, cv2.COLOR_RGB2BGR) if msg.encoding == 'rgb8' else image)
        tracker = self._tracker
        size = (int(image.shape[1]), int(image.shape[0]))
        window = tracker.detector.geometry
        if size[0] < window.window_w or size[1] < window.window_h:
            self.frames_dropped += 1
            self.input_health.refuse(self._image_topic, SMALLER_THAN_WINDOW,
                                     f'{size[0]}x{size[1]} < {window.window_w:g}x'
                                     f'{window.window_h:g}')
            return
        if tracker.image_size is not None and size != tracker.image_size:
            self._warn_throttled(
                'size', f'{self._image_topic}: frame size changed from {tracker.image_size[0]}x'
                        f'{tracker.image_size[1]} to {size[0]}x{size[1]}: tracker reset, '
                        f'{len(tracker.tracks)} tracks dropped')
            tracker.reset()
            self._forget_tracks()
            self.resets += 1
        homography, pose = self._ego_homography(msg.header)
        try:
            result = tracker.step(bgr, homography=homography)
        except FrameError as exc:
            self.frames_dropped += 1
            self.input_health.refuse(self._image_topic, UNUSABLE_FRAME, str(exc))
            return
        self._last_pose = pose
        self.frames_compensated += homography is not None
        self.frames_processed += 1
        self._frame_period.update(stamp_seconds(msg.header.stamp))
        tracks = tracker.tracks      # every track, tentative ones included: ages, frames_lost
        self._book.update(tracks.ids.tolist(), tracks.hits.tolist(), result.frame)
        persons = self._check_persons(msg.header, result, pose)
        self._tracks_pub.publish(messages.track_array(
            msg.header, result, persons, self._frame_period.period_s, self._book))
        self.input_health.published(self._tracks_pub.topic_name)
        planner = tracker.cfg.planner
        self._attention_pub.publish(messages.attention(msg.header, result, size, planner.k_max,
                                                       planner.s_max))
        if self._p['publish_overlay'] and has_subscribers(self._overlay_pub):
            self._overlay_pub.publish(numpy_to_image(
                messages.overlay(image, msg.encoding, result, persons), 'rgb8', header=msg.header))
        if self._p['publish_gaze']:
            self._send_gaze(msg.header, result, pose, persons)
        self.input_health.accept(self._image_topic)

    def _output_stall_s(self) -> float:
        """How long /mot/tracks may be silent while images arrive: three capped frames at least."""
        rate = self._p['max_rate_hz']
        return max(OUTPUT_STALL_S, 3.0 / rate) if rate > 0 else OUTPUT_STALL_S

    def _check_persons(self, header: Any, result: FrameResult,
                       pose: np.ndarray | None) -> np.ndarray:
        """Mask of the reported tracks that plausibly are people: their boxes stood on the
        floor at a height in person_height_m, steady within person_height_ratio, on each of
        their last person_check_frames frames (core.ground_plane). All true when the check is
        off or cannot be made (no camera_info, no pose of the image frame in world_frame)."""
        n = len(result.ids)
        if not self._p['person_check']:
            return np.ones(n, dtype=bool)
        if pose is None and header.frame_id:     # ego-motion off: the pose is still needed
            pose = self._camera_pose(header)
        if pose is None or self._k is None:
            self._note_once('person', f'no {self._info_topic} or no transform '
                                      f'{self._p["world_frame"]} -> '
                                      f'{header.frame_id or "(no frame_id)"}: person boxes are '
                                      'not checked against the floor until there are')
            return np.ones(n, dtype=bool)
        size = implied_size(result.boxes, np.reshape(self._k, (3, 3)), pose,
                            float(self._p['floor_z_m']))
        self.last_implied_heights = dict(zip(result.ids.tolist(), size.height.tolist(),
                                             strict=True))
        return self._persons.update(result.ids, size.height)

    # --- outputs ----------------------------------------------------------------------------

    def _send_gaze(self, header: Any, result: FrameResult, pose: np.ndarray | None,
                   persons: np.ndarray) -> None:
        """Pursuit of the established (gaze_min_hits, gaze_min_age), plausible (persons)
        tracks' mean centre. pose: the camera's pose in world_frame when the image was taken.
        With it the point goes out in world_frame, so the head's motion since the image (the
        gaze controller applies the latest tf) does not shift it; without it, in the image's
        frame."""
        if self._in_saccade:
            return
        steer = self._book.established(result.ids.tolist(), result.hits, result.frame,
                                       int(self._p['gaze_min_hits']),
                                       int(self._p['gaze_min_age'])) & persons
        if not steer.any():
            return
        now = self.get_clock().now().nanoseconds * 1e-9      # sim time in the graph
        if 0.0 <= now - self._last_gaze < 1.0 / self._p['gaze_rate_hz']:
            return
        if self._k is None:
            self._warn_throttled('gaze', f'no {self._info_topic} yet: no gaze commands')
            return
        if not header.frame_id:
            self._warn_throttled(
                'gaze', f'{self._image_topic}: images have no frame_id: no gaze commands')
            return
        p = gaze_point(result.boxes[steer], self._k, float(self._p['gaze_depth_m']), pose)
        frame_id = header.frame_id if pose is None else self._p['world_frame'].lstrip('/')
        self._gaze_pub.publish(messages.gaze_command(
            frame_id, self.get_clock().now().to_msg(), int(self._p['gaze_priority']), p))
        self._last_gaze = now
        self.gaze_commands += 1


main = main_for(MotPlannerNode)


if __name__ == '__main__':
    main()
