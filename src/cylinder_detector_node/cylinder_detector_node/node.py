"""The `cylinder_detector` node (thesis chapter 4): cylinders in RGB-D point clouds.

Subscribes the organized PointCloud2 /vizzy/rgbd/points (sensor data QoS; any frame, normally the
camera's optical frame), runs core.pipeline.detect_cylinders (tabletop segmentation, section 4.3.1,
then the two-stage Hough fit per cluster, section 4.3.3, method `ours` or `rabbani`) and publishes

  /cylinders          active_vision_msgs/CylinderArray, header = the cloud's
  /cylinders/markers  visualization_msgs/MarkerArray: DELETEALL, then one CYLINDER per cylinder
                      (coloured red -> green by confidence) and a TEXT label above it

The table's "up" is the RANSAC plane normal turned towards the sensor (the core does it), so the
Table 4.1 "vertical" biases mean "upright on the table" in any sensor frame.

The pre-attention classifier (section 4.3.2) does not exist yet: `confidence` is the Eq. 4.4 fit
quality (the same as `fit_quality`); classifier_enabled = true only logs that it is unavailable.

The pipeline runs on a worker thread: the subscription callback only stores the newest cloud, so
a cloud that arrives while one is being processed replaces any waiting one (older ones are
dropped, never queued). Bad input (no x/y/z, truncated data, too few finite points, no table,
nothing on it) is logged (throttled) and answered with an empty CylinderArray. While no cloud
arrives, an empty CylinderArray goes out every heartbeat_period_s in frame_id.
Algorithms live in cylinder_detector_node.core; this module only wires them to topics.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

import numpy as np

from cylinder_detector_node.core.accumulator import TABLE_4_1
from cylinder_detector_node.core.fitting import METHODS, Cylinder as FittedCylinder, FitParams
from cylinder_detector_node.core.pipeline import Detection, detect_cylinders
from cylinder_detector_node.core.segmentation import SegmentParams
from vizzy_runtime.convert import ConversionError, pointcloud2_to_array
from vizzy_runtime.node_tools import declare_parameters, guarded, main_for, replace_timer
from vizzy_runtime.ros import Node, message, qos_profile_sensor_data

CylinderArray = message('active_vision_msgs/msg/CylinderArray')
CylinderMsg = message('active_vision_msgs/msg/Cylinder')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')
Marker = message('visualization_msgs/msg/Marker')
MarkerArray = message('visualization_msgs/msg/MarkerArray')

CLOUD_TOPIC = '/vizzy/rgbd/points'
CYLINDERS_TOPIC = '/cylinders'
MARKERS_TOPIC = '/cylinders/markers'
WARN_PERIOD_S = 5.0
REPORT_PERIOD_S = 10.0

# (name, default, description): the node declares exactly these.
PARAMETERS: tuple[tuple[str, Any, str], ...] = (
    ('heartbeat_period_s', 1.0,
     'While no cloud arrives, publish an empty CylinderArray this often [s], in (0, 3600].'),
    ('frame_id', 'base_link', 'Frame of the heartbeat CylinderArrays.'),
    ('min_points', 50, 'Clouds with fewer finite points are reported and skipped, >= 0.'),
    ('method', 'ours',
     f'Orientation accumulator: {" or ".join(METHODS)} (GMM + curvature soft voting, thesis '
     'Eq. 4.3) or Rabbani & van den Heuvel 2005 (uniform, normals only).'),
    ('bias', 'mild',
     f'Table 4.1 orientation prior for method ours: {", ".join(sorted(TABLE_4_1))} '
     '(vertical = the table normal).'),
    ('n_directions', 450, 'Orientation accumulator size N_d, in [1, 20000].'),
    ('radius_min_m', 0.01, 'Smallest cylinder radius [m], in (0, radius_max_m).'),
    ('radius_max_m', 0.1, 'Largest cylinder radius [m], in (radius_min_m, 2].'),
    ('min_confidence', 0.5,
     'Eq. 4.4 threshold N_model / N_cluster, in [0, 1]: clusters below it are not cylinders.'),
    ('voxel_size_m', 0.01, 'Downsampling voxel for the plane RANSAC and clustering [m], in (0, 0.2].'),
    ('plane_distance_m', 0.01, 'RANSAC inlier distance of the table plane [m], in (0, 0.2].'),
    ('cluster_eps_m', 0.02, 'Euclidean clustering (DBSCAN) neighbourhood [m], in (0, 0.5].'),
    ('min_cluster_points', 30, 'Smallest object cluster (downsampled points), in [3, 100000].'),
    ('max_range_m', 3.0, 'Ignore points farther from the sensor [m]; 0 = no limit; in [0, 100].'),
    ('classifier_enabled', False,
     'Pre-attention CNN (section 4.3.2); not available yet: true is logged and ignored.'),
)


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is."""
    if name == 'heartbeat_period_s' and not 0.0 < value <= 3600.0:
        return f'heartbeat_period_s must be in (0, 3600], got {value}'
    if name == 'frame_id' and not value:
        return 'frame_id must not be empty'
    if name == 'min_points' and value < 0:
        return f'min_points must be >= 0, got {value}'
    if name == 'method' and value not in METHODS:
        return f'method must be one of {", ".join(METHODS)}, got {value!r}'
    if name == 'bias' and value not in TABLE_4_1:
        return f'bias must be one of {", ".join(sorted(TABLE_4_1))}, got {value!r}'
    if name == 'n_directions' and not 1 <= value <= 20000:
        return f'n_directions must be in [1, 20000], got {value}'
    if name in ('radius_min_m', 'radius_max_m') and not (math.isfinite(value) and 0.0 < value <= 2.0):
        return f'{name} must be in (0, 2] m, got {value}'
    if name == 'min_confidence' and not 0.0 <= value <= 1.0:
        return f'min_confidence must be in [0, 1], got {value}'
    if name in ('voxel_size_m', 'plane_distance_m') and not 0.0 < value <= 0.2:
        return f'{name} must be in (0, 0.2] m, got {value}'
    if name == 'cluster_eps_m' and not 0.0 < value <= 0.5:
        return f'cluster_eps_m must be in (0, 0.5] m, got {value}'
    if name == 'min_cluster_points' and not 3 <= value <= 100000:
        return f'min_cluster_points must be in [3, 100000], got {value}'
    if name == 'max_range_m' and not 0.0 <= value <= 100.0:
        return f'max_range_m must be in [0, 100] m (0 = no limit), got {value}'
    return None


