"""The `cylinder_detector` node (thesis chapter 4): cylinders in RGB-D point clouds.

Placeholder until the cylinder issue: checks each cloud and publishes an empty
CylinderArray for each usable one; while no cloud arrives, an empty one every
heartbeat_period_s.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from vizzy_runtime.convert import ConversionError, pointcloud2_to_array
from vizzy_runtime.node_tools import declare_parameters, guarded, main_for, replace_timer
from vizzy_runtime.ros import Node, message, qos_profile_sensor_data

CylinderArray = message('active_vision_msgs/msg/CylinderArray')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')

CLOUD_TOPIC = '/vizzy/rgbd/points'
CYLINDERS_TOPIC = '/cylinders'

# (name, default, description): the node declares exactly these.
PARAMETERS: tuple[tuple[str, Any, str], ...] = (
    ('heartbeat_period_s', 1.0,
     'While no cloud arrives, publish an empty CylinderArray this often [s], in (0, 3600].'),
    ('frame_id', 'base_link', 'Frame of the heartbeat CylinderArrays.'),
    ('min_points', 50, 'Clouds with fewer finite points are reported and skipped, >= 0.'),
)


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is."""
    if name == 'heartbeat_period_s' and not 0.0 < value <= 3600.0:
        return f'heartbeat_period_s must be in (0, 3600], got {value}'
    if name == 'frame_id' and not value:
        return 'frame_id must not be empty'
    if name == 'min_points' and value < 0:
        return f'min_points must be >= 0, got {value}'
    return None


def cloud_problem(msg: Any, min_points: int) -> str | None:
    """Why a cloud cannot be used, or None if it can (vectorized over the points)."""
    names = [f.name for f in msg.fields]
    missing = [n for n in ('x', 'y', 'z') if n not in names]
    if missing:
        return f'no field(s) {", ".join(missing)} (fields: {", ".join(names) or "none"})'
    try:
        points = pointcloud2_to_array(msg)
    except ConversionError as exc:
        return str(exc)
    finite = np.isfinite(points['x']) & np.isfinite(points['y']) & np.isfinite(points['z'])
    n = int(np.count_nonzero(finite))
    if n < min_points:
        return f'{n} finite points of {points.size}, fewer than min_points={min_points}'
    return None


class CylinderDetectorNode(Node):
    """Checks clouds and publishes (for now empty) cylinder arrays."""

    def __init__(self) -> None:
        super().__init__('cylinder_detector')
        self._p = declare_parameters(self, PARAMETERS, check_parameter,
                                     on_change=self._on_parameters_changed)

        self._last_cloud = -float('inf')   # time.monotonic() of the last cloud
        self._pub = self.create_publisher(CylinderArray, CYLINDERS_TOPIC, 10)
        self.create_subscription(
            PointCloud2, CLOUD_TOPIC, guarded(self, f'{CLOUD_TOPIC}: failed on a cloud',
                                              self._on_cloud), qos_profile_sensor_data)
        self._timer = self.create_timer(self._p['heartbeat_period_s'], self._on_heartbeat)
        self.get_logger().info(
            f'placeholder: checking clouds on {CLOUD_TOPIC}, publishing empty cylinder arrays '
            f'on {CYLINDERS_TOPIC} (and every {self._p["heartbeat_period_s"]} s while no cloud '
            f'comes)')

    def _on_cloud(self, msg: Any) -> None:
        self._last_cloud = time.monotonic()
        problem = cloud_problem(msg, self._p['min_points'])
        if problem:
            self.get_logger().warning(f'{CLOUD_TOPIC}: skipped cloud: {problem}',
                                      throttle_duration_sec=5.0)
            return
        self._pub.publish(CylinderArray(header=msg.header))

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


main = main_for(CylinderDetectorNode)


if __name__ == '__main__':
    main()
