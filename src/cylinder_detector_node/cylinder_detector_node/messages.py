"""What the cylinder detector reads and writes, as messages: the organized cloud and the colour
image taken apart (with the reasons a message is refused), and the CylinderArray, the
Detection3DArray of every segmented object and the MarkerArray built from a detection. The node
(node.py) only wires these to its topics."""

from __future__ import annotations

from typing import Any

import numpy as np

from cylinder_detector_node.core.fitting import Cylinder as FittedCylinder
from cylinder_detector_node.core.fitting import rotation_to_z
from cylinder_detector_node.core.pipeline import Detection
from vizzy_runtime.convert import (
    SHORT_DATA,
    image_refusal,
    image_to_numpy,
    pointcloud2_dtype,
    pointcloud2_to_array,
)
from vizzy_runtime.ros import message
from vizzy_vision.frames import matrix_to_quaternion, quaternion_z_to

CylinderArray = message('active_vision_msgs/msg/CylinderArray')
CylinderMsg = message('active_vision_msgs/msg/Cylinder')
Marker = message('visualization_msgs/msg/Marker')
MarkerArray = message('visualization_msgs/msg/MarkerArray')
Detection3D = message('vision_msgs/msg/Detection3D')
Detection3DArray = message('vision_msgs/msg/Detection3DArray')
ObjectHypothesisWithPose = message('vision_msgs/msg/ObjectHypothesisWithPose')

# Refusal reasons (InputHealth counter keys: short and stable; the values go in the detail).
NO_XYZ = 'no xyz fields'
BAD_FIELDS = 'bad field layout'
EMPTY_CLOUD = 'empty cloud'
TOO_FEW_POINTS = 'too few finite points'
CLOUD_REASONS = (NO_XYZ, BAD_FIELDS, SHORT_DATA, EMPTY_CLOUD, TOO_FEW_POINTS)
COLOUR_CHANNELS = {'rgb8': 3, 'bgr8': 3, 'rgba8': 4, 'bgra8': 4}