def check_all(values: dict[str, Any]) -> str | None:
    if values['radius_min_m'] >= values['radius_max_m']:
        return (f'radius_min_m ({values["radius_min_m"]}) must be below radius_max_m '
                f'({values["radius_max_m"]})')
    return None


def pipeline_params(p: dict[str, Any]) -> tuple[SegmentParams, FitParams]:
    """The core's parameters from the node's."""
    seg = SegmentParams(voxel_size=p['voxel_size_m'], plane_distance=p['plane_distance_m'],
                        cluster_eps=p['cluster_eps_m'], min_cluster_points=p['min_cluster_points'],
                        max_range=p['max_range_m'] or None)
    fit = FitParams(method=p['method'], gmm=TABLE_4_1[p['bias']], n_directions=p['n_directions'],
                    radius_min=p['radius_min_m'], radius_max=p['radius_max_m'],
                    min_confidence=p['min_confidence'])
    return seg, fit


def cloud_problem(msg: Any, min_points: int) -> str | None:
    """Why a cloud cannot be used, or None if it can (vectorized over the points)."""
    try:
        cloud_xyz(msg, min_points)
    except ValueError as exc:
        return str(exc)
    return None


def cloud_xyz(msg: Any, min_points: int) -> np.ndarray:
    """(H, W, 3) float64 xyz of a PointCloud2 (NaN kept); ValueError saying why it is unusable."""
    names = [f.name for f in msg.fields]
    missing = [n for n in ('x', 'y', 'z') if n not in names]
    if missing:
        raise ValueError(f'no field(s) {", ".join(missing)} (fields: {", ".join(names) or "none"})')
    points = pointcloud2_to_array(msg)     # ConversionError is a ValueError
    xyz = np.stack([points['x'], points['y'], points['z']], axis=-1).astype(np.float64)
    n = int(np.count_nonzero(np.all(np.isfinite(xyz), axis=-1)))
    if n < min_points or n == 0:
        raise ValueError(f'{n} finite points of {points.size}, fewer than '
                         f'min_points={max(min_points, 1)}')
    return xyz


