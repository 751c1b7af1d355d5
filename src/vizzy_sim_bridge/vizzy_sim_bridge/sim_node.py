"""The `sim` node: a placeholder simulated Vizzy head (until the MuJoCo simulator replaces it).

Publishes a synthetic moving stereo pair with camera info, the joint states (held at the
`joint_positions` parameter), the head's transforms and, as the graph's time source, /clock.
"""

from __future__ import annotations

import array
import math
import time
from typing import Any

import numpy as np

from vizzy_runtime.convert import numpy_to_image
from vizzy_runtime.node_tools import declare_parameters, main_for, replace_timer
from vizzy_runtime.ros import (
    USING_REAL_ROS, Node, Parameter, SetParametersResult, message, qos_profile_latched,
    qos_profile_sensor_data)
from vizzy_sim_bridge.core.camera import camera_matrix, projection_matrix
from vizzy_sim_bridge.core.kinematics import (
    JOINT_LIMITS, JOINT_NAMES, Transform, joint_transforms, static_transforms)
from vizzy_sim_bridge.core.pattern import SyntheticStereoScene

CameraInfo = message('sensor_msgs/msg/CameraInfo')
Clock = message('rosgraph_msgs/msg/Clock')
Header = message('std_msgs/msg/Header')
Image = message('sensor_msgs/msg/Image')
JointState = message('sensor_msgs/msg/JointState')
TFMessage = message('tf2_msgs/msg/TFMessage')
TimeMsg = message('builtin_interfaces/msg/Time')
TransformStamped = message('geometry_msgs/msg/TransformStamped')

