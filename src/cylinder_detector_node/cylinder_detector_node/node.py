"""The `cylinder_detector` node (thesis chapter 4): cylinders in RGB-D point clouds.

Topic names are relative (in: `points`, `image_raw`; out: `cylinders`, `cylinders/markers`,
`cylinders/overlay`); the
graph remaps the inputs to the RGB-D sensor's, so below are the resolved defaults.

Subscribes the organized PointCloud2 /vizzy/rgbd/points (sensor data QoS; any frame, normally the
camera's optical frame) and the matching colour image /vizzy/rgbd/image_raw (rgb8/bgr8, same
size), runs core.pipeline.detect_cylinders (tabletop segmentation, section 4.3.1; the
pre-attention CNN on each cluster's image patch, section 4.3.2, skipping the clusters it rejects;
then the two-stage Hough fit per remaining cluster, section 4.3.3, method `ours` or `rabbani`) and
publishes

  /cylinders          active_vision_msgs/CylinderArray, header = the cloud's
  /cylinders/markers  visualization_msgs/MarkerArray: DELETEALL, then one CYLINDER per cylinder
                      (red -> green by confidence), a TEXT label above; only for a subscriber
  /cylinders/clusters vision_msgs/Detection3DArray, header = the cloud's: every object the
                      segmentation found on the table, cylinder or not (cluster_array: a box
                      aligned with the table, and P(cylinder) when classified); the object map
                      places its objects with them
  /cylinders/overlay  sensor_msgs/Image rgb8 (if publish_overlay and the cloud's colour image is
                      there): the cylinders' outlines, axes and sizes projected on that image
                      (intrinsics fitted to the organized cloud itself, core.overlay), a legend
  /diagnostics        diagnostic_msgs/DiagnosticArray, about 1 Hz: the node's input health (below)

Which plane is the table: the highest one below the sensor that is level (within
up_tolerance_deg of "up") and has objects on it (core.segmentation: not the back wall, not the
floor under the table). "Up" in the cloud's frame comes from tf: +z of up_frame (base_link,
against gravity) turned into the cloud's frame, looked up for every cloud (latest transform,
vizzy_runtime.tf). Without that transform (no tf yet, another tree) or with up_frame empty, up is
the cloud frame's -y, a camera optical frame's (REP 103), with a throttled warning in the first
case. The table's "up" for the fit is its plane normal, so the Table 4.1 "vertical" biases mean
"upright on the table" in any sensor frame.

Image pairing: the last IMAGE_BUFFER images are kept; a cloud takes the one with the nearest
stamp if it is within image_tolerance_s (the simulator stamps both alike); an image that is no
readable colour image is refused on arrival (below) and never buffered. Without a matching image,
with an image whose size differs from the cloud's, or without a loadable model, the cylinders are
detected without the classifier (a throttled warning says why; the cloud is still accepted).
`confidence` is the classifier's P(cylinder) when the cluster was classified, else the Eq. 4.4 fit
quality; `fit_quality` is always Eq. 4.4.

The pipeline runs on a worker thread: the subscription callback only stores the newest cloud, so
a cloud that arrives while one is being processed replaces any waiting one (older ones are
dropped, never queued; not counted as refusals). A refused cloud is answered with an empty
CylinderArray; a valid cloud without a table or with nothing on it is accepted, gives an empty
CylinderArray and a throttled warning. While no cloud arrives, an empty CylinderArray goes out
every heartbeat_period_s in frame_id.

Refused inputs are counted by vizzy_runtime.input_health.InputHealth (self.input_health;
logging and /diagnostics as its docstring says). The reasons (counter keys):
  on /vizzy/rgbd/points (CLOUD_REASONS, checked on the worker thread): 'no xyz fields', 'bad
    field layout' (an unknown PointField datatype, fields outside point_step), 'size
    inconsistent with data' (fewer data bytes than the points need), 'empty cloud' (no points),
    'too few finite points' (fewer than min_points, e.g. all NaN), 'failed on a cloud: <ExcType>'
    (an exception in the callback or the pipeline, node_tools.guarded);
  on /vizzy/rgbd/image_raw (IMAGE_REASONS, checked on arrival): 'unsupported encoding' (not
    rgb8/bgr8/rgba8/bgra8), 'empty image', 'step shorter than a row', 'size inconsistent with
    data', 'failed on an image: <ExcType>'.

Algorithms live in cylinder_detector_node.core; this module only wires them to topics.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from cylinder_detector_node.core.accumulator import TABLE_4_1
from cylinder_detector_node.core.classifier import DEFAULT_MODEL, PatchClassifier
from cylinder_detector_node.core.fitting import METHODS
from cylinder_detector_node.core.fitting import Cylinder as FittedCylinder
from cylinder_detector_node.core.overlay import draw_cylinders, intrinsics_from_organized
from cylinder_detector_node.core.pairing import ImageBuffer, up_in_frame
from cylinder_detector_node.core.pipeline import (  # noqa: F401 (pipeline_params re-exported)
    Detection,
    detect_cylinders,
    image_problem,
    pipeline_params,
)
from cylinder_detector_node.core.segmentation import CAMERA_UP
from cylinder_detector_node.messages import (  # noqa: F401 (cloud reasons etc. re-exported)
    BAD_FIELDS,
    CLOUD_REASONS,
    COLOUR_CHANNELS,
    EMPTY_CLOUD,
    NO_XYZ,
    TOO_FEW_POINTS,
    CloudRefused,
    Marker,
    cloud_problem,
    cloud_xyz,
    cluster_array,
    colour_image_refusal,
    cylinder_array,
    marker_array,
    report_line,
    rgb_image,
)
from vizzy_runtime.convert import (  # noqa: F401 (the image reasons: counter keys, re-exported)
    EMPTY_IMAGE,
    IMAGE_REASONS,
    SHORT_DATA,
    SHORT_STEP,
    TOO_LARGE,
    UNCONVERTIBLE,
    UNSUPPORTED_ENCODING,
    numpy_to_image,
    stamp_seconds,
)
from vizzy_runtime.input_health import InputHealth, ThrottledWarnings
from vizzy_runtime.node_tools import (
    LatestWorker,
    Param,
    declare_parameters,
    guarded,
    has_subscribers,
    main_for,
    publish_from_thread,
    replace_timer,
)
from vizzy_runtime.ros import Node, message, qos_profile_sensor_data
from vizzy_runtime.tf import TransformBuffer, TransformListener

CylinderArray = message('active_vision_msgs/msg/CylinderArray')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')
Image = message('sensor_msgs/msg/Image')
MarkerArray = message('visualization_msgs/msg/MarkerArray')
Detection3DArray = message('vision_msgs/msg/Detection3DArray')

# Relative names: the graph remaps the generic inputs (points:=vizzy/rgbd/points, ...) and the
# node's namespace places everything; logs print the resolved names.
CLOUD_TOPIC = 'points'
IMAGE_TOPIC = 'image_raw'
IMAGE_BUFFER = 8
CYLINDERS_TOPIC = 'cylinders'
MARKERS_TOPIC = 'cylinders/markers'
CLUSTERS_TOPIC = 'cylinders/clusters'
OVERLAY_TOPIC = 'cylinders/overlay'
WARN_PERIOD_S = 5.0                        # throttle of the warnings that are no refusals
REPORT_PERIOD_S = 10.0

# The node declares exactly these; each range is the descriptor's, enforced by the middleware.
PARAMETERS: tuple[Param, ...] = (
    Param('heartbeat_period_s', 1.0,
          'While no cloud arrives, publish an empty CylinderArray this often [s], in '
          '[0.1, 3600].', '[0.1, 3600]'),
    Param('frame_id', 'base_link', 'Frame of the heartbeat CylinderArrays.',
          constraints='not empty'),
    Param('min_points', 50, 'Clouds with fewer finite points are reported and skipped, >= 0.',
          '[0, inf)'),
    Param('method', 'ours',
          f'Orientation accumulator: {" or ".join(METHODS)} (GMM + curvature soft voting, '
          'thesis Eq. 4.3) or Rabbani & van den Heuvel 2005 (uniform, normals only).',
          choices=tuple(METHODS)),
    Param('bias', 'mild',
          f'Table 4.1 orientation prior for method ours: {", ".join(sorted(TABLE_4_1))} '
          '(vertical = the table normal).', choices=tuple(sorted(TABLE_4_1))),
    Param('n_directions', 450, 'Orientation accumulator size N_d, in [1, 20000].', '[1, 20000]'),
    Param('radius_min_m', 0.01, 'Smallest cylinder radius [m], in (0, radius_max_m).',
          '(0, 2]', constraints='below radius_max_m'),
    Param('radius_max_m', 0.1, 'Largest cylinder radius [m], in (radius_min_m, 2].',
          '(0, 2]', constraints='above radius_min_m'),
    Param('min_confidence', 0.5,
          'Eq. 4.4 threshold N_model / N_cluster, in [0, 1]: clusters below it are not '
          'cylinders.', '[0, 1]'),
    # Off in the node for now: 0.7 rejects a real scan's milk carton (0.59) and keeps real
    # cylinders (0.89-0.93; detect_file's default), but the simulated graph's object map lost
    # precision with it (bench/active_perception.py, tabletop seeds 0-3: 0.93 -> 0.87).
    Param('min_normal_agreement', 0.0,
          'Least fraction of a fit\'s side points whose normal is within 20 deg of radial, in '
          '[0, 1] (0 = off; 0.7 rejects a box\'s faces, which pass Eq. 4.4).', '[0, 1]'),
    Param('voxel_size_m', 0.01, 'Downsampling voxel for the plane RANSAC and clustering [m], '
          'in (0, 0.2].', '(0, 0.2]'),
    Param('plane_distance_m', 0.01, 'RANSAC inlier distance of the table plane [m], in '
          '(0, 0.2].', '(0, 0.2]'),
    Param('cluster_eps_m', 0.02, 'Euclidean clustering (DBSCAN) neighbourhood [m], in '
          '(0, 0.5].', '(0, 0.5]'),
    Param('min_cluster_points', 30, 'Smallest object cluster (downsampled points), in '
          '[3, 100000].', '[3, 100000]'),
    Param('max_range_m', 3.0, 'Ignore points farther from the sensor [m]; 0 = no limit; in '
          '[0, 100].', '[0, 100]'),
    Param('up_frame', 'base_link',
          'Frame whose +z points up (against gravity): tf gives "up" in each cloud\'s frame for '
          'choosing the table plane; empty, or without that transform: the cloud frame\'s -y '
          '(a camera optical frame).'),
    Param('up_tolerance_deg', 60.0,
          'Largest angle between the table\'s normal and up [deg], in (0, 90): 60 admits a camera '
          'looking down 60 degrees when up is its -y; with tf a table is within a few degrees.',
          '(0, 90)'),
    Param('use_classifier', True,
          'Run the pre-attention CNN (section 4.3.2) on each cluster\'s image patch and fit '
          'only the clusters it accepts (needs the matching image on ' + IMAGE_TOPIC + ').'),
    Param('classifier_threshold', 0.5, 'Clusters with P(cylinder) below this are rejected, in '
          '[0, 1].', '[0, 1]'),
    Param('classifier_model', '', 'Classifier weights (.pt); empty = the packaged model.'),
    Param('publish_overlay', True,
          f'Publish the cylinders drawn on the colour image on {OVERLAY_TOPIC}.'),
    Param('image_tolerance_s', 0.05,
          'Largest stamp difference between a cloud and its image [s], in [0, 10].', '[0, 10]'),
)


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is: what the table's
    ranges and choices cannot express."""
    if name == 'frame_id' and not value:
        return 'frame_id must not be empty'
    return None


