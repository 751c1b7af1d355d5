"""What the simulated head sends that is built from its state rather than rendered: stamps,
/tf's TransformStamped of the head's joints, camera_info of a calibration, the ground-truth
objects and walkers as markers, and an object's image box (the ground truth of detections, as
active_vision_msgs/TrackArray for the walkers). sim_node.py publishes them."""

from __future__ import annotations

import array
from typing import TYPE_CHECKING, Any

import numpy as np

from vizzy_runtime.ros import USING_REAL_ROS, message
from vizzy_vision.camera import project
from vizzy_vision.frames import rotation_matrix
from vizzy_vision.kinematics import Transform

if TYPE_CHECKING:
    from vizzy_sim_bridge.camera_calibration import Calibration

CameraInfo = message('sensor_msgs/msg/CameraInfo')
Marker = message('visualization_msgs/msg/Marker')
MarkerArray = message('visualization_msgs/msg/MarkerArray')
Point = message('geometry_msgs/msg/Point')
Track = message('active_vision_msgs/msg/Track')
TrackArray = message('active_vision_msgs/msg/TrackArray')
TransformStamped = message('geometry_msgs/msg/TransformStamped')


def float_seq(values: Any) -> Any:
    """A float64[] field value: array.array for rclpy, numpy for the bundled runtime."""
    if USING_REAL_ROS:
        return array.array('d', [float(v) for v in values])
    return np.asarray(values, dtype=np.float64)


def transform_messages(transforms: list[Transform], stamp: Any) -> list[Any]:
    """geometry_msgs/TransformStamped of each kinematics.Transform, stamped stamp: what goes out
    on /tf and /tf_static."""
    out = []
    for t in transforms:
        msg = TransformStamped(child_frame_id=t.child)
        msg.header.stamp = stamp
        msg.header.frame_id = t.parent
        tr, rot = msg.transform.translation, msg.transform.rotation
        tr.x, tr.y, tr.z = (float(v) for v in t.translation)
        rot.x, rot.y, rot.z, rot.w = (float(v) for v in t.rotation)
        out.append(msg)
    return out


def camera_info(cal: Calibration, frame_id: str) -> Any:
    """sensor_msgs/CameraInfo of a calibration, in frame frame_id (its stamp left to set)."""
    info = CameraInfo(width=cal.width, height=cal.height,
                      distortion_model=cal.distortion_model)
    info.header.frame_id = frame_id
    info.d = float_seq(cal.d)
    info.k = np.asarray(cal.k, dtype=np.float64)
    info.r = np.asarray(cal.r, dtype=np.float64)
    info.p = np.asarray(cal.p, dtype=np.float64)
    return info


def fill_pose(pose: Any, position: Any, quaternion: Any) -> None:
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in position)
    (pose.orientation.x, pose.orientation.y, pose.orientation.z,
     pose.orientation.w) = (float(v) for v in quaternion)


def object_markers(objects: list[Any], stamp: Any, frame_id: str = 'base_link') -> Any:
    """MarkerArray of scene objects: shape (ns objects), cylinder axes (ns cylinder_axes, arrows
    from the bottom to the top face's centre), names with dimensions (ns labels)."""
    markers = [Marker(action=Marker.DELETEALL, ns='')]
    markers[0].header.frame_id = frame_id
    markers[0].header.stamp = stamp
    shape_type = {'cylinder': Marker.CYLINDER, 'box': Marker.CUBE, 'sphere': Marker.SPHERE}
    for obj in objects:
        m = Marker(ns='objects', id=obj.id, type=shape_type[obj.shape], action=Marker.ADD)
        m.header.frame_id, m.header.stamp = frame_id, stamp
        fill_pose(m.pose, obj.position, obj.orientation)
        m.scale.x, m.scale.y, m.scale.z = (float(v) for v in obj.size)
        m.color.r, m.color.g, m.color.b, m.color.a = (float(v) for v in obj.color)
        m.text = obj.name
        markers.append(m)
        label = Marker(ns='labels', id=obj.id, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD)
        label.header.frame_id, label.header.stamp = frame_id, stamp
        fill_pose(label.pose, np.add(obj.position, (0.0, 0.0, 0.5 * obj.size[2] + 0.03)),
                   (0.0, 0.0, 0.0, 1.0))
        label.scale.z = 0.025
        label.color.r = label.color.g = label.color.b = label.color.a = 1.0
        if obj.is_cylinder:
            label.text = (f'{obj.name} r={obj.radius:.3f} h={obj.height:.3f}'
                          + (' lid' if obj.lid else ''))
            axis = Marker(ns='cylinder_axes', id=obj.id, type=Marker.ARROW, action=Marker.ADD)
            axis.header.frame_id, axis.header.stamp = frame_id, stamp
            axis.pose.orientation.w = 1.0
            c, a = np.asarray(obj.position), np.asarray(obj.axis)
            axis.points = [Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))
                           for p in (c - 0.5 * obj.height * a, c + 0.5 * obj.height * a)]
            axis.scale.x, axis.scale.y, axis.scale.z = 0.004, 0.01, 0.015
            axis.color.r, axis.color.g, axis.color.b, axis.color.a = 1.0, 1.0, 0.0, 1.0
            markers.append(axis)
        else:
            label.text = f'{obj.name} ' + 'x'.join(f'{v:.3f}' for v in obj.size)
        markers.append(label)
    return MarkerArray(markers=markers)


