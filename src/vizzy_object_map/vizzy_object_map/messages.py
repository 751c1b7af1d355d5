"""The object map as messages: vision_msgs/Detection3DArray (the confirmed objects, with their
label shares and covariance), active_vision_msgs/MapObjectArray (every object, with what
Detection3D has no field for) and a MarkerArray for viewers; the node (node.py) publishes them."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from vizzy_object_map.core.object_map import (
    CameraView,
    GeometryObservation,
    MapObject,
    ObjectMap,
    Recognition,
)
from vizzy_object_map.core.observations import (
    cluster_observation,
    cylinder_observation,
    surface_point_at,
)
from vizzy_runtime.convert import stamp_msg, stamp_seconds
from vizzy_runtime.ros import message
from vizzy_vision.frames import rotation_matrix

MapObjectMsg = message('active_vision_msgs/msg/MapObject')
MapObjectArray = message('active_vision_msgs/msg/MapObjectArray')
Detection3D = message('vision_msgs/msg/Detection3D')
Detection3DArray = message('vision_msgs/msg/Detection3DArray')
ObjectHypothesisWithPose = message('vision_msgs/msg/ObjectHypothesisWithPose')
Marker = message('visualization_msgs/msg/Marker')
MarkerArray = message('visualization_msgs/msg/MarkerArray')
GazeCommand = message('active_vision_msgs/msg/GazeCommand')

FIXATION_PIXEL_PX = 3.0             # a detection this near the principal point is the gaze's own
FIXATION_SIGMA_M = 0.01             # the vergence point's uncertainty as an object's position


def _covariance6(cov3: np.ndarray) -> list[float]:
    """PoseWithCovariance's 6x6 (row-major) from a position covariance; orientation unknown."""
    out = np.zeros((6, 6))
    out[:3, :3] = cov3
    out[3, 3] = out[4, 4] = out[5, 5] = -1.0
    return [float(v) for v in out.ravel()]


def detection3d_array(objects: list[MapObject], reject_label: str, frame_id: str,
                      stamp: Any) -> Any:
    """The confirmed objects as a vision_msgs/Detection3DArray (module docstring)."""
    out = Detection3DArray()
    out.header.frame_id, out.header.stamp = frame_id, stamp
    for obj in objects:
        det = Detection3D(id=str(obj.id))
        det.header.frame_id, det.header.stamp = frame_id, stamp_msg(obj.last_seen)
        c = det.bbox.center
        c.position.x, c.position.y, c.position.z = (float(v) for v in obj.position)
        c.orientation.w = 1.0
        det.bbox.size.x, det.bbox.size.y, det.bbox.size.z = (float(v) for v in obj.size)
        for label, share in obj.ranked_labels(reject_label):
            hyp = ObjectHypothesisWithPose()
            hyp.hypothesis.class_id, hyp.hypothesis.score = label, float(share)
            hyp.pose.pose = c
            hyp.pose.covariance = _covariance6(obj.covariance)
            det.results.append(hyp)
        out.detections.append(det)
    return out


def map_object_array(object_map: ObjectMap, frame_id: str, stamp: Any) -> Any:
    """Every object as an active_vision_msgs/MapObjectArray."""
    out = MapObjectArray()
    out.header.frame_id, out.header.stamp = frame_id, stamp
    reject = object_map.config.reject_label
    for obj in object_map.objects():
        ranked = obj.ranked_labels(reject)
        label, share = obj.label(reject)
        m = MapObjectMsg(id=str(obj.id), label=label, label_share=float(share),
                         labels=[k for k, _ in ranked],
                         observations=obj.observations, recognitions=obj.recognitions,
                         geometry_observations=obj.geometry,
                         established=object_map.is_established(obj),
                         confirmed=object_map.is_confirmed(obj))
        m.shares = [float(v) for _, v in ranked]
        m.position.x, m.position.y, m.position.z = (float(v) for v in obj.position)
        m.position_covariance = [float(v) for v in np.asarray(obj.covariance).ravel()]
        m.size.x, m.size.y, m.size.z = (float(v) for v in obj.size)
        m.first_seen, m.last_seen = stamp_msg(obj.first_seen), stamp_msg(obj.last_seen)
        out.objects.append(m)
    return out


def marker_array(object_map: ObjectMap, frame_id: str, stamp: Any) -> Any:
    """A box and a label per established object (module docstring)."""
    clear = Marker(action=Marker.DELETEALL)
    clear.header.frame_id, clear.header.stamp = frame_id, stamp
    markers = [clear]
    reject = object_map.config.reject_label
    for obj in object_map.objects():
        if not object_map.is_established(obj):
            continue
        confirmed = object_map.is_confirmed(obj)
        box = Marker(ns='objects', id=obj.id, type=Marker.CUBE, action=Marker.ADD)
        box.header.frame_id, box.header.stamp = frame_id, stamp
        box.pose.position.x, box.pose.position.y, box.pose.position.z = (
            float(v) for v in obj.position)
        box.pose.orientation.w = 1.0
        box.scale.x, box.scale.y, box.scale.z = (max(float(v), 0.005) for v in obj.size)
        box.color.r, box.color.g, box.color.b = (0.1, 0.8, 0.2) if confirmed else (0.6, 0.6, 0.6)
        box.color.a = 0.6
        markers.append(box)
        label, share = obj.label(reject)
        text = Marker(ns='labels', id=obj.id, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD)
        text.header.frame_id, text.header.stamp = frame_id, stamp
        text.pose.position.x, text.pose.position.y = float(obj.position[0]), float(obj.position[1])
        text.pose.position.z = float(obj.position[2] + 0.5 * obj.size[2] + 0.03)
        text.pose.orientation.w = 1.0
        text.scale.z = 0.03
        text.color.r = text.color.g = text.color.b = text.color.a = 1.0
        text.text = (f'{label} {share:.2f} ({obj.recognitions}/{obj.observations})' if label
                     else f'? ({obj.observations})')
        markers.append(text)
    return MarkerArray(markers=markers)


