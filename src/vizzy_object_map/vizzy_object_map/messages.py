"""The object map as messages: vision_msgs/Detection3DArray (the confirmed objects, with their
label shares and covariance), active_vision_msgs/MapObjectArray (every object, with what
Detection3D has no field for) and a MarkerArray for viewers; the node (node.py) publishes them."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from vizzy_object_map.core.object_map import MapObject, ObjectMap
from vizzy_runtime.ros import message

MapObjectMsg = message('active_vision_msgs/msg/MapObject')
MapObjectArray = message('active_vision_msgs/msg/MapObjectArray')
Detection3D = message('vision_msgs/msg/Detection3D')
Detection3DArray = message('vision_msgs/msg/Detection3DArray')
ObjectHypothesisWithPose = message('vision_msgs/msg/ObjectHypothesisWithPose')
Marker = message('visualization_msgs/msg/Marker')
MarkerArray = message('visualization_msgs/msg/MarkerArray')
TimeMsg = message('builtin_interfaces/msg/Time')


def stamp_msg(t: float) -> Any:
    sec = math.floor(t)
    return TimeMsg(sec=int(sec), nanosec=min(int(round((t - sec) * 1e9)), 999_999_999))


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