class CloudRefused(ValueError):
    """A cloud the node cannot use: reason (one of CLOUD_REASONS, a counter key), str = detail."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(detail)
        self.reason = reason


def cloud_problem(msg: Any, min_points: int) -> str | None:
    """Why a cloud cannot be used, or None if it can (vectorized over the points)."""
    try:
        cloud_xyz(msg, min_points)
    except ValueError as exc:
        return str(exc)
    return None


def cloud_xyz(msg: Any, min_points: int) -> np.ndarray:
    """(H, W, 3) float32 xyz of a PointCloud2 (NaN kept); CloudRefused (a ValueError) saying why
    it is unusable."""
    names = [f.name for f in msg.fields]
    missing = [n for n in ('x', 'y', 'z') if n not in names]
    if missing:
        raise CloudRefused(NO_XYZ, f'no field(s) {", ".join(missing)} '
                                   f'(fields: {", ".join(names) or "none"})')
    try:
        pointcloud2_dtype(msg)
    except (ValueError, TypeError) as exc:   # unknown datatype, a field beyond point_step
        raise CloudRefused(BAD_FIELDS, f'{exc} (point_step {msg.point_step})') from None
    try:
        points = pointcloud2_to_array(msg)
    except ValueError as exc:                # ConversionError: fewer bytes than the points need
        raise CloudRefused(SHORT_DATA, str(exc)) from None
    if points.size == 0:
        raise CloudRefused(EMPTY_CLOUD, f'{msg.width}x{msg.height} points')
    try:
        xyz = np.stack([points['x'], points['y'], points['z']], axis=-1).astype(np.float32,
                                                                               copy=False)
    except (ValueError, TypeError) as exc:   # e.g. x, y, z with different counts
        raise CloudRefused(BAD_FIELDS, f'x, y, z: {exc}') from None
    # counted from the three fields: 0.4 ms per VGA cloud, against 5.2 ms through xyz.sum
    # (which also called finite points whose sum overflows non-finite)
    n = int(np.count_nonzero(np.isfinite(points['x']) & np.isfinite(points['y'])
                             & np.isfinite(points['z'])))
    if n < min_points or n == 0:
        raise CloudRefused(TOO_FEW_POINTS, f'{n} finite points of {points.size}, fewer than '
                                           f'min_points={max(min_points, 1)}')
    return xyz


def colour_image_refusal(msg: Any) -> tuple[str, str] | None:
    """(reason, detail) of why an input image is no usable colour image, or None if it is
    (reason: one of IMAGE_REASONS, a counter key)."""
    return image_refusal(msg, COLOUR_CHANNELS, convert=rgb_image)


def rgb_image(msg: Any) -> np.ndarray:
    """(H, W, 3) uint8 RGB of an rgb8/bgr8/rgba8/bgra8 Image; ValueError naming the problem."""
    img = image_to_numpy(msg)          # ConversionError is a ValueError
    enc = msg.encoding
    if enc in ('rgb8', 'rgba8'):
        return img[..., :3]
    if enc in ('bgr8', 'bgra8'):
        return img[..., 2::-1]
    raise ValueError(f'image encoding {enc!r} is not a colour one (rgb8, bgr8, rgba8, bgra8)')


def cylinder_array(header: Any, cylinders: list[FittedCylinder],
                   probabilities: list[float | None] | None = None) -> Any:
    out = CylinderArray(header=header)
    probabilities = probabilities or [None] * len(cylinders)
    for i, (c, p) in enumerate(zip(cylinders, probabilities, strict=True)):
        m = CylinderMsg(id=i, label='cylinder', radius=float(c.radius), height=float(c.height),
                        confidence=float(c.confidence if p is None else p),
                        fit_quality=float(c.confidence))
        m.center.x, m.center.y, m.center.z = (float(v) for v in c.centre)
        m.axis.x, m.axis.y, m.axis.z = (float(v) for v in c.axis)
        out.cylinders.append(m)
    return out


def cluster_array(header: Any, det: Detection | None) -> Any:
    """Every object the segmentation found on the table as a vision_msgs/Detection3DArray in the
    cloud's frame: per cluster the box of its points aligned with the table (z along the table
    normal; size = extents), id its index, and, when the pre-attention CNN saw it, one result
    'cylinder' with P(cylinder)."""
    out = Detection3DArray(header=header)
    if det is None or det.plane is None:
        return out
    rot = rotation_to_z(np.asarray(det.plane[:3], np.float64))   # cloud -> table frame
    quat = matrix_to_quaternion(rot.T)                           # the table frame in the cloud's
    for i, (cl, p) in enumerate(zip(det.all_clusters, det.cluster_probabilities, strict=True)):
        pts = np.asarray(cl.points, np.float64) @ rot.T
        if len(pts) == 0:
            continue
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        centre = rot.T @ (0.5 * (lo + hi))
        d = Detection3D(header=header, id=str(i))
        c = d.bbox.center
        c.position.x, c.position.y, c.position.z = (float(v) for v in centre)
        c.orientation.x, c.orientation.y, c.orientation.z, c.orientation.w = (float(v)
                                                                              for v in quat)
        d.bbox.size.x, d.bbox.size.y, d.bbox.size.z = (float(v) for v in hi - lo)
        if p is not None:
            hyp = ObjectHypothesisWithPose()
            hyp.hypothesis.class_id, hyp.hypothesis.score = 'cylinder', float(p)
            hyp.pose.pose = c
            d.results.append(hyp)
        out.detections.append(d)
    return out


def marker_array(header: Any, cylinders: list[FittedCylinder],
                 probabilities: list[float | None] | None = None) -> Any:
    """DELETEALL, then a CYLINDER and a TEXT label per cylinder, in the cloud's frame."""
    out = MarkerArray()
    clear = Marker(action=Marker.DELETEALL)
    clear.header = header
    out.markers.append(clear)
    probabilities = probabilities or [None] * len(cylinders)
    for i, (c, p) in enumerate(zip(cylinders, probabilities, strict=True)):
        conf = float(np.clip(c.confidence if p is None else p, 0.0, 1.0))
        body = Marker(ns='cylinders', id=i, type=Marker.CYLINDER, action=Marker.ADD)
        body.header = header
        (body.pose.position.x, body.pose.position.y,
         body.pose.position.z) = (float(v) for v in c.centre)
        q = quaternion_z_to(np.array(c.axis))
        (body.pose.orientation.x, body.pose.orientation.y, body.pose.orientation.z,
         body.pose.orientation.w) = q
        body.scale.x = body.scale.y = 2.0 * float(c.radius)
        body.scale.z = float(c.height)
        body.color.r, body.color.g, body.color.b, body.color.a = 1.0 - conf, conf, 0.1, 0.8
        out.markers.append(body)
        label = Marker(ns='cylinder_labels', id=i, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD)
        label.header = header
        top = np.array(c.centre) + (0.5 * c.height + 0.03) * np.array(c.axis)
        (label.pose.position.x, label.pose.position.y,
         label.pose.position.z) = (float(v) for v in top)
        label.pose.orientation.w = 1.0
        label.scale.z = 0.03
        label.color.r = label.color.g = label.color.b = label.color.a = 1.0
        label.text = f'{i}: r {100 * c.radius:.1f} cm, p {conf:.2f}'
        out.markers.append(label)
    return out


def report_line(det: Detection, times: list[float], shape: tuple[int, ...], processed: int,
                dropped: int) -> str:
    """The periodic log line: frame times over the last period and the last cloud's result."""
    stages = ', '.join(f'{k} {v:.0f}' for k, v in det.stage_cpu_ms.items())
    found = ', '.join(f'r {100 * c.radius:.1f} cm h {100 * c.height:.1f} cm '
                      f'p {c.confidence:.2f}'
                      for c in det.cylinders) or 'none'
    return (f'{shape[1]}x{shape[0]} clouds in {np.median(times):.0f} ms median, '
            f'{max(times):.0f} max over {len(times)} (last, CPU: {stages} ms): '
            f'{len(det.cylinders)} cylinder(s) '
            f'({found}), {det.rejected_by_classifier} cluster(s) rejected by the classifier, '
            f'{det.rejected} by Eq. 4.4; {processed} clouds '
            f'processed, {dropped} dropped while busy')