def cluster_observations(msg: Any, pose: np.ndarray) -> tuple[list[GeometryObservation],
                                                               list[str]]:
    """A Detection3DArray of segmented objects (in the frame pose places in the map) as
    observations, and a line for each box with non-finite values (left out)."""
    stamp = stamp_seconds(msg.header.stamp)
    observations: list[GeometryObservation] = []
    bad: list[str] = []
    for det in msg.detections:
        c, s = det.bbox.center, det.bbox.size
        centre = np.array([c.position.x, c.position.y, c.position.z], np.float64)
        quat = (c.orientation.x, c.orientation.y, c.orientation.z, c.orientation.w)
        size = np.array([s.x, s.y, s.z], np.float64)
        if not (np.isfinite(centre).all() and np.isfinite(size).all()
                and np.isfinite(quat).all() and np.linalg.norm(quat) > 1e-9):
            bad.append(f'cluster {det.id!r}')
            continue
        observations.append(cluster_observation(pose, centre, rotation_matrix(quat),
                                                np.abs(size), stamp))
    return observations, bad


def cylinder_observations(msg: Any, pose: np.ndarray) -> tuple[list[GeometryObservation],
                                                                list[str]]:
    """A CylinderArray (in the frame pose places in the map) as observations, and a line for
    each cylinder with non-finite values or no axis (left out)."""
    stamp = stamp_seconds(msg.header.stamp)
    observations: list[GeometryObservation] = []
    bad: list[str] = []
    for cyl in msg.cylinders:
        centre = np.array([cyl.center.x, cyl.center.y, cyl.center.z], np.float64)
        axis = np.array([cyl.axis.x, cyl.axis.y, cyl.axis.z], np.float64)
        values = np.concatenate([centre, axis, [cyl.radius, cyl.height]])
        if not np.isfinite(values).all() or np.linalg.norm(axis) < 1e-9:
            bad.append(f'cylinder {cyl.id}')
            continue
        observations.append(cylinder_observation(pose, centre, axis, float(cyl.radius),
                                                 float(cyl.height), stamp))
    return observations, bad


def look_command(aim: np.ndarray, source: str, priority: int, dwell_s: float, frame_id: str,
                 stamp: Any) -> Any:
    """A saccade to aim (in frame_id) held dwell_s: the object map's look at an unnamed object."""
    cmd = GazeCommand(mode=GazeCommand.MODE_FIXATION_POINT,
                      motion=GazeCommand.MOTION_SACCADE, source=source,
                      priority=priority, hold_time=dwell_s)
    cmd.header.stamp = stamp
    cmd.header.frame_id = frame_id
    (cmd.fixation_point.x, cmd.fixation_point.y,
     cmd.fixation_point.z) = (float(v) for v in aim)
    return cmd


def recognitions_from(detections: Any, object_map: ObjectMap, view: CameraView, stamp: float,
                      vergence: np.ndarray | None, depth: np.ndarray | None,
                      depth_radius_px: float) -> tuple[list[Recognition], list[str]]:
    """FoveatedDetections as recognitions, placed at the vergence point when at the gaze's own
    pixel, else (with depth) on the surface under a pixel that shows no known object; and a line
    for each detection with non-finite values (left out)."""
    principal = (float(view.k[0, 2]), float(view.k[1, 2]))
    recognitions: list[Recognition] = []
    bad: list[str] = []
    for d in detections:
        u, v = float(d.fixation_u), float(d.fixation_v)
        if not (math.isfinite(u) and math.isfinite(v) and math.isfinite(d.score)):
            bad.append(f'detection {d.label!r}')
            continue
        point, cov = None, None
        if (vergence is not None and abs(u - principal[0]) <= FIXATION_PIXEL_PX
                and abs(v - principal[1]) <= FIXATION_PIXEL_PX):
            # the gaze's own pixel shows the point where both optical axes meet
            point, cov = vergence, np.eye(3) * FIXATION_SIGMA_M ** 2
        elif depth is not None and object_map.objects_at_pixel(view, u, v) == []:
            surface = surface_point_at(view, u, v, depth, depth_radius_px)
            point, cov = surface if surface is not None else (None, None)
        recognitions.append(Recognition(u, v, d.label, float(d.score), stamp, point, cov))
    return recognitions, bad
