"""The `object_map` node: persistent labelled 3D objects from what the other nodes see.

Topic names are relative; the graph remaps camera_info to the left camera's, so below are the
resolved defaults. The map lives in map_frame (base_link, REP 103: x forward, z up).

Subscribes
  /foveation/detections     active_vision_msgs/FoveatedDetectionArray: recognitions. Each
                            detection of passes min_pass to max_pass (default: the first pass,
                            at the gaze fixation) names what lies under its
                            fixation (fixation_u, fixation_v): the classifier learned from views
                            foveated at an object, labelled with the object under the fovea
  /vizzy/left/camera_info   sensor_msgs/CameraInfo: K and size of the detections' camera
  /cylinders/clusters       vision_msgs/Detection3DArray: the objects segmented on a support
                            surface (cylinder_detector), boxes in the cloud's frame
  /cylinders                active_vision_msgs/CylinderArray: fitted cylinders, cloud frame
  /stereo/points            sensor_msgs/PointCloud2 (x y z, left optical frame): depth for a
                            recognition that falls on no known object; subscribed only while
                            use_stereo_depth is on (off in the graph: a 1.5 MB cloud a second
                            the map would receive and drop)
  /tf, /tf_static           poses of the sensors at each input's stamp (tf.FramePoses)
  /gaze/state               active_vision_msgs/GazeState: whether the eyes move, whose look
                            is served, where they fixate

core.object_map.ObjectMap fuses them (its docstring: association, fusion, naming, fading,
merging) and, every publish_period_s of the node's clock (sim time in the graph), publishes

  /objects          vision_msgs/Detection3DArray in map_frame: the confirmed objects; per
                    object header.stamp = last seen, id = the persistent id, bbox = centre and
                    axis-aligned size, results = its names best first (class_id the label, score
                    its share of the name evidence) with the position and its covariance in
                    pose (the orientation is unknown: identity, rotational variance -1 as REP
                    says for unknown)
  /objects/markers  visualization_msgs/MarkerArray: DELETEALL, then a box per established
                    object (green when confirmed, grey while unnamed) and its label with share
                    and observation count; built only while something subscribes (a viewer:
                    it gets the current markers within publish_period_s)
  /objects/map      active_vision_msgs/MapObjectArray: every object, with what Detection3D has
                    no field for (observation counts, first and last seen, established,
                    confirmed)
  /diagnostics      the node's input health
  /gaze/command     active_vision_msgs/GazeCommand (looks_enabled): a saccade (MODE_FIXATION_
                    POINT in map_frame, source 'object_map', priority gaze_priority, hold_time
                    dwell_s) to the next established object without a name (core.attention:
                    the task bias toward where objects are, inhibition of return on named ones,
                    dwell_s on each settled fixation for the recogniser, max_looks per object)

The three outputs are reliable and transient local (depth 1), like a map: a late subscriber gets
the current map at once (the markers: the last ones built, then the current ones at the next
publication).

Refused inputs (vizzy_runtime.input_health.InputHealth): 'no camera_info' (detections before a
usable K, or of another size), 'unusable K', 'no frame_id', 'no pose' (tf has no chain from
map_frame to the input's frame), 'non-finite values' (a box or cylinder with NaN), 'no xyz
fields' (a point cloud without x, y, z), 'failed on a ...: <ExcType>' (node_tools.guarded).
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from vizzy_object_map.core.attention import LookConfig, LookScheduler
from vizzy_object_map.core.object_map import CameraView, MapConfig, ObjectMap
from vizzy_object_map.core.observations import finite_points, fixation_at
from vizzy_object_map.messages import (
    Detection3DArray,
    GazeCommand,
    MapObjectArray,
    MarkerArray,
    cluster_observations,
    cylinder_observations,
    detection3d_array,
    look_command,
    map_object_array,
    marker_array,
    recognitions_from,
)
from vizzy_object_map.parameters import (
    GAZE_COMMAND_TOPIC,
    MAP_PARAMETERS,
    PARAMETERS,
    STEREO_TOPIC,
    check_all,
    check_parameter,
)
from vizzy_runtime.convert import ConversionError, camera_k, pointcloud2_to_array, stamp_seconds
from vizzy_runtime.input_health import InputHealth
from vizzy_runtime.node_tools import (
    declare_parameters,
    guarded,
    has_subscribers,
    main_for,
    replace_timer,
)
from vizzy_runtime.ros import Node, message, qos_profile_latched
from vizzy_runtime.tf import FramePoses, TransformBuffer, TransformListener

CameraInfo = message('sensor_msgs/msg/CameraInfo')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')
FoveatedDetectionArray = message('active_vision_msgs/msg/FoveatedDetectionArray')
GazeState = message('active_vision_msgs/msg/GazeState')
CylinderArray = message('active_vision_msgs/msg/CylinderArray')

DETECTIONS_TOPIC = 'foveation/detections'
CAMERA_INFO_TOPIC = 'camera_info'
CLUSTERS_TOPIC = 'cylinders/clusters'
CYLINDERS_TOPIC = 'cylinders'
GAZE_STATE_TOPIC = 'gaze/state'
GAZE_SOURCE = 'object_map'
LOOK_PERIOD_S = 0.1                 # how often the look scheduler runs (node clock)
FIXATION_MAX_AGE_S = 0.25           # a gaze state older than this tells nothing of an image
FIXATIONS_KEPT = 200                # gaze states remembered (several seconds at its rate)
OBJECTS_TOPIC = 'objects'
MARKERS_TOPIC = 'objects/markers'
MAP_TOPIC = 'objects/map'
# Refusal reasons (InputHealth counter keys)
NO_CAMERA_INFO = 'no camera_info'
UNUSABLE_K = 'unusable K'
NO_FRAME_ID = 'no frame_id'
NO_POSE = 'no pose'
NON_FINITE = 'non-finite values'
NO_XYZ = 'no xyz fields'
STEREO_MAX_POINTS = 20000            # a stereo cloud is thinned evenly to at most this



def map_config(p: dict[str, Any]) -> MapConfig:
    return MapConfig(**{name: p[name] for name in MAP_PARAMETERS})


class ObjectMapNode(Node):
    """Fuses recognitions, segmented objects and cylinders into labelled 3D objects."""

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__('object_map', **node_kwargs)
        self._p = declare_parameters(self, PARAMETERS, check_parameter, check_all=check_all,
                                     on_change=self._on_parameters_changed)
        self.map = ObjectMap(map_config(self._p))
        self.input_health = InputHealth(self)
        self._k: np.ndarray | None = None
        self._camera_size: tuple[int, int] | None = None
        self._stereo: tuple[float, np.ndarray] | None = None    # (stamp, (N, 3) map frame)
        self.recognitions_received = 0
        self.recognitions_placed = 0
        self.publications = 0

        self._tf = TransformBuffer()
        self.poses = FramePoses(self._tf, self._p['map_frame'], max_age_s=self._p['tf_history_s'])
        self._tf_listener = TransformListener(self._tf, self, on_update=self.poses.on_tf)
        self._objects_pub = self.create_publisher(Detection3DArray, OBJECTS_TOPIC,
                                                  qos_profile_latched)
        self._markers_pub = self.create_publisher(MarkerArray, MARKERS_TOPIC, qos_profile_latched)
        self._map_pub = self.create_publisher(MapObjectArray, MAP_TOPIC, qos_profile_latched)

        self._topics = {name: self.resolve_topic_name(name) for name in (
            DETECTIONS_TOPIC, CAMERA_INFO_TOPIC, CLUSTERS_TOPIC, CYLINDERS_TOPIC, STEREO_TOPIC)}
        subs = ((FoveatedDetectionArray, DETECTIONS_TOPIC, 'a detection array',
                 self._on_detections, 10),
                (CameraInfo, CAMERA_INFO_TOPIC, 'a camera_info', self._on_camera_info, 10),
                (Detection3DArray, CLUSTERS_TOPIC, 'a cluster array', self._on_clusters, 10),
                (CylinderArray, CYLINDERS_TOPIC, 'a cylinder array', self._on_cylinders, 10))
        self._subs = [self.create_subscription(
            msg_type, topic, guarded(self, f'failed on {what}', callback,
                                     topic=self._topics[topic]), depth)
            for msg_type, topic, what, callback, depth in subs]
        # only while use_stereo_depth: every cloud costs its transfer even when dropped
        self._stereo_sub: Any = None
        self._subscribe_stereo(self._p['use_stereo_depth'])
        self._tick = guarded(self, 'publishing the map failed', self.publish_map)
        self._timer = self.create_timer(self._p['publish_period_s'], self._tick)
        # task-driven looks (core.attention)
        self.looks = LookScheduler(self._look_config())
        self._in_saccade = False
        self._gaze_ours = False
        self._fixation: np.ndarray | None = None     # the gaze fixation, map frame
        # (stamp, fixation point in the map frame or None, in_saccade) of recent gaze states
        self._fixations: deque[tuple[float, np.ndarray | None, bool]] = deque(
            maxlen=FIXATIONS_KEPT)
        self._gaze_pub = self.create_publisher(GazeCommand, GAZE_COMMAND_TOPIC, 10)
        self._topics[GAZE_STATE_TOPIC] = self.resolve_topic_name(GAZE_STATE_TOPIC)
        self._subs.append(self.create_subscription(
            GazeState, GAZE_STATE_TOPIC, guarded(self, 'failed on a state', self._on_gaze_state,
                                                 topic=self._topics[GAZE_STATE_TOPIC]), 10))
        self._look_timer = self.create_timer(LOOK_PERIOD_S, guarded(self, 'looking failed',
                                                                    self.look))
        self.get_logger().info(
            f'object map in {self._p["map_frame"]!r}: recognitions from '
            f'{self._topics[DETECTIONS_TOPIC]} (camera {self._topics[CAMERA_INFO_TOPIC]}), '
            f'objects from {self._topics[CLUSTERS_TOPIC]} and {self._topics[CYLINDERS_TOPIC]}, '
            f'depth from {self._topics[STEREO_TOPIC] if self._p["use_stereo_depth"] else "none"}'
            f' (use_stereo_depth); map on {self._objects_pub.topic_name}, '
            f'{self._markers_pub.topic_name}, {self._map_pub.topic_name} every '
            f'{self._p["publish_period_s"]:g} s')

    # --- parameters -----------------------------------------------------------------------------

    def _look_config(self) -> LookConfig:
        return LookConfig(dwell_s=self._p['dwell_s'], max_looks=self._p['max_looks'])

    def _subscribe_stereo(self, on: bool) -> None:
        """Subscribe to the stereo cloud (on) or drop the subscription and the last cloud."""
        if on and self._stereo_sub is None:
            self._stereo_sub = self.create_subscription(
                PointCloud2, STEREO_TOPIC, guarded(self, 'failed on a cloud', self._on_stereo,
                                                   topic=self._topics[STEREO_TOPIC]), 2)
        elif not on and self._stereo_sub is not None:
            self.destroy_subscription(self._stereo_sub)
            self._stereo_sub, self._stereo = None, None

    def _on_parameters_changed(self, changed: dict[str, Any]) -> None:
        if 'use_stereo_depth' in changed:
            self._subscribe_stereo(bool(changed['use_stereo_depth']))
        if 'dwell_s' in changed or 'max_looks' in changed:
            self.looks.config = self._look_config()
        if any(name in changed for name in MAP_PARAMETERS):
            self.map.reconfigure(**{n: changed[n] for n in MAP_PARAMETERS if n in changed})
        if 'map_frame' in changed:
            self.poses.set_fixed_frame(changed['map_frame'])
            self.map.clear()
            self._stereo = None
            self.get_logger().info(f'map_frame is now {changed["map_frame"]!r}: map cleared')
        if 'tf_history_s' in changed:
            self.poses.max_age_s = float(changed['tf_history_s'])
        if 'publish_period_s' in changed:
            self._timer = replace_timer(self, self._timer, changed['publish_period_s'],
                                        self._tick)

    # --- inputs ---------------------------------------------------------------------------------

    def _pose(self, topic: str, header: Any) -> np.ndarray | None:
        """The pose (4x4) of header's frame in the map frame at its stamp, or None (refused)."""
        frame = header.frame_id.strip('/')
        if not frame:
            self.input_health.refuse(self._topics[topic], NO_FRAME_ID)
            return None
        pose = self.poses.pose_at(frame, stamp_seconds(header.stamp))
        if pose is None:
            self.input_health.refuse(self._topics[topic], NO_POSE,
                                     f'no transform {self._p["map_frame"]} <- {frame}')
        return pose

    def _on_camera_info(self, msg: Any) -> None:
        k = camera_k(msg)
        if k is None:
            self.input_health.refuse(self._topics[CAMERA_INFO_TOPIC], UNUSABLE_K,
                                     f'K {[float(v) for v in msg.k]}')
            return
        self._k, self._camera_size = k, (int(msg.width), int(msg.height))
        self.input_health.accept(self._topics[CAMERA_INFO_TOPIC])

    def _on_detections(self, msg: Any) -> None:
        topic = self._topics[DETECTIONS_TOPIC]
        chosen = [d for d in msg.detections
                  if self._p['min_pass'] <= d.pass_index <= self._p['max_pass']]
        if not chosen:
            self.input_health.accept(topic)
            return
        if self._k is None or self._camera_size is None:
            self.input_health.refuse(topic, NO_CAMERA_INFO,
                                     f'no usable {self._topics[CAMERA_INFO_TOPIC]} yet')
            return
        pose = self._pose(DETECTIONS_TOPIC, msg.header)
        if pose is None:
            return
        view = CameraView(self._k, pose, *self._camera_size)
        stamp = stamp_seconds(msg.header.stamp)
        depth = self._depth_points(stamp)
        vergence = self.fixation_at(stamp)
        recognitions, bad = recognitions_from(chosen, self.map, view, stamp, vergence, depth,
                                              self._p['depth_radius_px'])
        for detail in bad:
            self.input_health.refuse(topic, NON_FINITE, detail)
        placed = self.map.add_recognitions(recognitions, view)
        self.recognitions_received += len(recognitions)
        self.recognitions_placed += sum(p is not None for p in placed)
        self.input_health.accept(topic)

    def _depth_points(self, stamp: float) -> np.ndarray | None:
        if not self._p['use_stereo_depth'] or self._stereo is None:
            return None
        t, points = self._stereo
        return points if abs(stamp - t) <= self._p['stereo_max_age_s'] else None

    def _on_clusters(self, msg: Any) -> None:
        topic = self._topics[CLUSTERS_TOPIC]
        pose = self._pose(CLUSTERS_TOPIC, msg.header)
        if pose is None:
            return
        observations, bad = cluster_observations(msg, pose)
        for detail in bad:
            self.input_health.refuse(topic, NON_FINITE, detail)
        self.map.add_geometry(observations)
        self.input_health.accept(topic)

    def _on_cylinders(self, msg: Any) -> None:
        topic = self._topics[CYLINDERS_TOPIC]
        if not msg.cylinders:
            self.input_health.accept(topic)      # also the detector's heartbeat
            return
        pose = self._pose(CYLINDERS_TOPIC, msg.header)
        if pose is None:
            return
        observations, bad = cylinder_observations(msg, pose)
        for detail in bad:
            self.input_health.refuse(topic, NON_FINITE, detail)
        self.map.add_geometry(observations)
        self.input_health.accept(topic)

    def _on_stereo(self, msg: Any) -> None:
        topic = self._topics[STEREO_TOPIC]
        if not self._p['use_stereo_depth']:
            return
        names = {f.name for f in msg.fields}
        if not {'x', 'y', 'z'} <= names:
            self.input_health.refuse(topic, NO_XYZ, f'fields {sorted(names)}')
            return
        try:
            cloud = pointcloud2_to_array(msg).reshape(-1)
        except ConversionError as exc:
            self.input_health.refuse(topic, NO_XYZ, str(exc))
            return
        pose = self._pose(STEREO_TOPIC, msg.header)
        if pose is None:
            return
        xyz = finite_points(cloud, STEREO_MAX_POINTS)
        self._stereo = (stamp_seconds(msg.header.stamp), xyz @ pose[:3, :3].T + pose[:3, 3])
        self.input_health.accept(topic)

    def _on_gaze_state(self, msg: Any) -> None:
        self._in_saccade = bool(msg.in_saccade)
        self._gaze_ours = msg.active_source == GAZE_SOURCE
        p = msg.fixation_point
        frame = msg.header.frame_id.strip('/') or self._p['map_frame']
        try:
            m = self._tf.lookup_transform(self._p['map_frame'], frame)
        except LookupError:
            self._fixation = None
        else:
            self._fixation = m[:3, :3] @ np.array([p.x, p.y, p.z]) + m[:3, 3]
        active = bool(msg.active_source) and np.isfinite([p.x, p.y, p.z]).all()
        self._fixations.append((stamp_seconds(msg.header.stamp),
                                self._fixation if active else None, self._in_saccade))
        self.input_health.accept(self._topics[GAZE_STATE_TOPIC])

    def fixation_at(self, t: float) -> np.ndarray | None:
        """Where both optical axes met at time t (the map frame), if the eyes were still."""
        return fixation_at(self._fixations, t, FIXATION_MAX_AGE_S)

    def look(self) -> None:
        """The look scheduler's turn (timer): maybe a saccade to an unnamed object."""
        if not self._p['looks_enabled']:
            return
        now = self.get_clock().now().nanoseconds * 1e-9
        if now <= 0:
            return
        origin = self._head_origin()
        target = self.looks.update(now, self._in_saccade, self._gaze_ours, self.map, origin,
                                   self._fixation)
        if target is None:
            return
        aim = self.looks.aim if self.looks.aim is not None else target.position
        self._gaze_pub.publish(look_command(
            aim, GAZE_SOURCE, int(self._p['gaze_priority']), float(self._p['dwell_s']),
            self._p['map_frame'].strip('/'), self.get_clock().now().to_msg()))
        self._gaze_ours = False            # until /gaze/state says the look is served

    def _head_origin(self) -> np.ndarray:
        """Where the recognising camera (the left one) is in the map frame, else the ego frame,
        else the origin: the rays of the occlusion checks start there."""
        for frame in ('left_camera_optical_frame', 'ego'):   # the recognising camera first
            try:
                return self._tf.lookup_transform(self._p['map_frame'], frame)[:3, 3]
            except LookupError:
                continue
        return np.zeros(3)

    # --- output ---------------------------------------------------------------------------------

    def publish_map(self) -> None:
        """Forget what faded, then publish the three outputs (on the timer)."""
        now_time = self.get_clock().now()
        now = now_time.nanoseconds * 1e-9
        if now > 0:                       # sim time before the first /clock reads 0
            self.looks.forget(self.map.expire(now))
        stamp = now_time.to_msg()
        frame = self._p['map_frame'].strip('/')
        reject = self.map.config.reject_label
        self._objects_pub.publish(detection3d_array(self.map.objects(confirmed_only=True),
                                                    reject, frame, stamp))
        if has_subscribers(self._markers_pub):       # for viewers only
            self._markers_pub.publish(marker_array(self.map, frame, stamp))
        self._map_pub.publish(map_object_array(self.map, frame, stamp))
        self.publications += 1


main = main_for(ObjectMapNode)


if __name__ == '__main__':
    main()