def quaternion_z_to(axis: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of the shortest rotation taking +z to the unit vector axis."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    if a[2] < -1.0 + 1e-9:
        return (1.0, 0.0, 0.0, 0.0)
    q = np.array([-a[1], a[0], 0.0, 1.0 + a[2]])      # (z x a, 1 + z.a), normalized
    q /= np.linalg.norm(q)
    return tuple(float(v) for v in q)                   # type: ignore[return-value]


def cylinder_array(header: Any, cylinders: list[FittedCylinder]) -> Any:
    out = CylinderArray(header=header)
    for i, c in enumerate(cylinders):
        m = CylinderMsg(id=i, label='cylinder', radius=float(c.radius), height=float(c.height),
                        confidence=float(c.confidence), fit_quality=float(c.confidence))
        m.center.x, m.center.y, m.center.z = (float(v) for v in c.centre)
        m.axis.x, m.axis.y, m.axis.z = (float(v) for v in c.axis)
        out.cylinders.append(m)
    return out


def marker_array(header: Any, cylinders: list[FittedCylinder]) -> Any:
    """DELETEALL, then a CYLINDER and a TEXT label per cylinder, in the cloud's frame."""
    out = MarkerArray()
    clear = Marker(action=Marker.DELETEALL)
    clear.header = header
    out.markers.append(clear)
    for i, c in enumerate(cylinders):
        conf = float(np.clip(c.confidence, 0.0, 1.0))
        body = Marker(ns='cylinders', id=i, type=Marker.CYLINDER, action=Marker.ADD)
        body.header = header
        body.pose.position.x, body.pose.position.y, body.pose.position.z = (float(v) for v in c.centre)
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
        label.pose.position.x, label.pose.position.y, label.pose.position.z = (float(v) for v in top)
        label.pose.orientation.w = 1.0
        label.scale.z = 0.03
        label.color.r = label.color.g = label.color.b = label.color.a = 1.0
        label.text = f'{i}: r {100 * c.radius:.1f} cm, p {conf:.2f}'
        out.markers.append(label)
    return out


class CylinderDetectorNode(Node):
    """Detects cylinders in each cloud (on a worker thread) and publishes them with markers."""

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__('cylinder_detector', **node_kwargs)
        self._p = declare_parameters(self, PARAMETERS, check_parameter, check_all=check_all,
                                     on_change=self._on_parameters_changed)
        self._params = pipeline_params(self._p)
        self._warned: dict[str, float] = {}
        self._last_cloud = -math.inf       # time.monotonic() of the last cloud
        self._last_report = -math.inf
        self.frames_processed = 0
        self.frames_dropped = 0
        self.last_detection: Detection | None = None
        self.last_frame_ms: float | None = None

        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._pending: Any = None           # newest cloud not yet processed
        self._stop = False

        self._pub = self.create_publisher(CylinderArray, CYLINDERS_TOPIC, 10)
        self._marker_pub = self.create_publisher(MarkerArray, MARKERS_TOPIC, 10)
        self.create_subscription(
            PointCloud2, CLOUD_TOPIC, guarded(self, f'{CLOUD_TOPIC}: failed on a cloud',
                                              self._on_cloud), qos_profile_sensor_data)
        self._timer = self.create_timer(self._p['heartbeat_period_s'], self._on_heartbeat)
        self._worker = threading.Thread(target=self._work, name='cylinder_detector', daemon=True)
        self._worker.start()
        p = self._p
        self.get_logger().info(
            f'detecting cylinders in {CLOUD_TOPIC} onto {CYLINDERS_TOPIC} and {MARKERS_TOPIC}: '
            f'method {p["method"]}, bias {p["bias"]}, N_d {p["n_directions"]}, radius '
            f'{p["radius_min_m"]:g}-{p["radius_max_m"]:g} m, min confidence {p["min_confidence"]:g}')
        if p['classifier_enabled']:
            self._classifier_unavailable()

    # --- inputs ---------------------------------------------------------------------------------

    def _on_cloud(self, msg: Any) -> None:
        self._last_cloud = time.monotonic()
        with self._wake:
            if self._pending is not None:
                self.frames_dropped += 1    # the worker is still busy: keep only the newest
            self._pending = msg
            self._wake.notify()

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
                                        self._on_heartbeat)
        self._params = pipeline_params(self._p)   # check_all keeps FitParams valid
        if changed.get('classifier_enabled'):
            self._classifier_unavailable()

    def _classifier_unavailable(self) -> None:
        self.get_logger().warning(
            'classifier_enabled: the pre-attention classifier (section 4.3.2) is not available '
            'yet; detecting without it (confidence = Eq. 4.4 fit quality)')

    def _warn(self, kind: str, text: str) -> None:
        """A warning at most once every WARN_PERIOD_S per kind of problem."""
        now = time.monotonic()
        if now - self._warned.get(kind, -math.inf) >= WARN_PERIOD_S:
            self._warned[kind] = now
            self.get_logger().warning(text)

    # --- the worker -----------------------------------------------------------------------------

    def _work(self) -> None:
        process = guarded(self, f'{CLOUD_TOPIC}: failed on a cloud', self.process_cloud)
        while True:
            with self._wake:
                while self._pending is None and not self._stop:
                    self._wake.wait(0.5)
                if self._stop:
                    return
                msg, self._pending = self._pending, None
            process(msg)

    def process_cloud(self, msg: Any) -> Detection | None:
        """Detect cylinders in one cloud and publish them (an empty array for a bad cloud)."""
        t0 = time.perf_counter()
        try:
            xyz = cloud_xyz(msg, self._p['min_points'])
        except ValueError as exc:
            self._warn('cloud', f'{CLOUD_TOPIC}: no cylinders: {exc}')
            self._publish(msg.header, [])
            return None
        seg, fit = self._params
        det = detect_cylinders(xyz, seg, fit)
        ms = 1000.0 * (time.perf_counter() - t0)
        self.last_detection, self.last_frame_ms = det, ms
        self.frames_processed += 1
        if det.plane is None or (not det.cylinders and det.messages):
            self._warn('pipeline', f'{CLOUD_TOPIC}: no cylinders: {"; ".join(det.messages)}')
        self._publish(msg.header, det.cylinders)
        self._report(det, ms, xyz.shape)
        return det

    def _publish(self, header: Any, cylinders: list[FittedCylinder]) -> None:
        self._pub.publish(cylinder_array(header, cylinders))
        self._marker_pub.publish(marker_array(header, cylinders))

    def _report(self, det: Detection, ms: float, shape: tuple[int, ...]) -> None:
        now = time.monotonic()
        if now - self._last_report < REPORT_PERIOD_S:
            return
        self._last_report = now
        found = ', '.join(f'r {100 * c.radius:.1f} cm h {100 * c.height:.1f} cm p {c.confidence:.2f}'
                          for c in det.cylinders) or 'none'
        self.get_logger().info(
            f'{shape[1]}x{shape[0]} cloud in {ms:.0f} ms: {len(det.cylinders)} cylinder(s) '
            f'({found}), {det.rejected} cluster(s) rejected; {self.frames_processed} clouds '
            f'processed, {self.frames_dropped} dropped while busy')

    def destroy_node(self) -> Any:
        with self._wake:
            self._stop = True
            self._wake.notify()
        if self._worker.is_alive() and self._worker is not threading.current_thread():
            self._worker.join(timeout=30.0)
        return super().destroy_node()


main = main_for(CylinderDetectorNode)


if __name__ == '__main__':
    main()