# (name, default, description): the node declares exactly these.
PARAMETERS: tuple[tuple[str, Any, str], ...] = (
    ('rate_hz', 15.0, 'Rate of images, camera info, joint states and /tf [Hz], in (0, 120].'),
    ('width', 640, 'Image width [px] (read-only).'),
    ('height', 480, 'Image height [px] (read-only).'),
    ('horizontal_fov_deg', 85.4, 'Horizontal field of view of each camera [deg] (read-only).'),
    ('baseline_m', 0.204, 'Stereo baseline between the camera centres [m] (read-only).'),
    ('joint_positions', [0.0, 0.0, 0.0, 0.0, 0.0],
     'Joint positions held by the head [rad], in the order ' + ', '.join(JOINT_NAMES) + '.'),
    ('publish_clock', True,
     'Publish /clock (simulated time starting at 0) and stamp messages with it (read-only). '
     'The sim itself must run with use_sim_time false.'),
    ('clock_rate_hz', 100.0, 'Rate of /clock [Hz], in (0, 1000] (read-only).'),
)
READ_ONLY = frozenset({'width', 'height', 'horizontal_fov_deg', 'baseline_m', 'publish_clock',
                       'clock_rate_hz'})


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is."""
    if name == 'rate_hz' and not 0.0 < value <= 120.0:
        return f'rate_hz must be in (0, 120], got {value}'
    if name in ('width', 'height') and not 16 <= value <= 8192:
        return f'{name} must be in [16, 8192] px, got {value}'
    if name == 'horizontal_fov_deg' and not 1.0 <= value <= 170.0:
        return f'horizontal_fov_deg must be in [1, 170], got {value}'
    if name == 'baseline_m' and not 0.0 < value <= 1.0:
        return f'baseline_m must be in (0, 1] m, got {value}'
    if name == 'clock_rate_hz' and not 0.0 < value <= 1000.0:
        return f'clock_rate_hz must be in (0, 1000], got {value}'
    if name == 'joint_positions':
        if len(value) != len(JOINT_NAMES):
            return f'joint_positions needs {len(JOINT_NAMES)} values, got {len(value)}'
        for joint, q in zip(JOINT_NAMES, value):
            lo, hi = JOINT_LIMITS[joint]
            if not (math.isfinite(q) and lo <= q <= hi):
                return f'joint_positions: {joint}={q} outside [{lo}, {hi}] rad'
    return None


def _stamp(t: float) -> Any:
    sec = math.floor(t)
    return TimeMsg(sec=int(sec), nanosec=min(int(round((t - sec) * 1e9)), 999_999_999))


def _float_seq(values: Any) -> Any:
    """A float64[] field value: array.array for rclpy, numpy for the bundled runtime."""
    if USING_REAL_ROS:
        return array.array('d', [float(v) for v in values])
    return np.asarray(values, dtype=np.float64)


class SimNode(Node):
    """Placeholder simulator: synthetic stereo images, camera info, joints, tf and /clock."""

    def __init__(self) -> None:
        super().__init__('sim')
        p = declare_parameters(self, PARAMETERS, check_parameter, read_only=READ_ONLY,
                               on_change=self._on_parameters_changed)
        self._width, self._height = int(p['width']), int(p['height'])
        self._joints = [float(q) for q in p['joint_positions']]
        self._publish_clock = bool(p['publish_clock'])
        # Added after declare_parameters' callback, so it runs first (see there).
        self.add_on_set_parameters_callback(self._refuse_sim_time)
        if self._publish_clock and self.get_parameter('use_sim_time').value:
            # Following the /clock we publish ourselves would stop every timer at time 0.
            self.get_logger().info('the sim is the /clock source: running on wall time '
                                   '(use_sim_time set to false)')
            self.set_parameters([Parameter('use_sim_time', Parameter.Type.BOOL, False)])
        self._scene = SyntheticStereoScene(self._width, self._height)
        k = camera_matrix(self._width, self._height, float(p['horizontal_fov_deg']))
        self._info = {'left': self._camera_info(k, 0.0, 'left_camera_optical_frame'),
                      'right': self._camera_info(k, float(p['baseline_m']),
                                                 'right_camera_optical_frame')}
        self._t0 = time.monotonic()

        self._image_pubs = {eye: self.create_publisher(
            Image, f'/vizzy/{eye}/image_raw', qos_profile_sensor_data)
            for eye in ('left', 'right')}
        self._info_pubs = {eye: self.create_publisher(
            CameraInfo, f'/vizzy/{eye}/camera_info', qos_profile_sensor_data)
            for eye in ('left', 'right')}
        self._joint_pub = self.create_publisher(JointState, '/joint_states', 10)
        self._tf_pub = self.create_publisher(TFMessage, '/tf', 100)
        self._tf_static_pub = self.create_publisher(TFMessage, '/tf_static', qos_profile_latched)
        self._clock_pub = (self.create_publisher(Clock, '/clock', 10)
                           if self._publish_clock else None)

        self._tf_static_pub.publish(TFMessage(transforms=self._transforms(
            static_transforms(), self._now())))
        self._timer = self.create_timer(1.0 / float(p['rate_hz']), self._on_tick)
        if self._clock_pub is not None:
            self._clock_timer = self.create_timer(1.0 / float(p['clock_rate_hz']), self._on_clock)
        self.get_logger().info(
            f'placeholder head: synthetic {self._width}x{self._height} rgb8 stereo on '
            f'/vizzy/{{left,right}}/image_raw at {p["rate_hz"]} Hz, camera_info, /joint_states, '
            f'/tf, /tf_static' + (', /clock (sim time from 0)' if self._publish_clock else ''))

    def _now(self) -> Any:
        if self._publish_clock:
            return _stamp(time.monotonic() - self._t0)
        return self.get_clock().now().to_msg()

    def _camera_info(self, k: np.ndarray, baseline_m: float, frame_id: str) -> Any:
        info = CameraInfo(width=self._width, height=self._height, distortion_model='plumb_bob')
        info.header.frame_id = frame_id
        info.d = _float_seq([0.0] * 5)
        info.k = np.ascontiguousarray(k, dtype=np.float64).reshape(9)
        info.r = np.eye(3).reshape(9)
        info.p = np.ascontiguousarray(projection_matrix(k, baseline_m)).reshape(12)
        return info

    def _transforms(self, transforms: list[Transform], stamp: Any) -> list[Any]:
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

    def _on_clock(self) -> None:
        self._clock_pub.publish(Clock(clock=self._now()))

    def _on_tick(self) -> None:
        stamp = self._now()
        t = stamp.sec + stamp.nanosec * 1e-9
        for eye in ('left', 'right'):
            header = Header(stamp=stamp, frame_id=f'{eye}_camera_optical_frame')
            image = numpy_to_image(self._scene.render(t, eye), 'rgb8', header)
            self._image_pubs[eye].publish(image)
            info = self._info[eye]
            info.header.stamp = stamp
            self._info_pubs[eye].publish(info)
        joints = JointState(name=list(JOINT_NAMES))
        joints.header.stamp = stamp
        joints.position = _float_seq(self._joints)
        joints.velocity = _float_seq([0.0] * len(JOINT_NAMES))
        self._joint_pub.publish(joints)
        self._tf_pub.publish(TFMessage(transforms=self._transforms(
            joint_transforms(self._joints), stamp)))

    def _refuse_sim_time(self, params: list[Any]) -> Any:
        for param in params:
            if param.name == 'use_sim_time' and param.value and self._publish_clock:
                return SetParametersResult(
                    successful=False, reason='the sim publishes /clock; it cannot follow it')
        return SetParametersResult(successful=True)

    def _on_parameters_changed(self, changed: dict[str, Any]) -> None:
        if 'rate_hz' in changed:
            self._timer = replace_timer(self, self._timer, 1.0 / float(changed['rate_hz']),
                                        self._on_tick)
        if 'joint_positions' in changed:
            self._joints = [float(q) for q in changed['joint_positions']]


main = main_for(SimNode)


if __name__ == '__main__':
    main()