def check_all(values: dict[str, Any]) -> str | None:
    if values['radius_min_m'] >= values['radius_max_m']:
        return (f'radius_min_m ({values["radius_min_m"]}) must be below radius_max_m '
                f'({values["radius_max_m"]})')
    return None


class CylinderDetectorNode(Node):
    """Detects cylinders in each cloud (on a worker thread) and publishes them with markers."""

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__('cylinder_detector', **node_kwargs)
        self._p = declare_parameters(self, PARAMETERS, check_parameter, check_all=check_all,
                                     on_change=self._on_parameters_changed)
        self._params = pipeline_params(self._p)
        self._warn_throttled = ThrottledWarnings(self, WARN_PERIOD_S)  # what is no refusal
        # refused inputs, per topic and reason; /diagnostics (before any subscription)
        self.input_health = InputHealth(self)
        self.clouds_received = 0           # by the subscription (read by tests)
        self._last_cloud = -math.inf       # time.monotonic() of the last cloud
        self._last_report = -math.inf
        self.frames_processed = 0
        self.frames_dropped = 0
        self.last_detection: Detection | None = None
        self.last_frame_ms: float | None = None
        self._frame_ms: list[float] = []    # frame times since the last report

        self._images = ImageBuffer(IMAGE_BUFFER, lambda m: stamp_seconds(m.header.stamp))
        self.classifier: PatchClassifier | None = None
        self.last_classified = False        # whether the last cloud went through the classifier
        self.classifier_skipped: str | None = None   # why the last cloud did not, when it was on
        self._load_classifier()

        self.tf_buffer = TransformBuffer()     # "up" of each cloud's frame (up_frame's +z)
        self._tf_listener = TransformListener(self.tf_buffer, self)
        self.last_up: tuple[float, float, float] | None = None   # up used for the last cloud

        self._pub = self.create_publisher(CylinderArray, CYLINDERS_TOPIC, 10)
        self._marker_pub = self.create_publisher(MarkerArray, MARKERS_TOPIC, 10)
        self._clusters_pub = self.create_publisher(Detection3DArray, CLUSTERS_TOPIC, 10)
        self._overlay_pub = self.create_publisher(Image, OVERLAY_TOPIC, qos_profile_sensor_data)
        self._intrinsics: dict[tuple[str, tuple[int, ...]], np.ndarray | None] = {}
        # resolved names, for log lines
        self._cloud_topic = self.resolve_topic_name(CLOUD_TOPIC)
        self._image_topic = self.resolve_topic_name(IMAGE_TOPIC)
        # an exception in a callback (or in the worker) is counted as a refusal of its topic
        self._cloud_sub = self.create_subscription(
            PointCloud2, CLOUD_TOPIC,
            guarded(self, 'failed on a cloud', self._on_cloud, topic=self._cloud_topic),
            qos_profile_sensor_data)
        self._image_sub = self.create_subscription(
            Image, IMAGE_TOPIC,
            guarded(self, 'failed on an image', self._on_image, topic=self._image_topic),
            qos_profile_sensor_data)
        # guarded: a heartbeat racing with Ctrl-C ends spin quietly (ExternalShutdownException)
        self._heartbeat = guarded(self, 'heartbeat failed', self._on_heartbeat)
        self._timer = self.create_timer(self._p['heartbeat_period_s'], self._heartbeat)
        self._worker = LatestWorker('cylinder_detector', guarded(
            self, 'failed on a cloud', self.process_cloud, topic=self._cloud_topic))
        p = self._p
        classifier = (f'on (threshold {p["classifier_threshold"]:g}, images from '
                      f'{self._image_sub.topic_name})' if p['use_classifier'] else 'off')
        self.get_logger().info(
            f'detecting cylinders in {self._cloud_sub.topic_name} onto {self._pub.topic_name} and '
            f'{self._marker_pub.topic_name} (every object on the table on '
            f'{self._clusters_pub.topic_name}): '
            f'method {p["method"]}, bias {p["bias"]}, N_d {p["n_directions"]}, radius '
            f'{p["radius_min_m"]:g}-{p["radius_max_m"]:g} m, '
            f'min confidence {p["min_confidence"]:g}, classifier {classifier}')

    # --- inputs ---------------------------------------------------------------------------------

    def _on_cloud(self, msg: Any) -> None:
        self._last_cloud = time.monotonic()
        self.clouds_received += 1
        if self._worker.put(msg):
            self.frames_dropped += 1        # the worker is still busy: keep only the newest

    def _on_image(self, msg: Any) -> None:
        problem = colour_image_refusal(msg)
        if problem:
            self.input_health.refuse(self._image_topic, *problem)
            return
        self._images.add(msg)
        self.input_health.accept(self._image_topic)

    def _load_classifier(self) -> None:
        """(Re)load the model when use_classifier is on; a missing or bad file is logged and the
        node goes on without the classifier."""
        self.classifier = None
        if not self._p['use_classifier']:
            return
        path = self._p['classifier_model'] or DEFAULT_MODEL
        try:
            self.classifier = PatchClassifier.load(path)
        except (OSError, ValueError) as exc:
            self.get_logger().error(f'classifier unavailable, detecting without it: {exc}')

    def matching_image(self, stamp: Any) -> tuple[np.ndarray | None, str | None]:
        """(RGB image, None) of the buffered image nearest in time to stamp, or (None, why not)."""
        nearest = self._images.nearest(stamp_seconds(stamp))
        if nearest is None:
            return None, f'no image on {self._image_topic} yet'
        best, dt = nearest
        if dt > self._p['image_tolerance_s']:
            return None, (f'no image within {self._p["image_tolerance_s"]:g} s of the cloud '
                          f'(nearest {dt:.3f} s away)')
        try:
            return rgb_image(best), None
        except ValueError as exc:
            return None, f'{self._image_topic}: {exc}'

    def _on_heartbeat(self) -> None:
        if time.monotonic() - self._last_cloud < self._p['heartbeat_period_s']:
            return
        msg = CylinderArray()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self._p['frame_id']
        self._pub.publish(msg)

    def _on_parameters_changed(self, changed: dict[str, Any]) -> None:
        if 'heartbeat_period_s' in changed:
            self._timer = replace_timer(self, self._timer, changed['heartbeat_period_s'],
                                        self._heartbeat)
        self._params = pipeline_params(self._p)   # check_all keeps FitParams valid
        if 'use_classifier' in changed or 'classifier_model' in changed:
            self._load_classifier()

    # --- the worker -----------------------------------------------------------------------------

    def process_cloud(self, msg: Any) -> Detection | None:
        """Detect cylinders in one cloud and publish them (an empty array for a refused cloud)."""
        t0 = time.perf_counter()
        try:
            xyz = cloud_xyz(msg, self._p['min_points'])
        except CloudRefused as exc:
            self.input_health.refuse(self._cloud_topic, exc.reason, f'no cylinders: {exc}')
            self._publish(msg.header, [])
            publish_from_thread(self, self._clusters_pub, cluster_array(msg.header, None))
            return None
        seg, fit = self._params
        image, classifier, skipped = None, None, None
        if self._p['use_classifier'] and self.classifier is not None:
            image, why = self.matching_image(msg.header.stamp)
            kind = 'no matching image'
            if image is not None:
                problem = image_problem(image, xyz.shape)
                if problem is None:
                    classifier = self.classifier
                else:
                    why, kind = problem, 'image mismatch'
            if classifier is None:      # each reason throttled on its own
                skipped = why
                self._warn_throttled(kind, f'{self._cloud_topic}: detecting without the '
                                           f'classifier: {why}')
        self.classifier_skipped = skipped
        seg = replace(seg, up=self.cloud_up(msg.header.frame_id))
        det = detect_cylinders(xyz, seg, fit, image=image, classifier=classifier,
                               classifier_threshold=self._p['classifier_threshold'])
        self.last_classified = classifier is not None
        ms = 1000.0 * (time.perf_counter() - t0)
        self.last_detection, self.last_frame_ms = det, ms
        self.frames_processed += 1
        if det.plane is None or (not det.cylinders and det.messages):
            self._warn_throttled('pipeline', f'{self._cloud_topic}: no cylinders: '
                                             f'{"; ".join(det.messages)}')
        self._publish(msg.header, det.cylinders, det.probabilities)
        publish_from_thread(self, self._clusters_pub, cluster_array(msg.header, det))
        if self._p['publish_overlay'] and has_subscribers(self._overlay_pub):
            self._publish_overlay(msg.header, xyz, image, det.cylinders)
        self.input_health.accept(self._cloud_topic)
        self._report(det, ms, xyz.shape)
        return det

    def _publish_overlay(self, header: Any, xyz: np.ndarray, image: np.ndarray | None,
                         cylinders: list[FittedCylinder]) -> None:
        """The cylinders on the cloud's colour image (from the worker thread). The intrinsics are
        fitted to the organized cloud once per frame and size (they do not change)."""
        if image is None:
            image, _why = self.matching_image(header.stamp)
        if image is None or image.shape[:2] != xyz.shape[:2]:
            return
        key = (header.frame_id, xyz.shape)
        if key not in self._intrinsics:
            self._intrinsics[key] = intrinsics_from_organized(xyz)
        k = self._intrinsics[key]
        if k is None:
            return
        publish_from_thread(self, self._overlay_pub,
                            numpy_to_image(draw_cylinders(image, k, cylinders), 'rgb8',
                                           header=header))

    def cloud_up(self, cloud_frame: str) -> tuple[float, float, float]:
        """Up (against gravity) in cloud_frame: up_frame's +z from tf, else the frame's -y."""
        up_frame = self._p['up_frame']
        up = CAMERA_UP
        if up_frame and cloud_frame:
            try:
                up = up_in_frame(self.tf_buffer, up_frame, cloud_frame)
            except LookupError as exc:
                self._warn_throttled('up', f'{self._cloud_topic}: taking -y of {cloud_frame!r} '
                                           f'as up (camera optical frame): {exc}')
        self.last_up = up
        return up

    def _publish(self, header: Any, cylinders: list[FittedCylinder],
                 probabilities: list[float | None] | None = None) -> None:
        """From the worker thread."""
        publish_from_thread(self, self._pub, cylinder_array(header, cylinders, probabilities))
        if has_subscribers(self._marker_pub):     # for viewers only (volatile: none missed)
            markers = marker_array(header, cylinders, probabilities)
            publish_from_thread(self, self._marker_pub, markers)

    def _report(self, det: Detection, ms: float, shape: tuple[int, ...]) -> None:
        self._frame_ms.append(ms)
        now = time.monotonic()
        if now - self._last_report < REPORT_PERIOD_S:
            return
        self._last_report = now
        times, self._frame_ms = self._frame_ms, []
        self.get_logger().info(report_line(det, times, shape, self.frames_processed,
                                           self.frames_dropped))

    def destroy_node(self) -> Any:
        worker = getattr(self, '_worker', None)  # None: __init__ failed before it started
        if worker is not None:
            worker.close()
        return super().destroy_node()


main = main_for(CylinderDetectorNode)


if __name__ == '__main__':
    main()