def box_corners(center: Any, size: Any, quaternion: Any) -> np.ndarray:
    """8 x 3 corners of a box (centre, full size, orientation (x, y, z, w))."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    local = 0.5 * signs * np.asarray(size, float)
    return local @ rotation_matrix(quaternion).T + np.asarray(center, float)


def image_box(k: np.ndarray, camera_pose: np.ndarray, corners: np.ndarray, width: int,
              height: int) -> tuple[float, float, float, float] | None:
    """(u0, v0, u1, v1) [px] of the corners' projection clipped to the image, or None when the
    box is not in view (behind the camera or entirely outside the image)."""
    uv = project(k, camera_pose, corners)
    if np.isnan(uv).any():
        cam = (corners - camera_pose[:3, 3]) @ camera_pose[:3, :3]
        if (cam[:, 2] <= 0.05).all():
            return None
        uv = uv[~np.isnan(uv).any(axis=1)]   # partly behind: bound the visible corners
    u0, v0 = np.min(uv, axis=0)
    u1, v1 = np.max(uv, axis=0)
    u0, u1 = max(u0, -0.5), min(u1, width - 0.5)
    v0, v1 = max(v0, -0.5), min(v1, height - 0.5)
    if u0 >= u1 or v0 >= v1:
        return None
    return float(u0), float(v0), float(u1), float(v1)


def pedestrian_markers(boxes: list[dict[str, Any]], stamp: Any) -> Any:
    """MarkerArray of the walkers' 3D boxes (ns pedestrians) in base_link."""
    markers = [Marker(action=Marker.DELETEALL)]
    markers[0].header.frame_id, markers[0].header.stamp = 'base_link', stamp
    for box in boxes:
        m = Marker(ns='pedestrians', id=box['id'], type=Marker.CUBE, action=Marker.ADD,
                   text=box['label'])
        m.header.frame_id, m.header.stamp = 'base_link', stamp
        fill_pose(m.pose, box['center'], box['orientation'])
        m.scale.x, m.scale.y, m.scale.z = box['size']
        m.color.r, m.color.g, m.color.b, m.color.a = 0.2, 0.8, 0.2, 0.5
        markers.append(m)
    return MarkerArray(markers=markers)


def pedestrian_tracks(boxes: list[dict[str, Any]], k: np.ndarray, camera_pose: np.ndarray,
                      width: int, height: int, stamp: Any, frame_id: str) -> Any:
    """TrackArray of the walkers' boxes in one camera's image [px]; those out of view left out."""
    tracks = []
    for box in boxes:
        corners = box.get('corners')
        if corners is None:
            corners = box_corners(box['center'], box['size'], box['orientation'])
        bb = image_box(k, camera_pose, corners, width, height)
        if bb is None:
            continue
        u0, v0, u1, v1 = bb
        tracks.append(Track(id=box['id'], label=box['label'], center_u=(u0 + u1) / 2,
                            center_v=(v0 + v1) / 2, width=u1 - u0, height=v1 - v0,
                            scale=1.0))
    msg = TrackArray(tracks=tracks)
    msg.header.stamp, msg.header.frame_id = stamp, frame_id
    return msg
