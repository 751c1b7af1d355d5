"""Shared by the sim node's tests (test_sim_node.py, test_sim_node_images.py, conftest.py):
the message types, the reduced-resolution parameters and the Listener node that keeps the last
message of each sim topic."""

from __future__ import annotations

from typing import Any

from vizzy_runtime.ros import (
    Context,
    Node,
    Parameter,
    message,
    qos_profile_latched,
    qos_profile_sensor_data,
)
from vizzy_runtime.testing import scaled

CameraInfo = message('sensor_msgs/msg/CameraInfo')
CompressedImage = message('sensor_msgs/msg/CompressedImage')
Image = message('sensor_msgs/msg/Image')
JointState = message('sensor_msgs/msg/JointState')
MarkerArray = message('visualization_msgs/msg/MarkerArray')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')
TFMessage = message('tf2_msgs/msg/TFMessage')
Clock = message('rosgraph_msgs/msg/Clock')
String = message('std_msgs/msg/String')

TIMEOUT = scaled(30.0)
W, H = 160, 120
OVERRIDES = [Parameter('width', value=W), Parameter('height', value=H),
             Parameter('rgbd_width', value=W), Parameter('rgbd_height', value=H),
             Parameter('rate_hz', value=20.0), Parameter('rgbd_rate_hz', value=10.0),
             Parameter('joint_state_rate_hz', value=100.0)]


class Listener(Node):
    """Keeps the last message of each sim topic and sends joint commands."""

    TOPICS = {
        '/vizzy/left/image_raw': (Image, qos_profile_sensor_data),
        '/vizzy/right/image_raw': (Image, qos_profile_sensor_data),
        '/vizzy/left/camera_info': (CameraInfo, qos_profile_sensor_data),
        '/vizzy/right/camera_info': (CameraInfo, qos_profile_sensor_data),
        '/vizzy/rgbd/image_raw': (Image, qos_profile_sensor_data),
        '/vizzy/rgbd/depth/image_raw': (Image, qos_profile_sensor_data),
        '/vizzy/rgbd/points': (PointCloud2, qos_profile_sensor_data),
        '/vizzy/rgbd/camera_info': (CameraInfo, qos_profile_sensor_data),
        '/joint_states': (JointState, 10),
        '/tf': (TFMessage, 100),
        '/tf_static': (TFMessage, qos_profile_latched),
        '/clock': (Clock, 10),
        '/sim/ground_truth/objects': (MarkerArray, qos_profile_latched),
        # reliable + transient local, depth 1: what RViz's RobotModel asks for
        '/robot_description': (String, qos_profile_latched),
    }

    def __init__(self, context: Context) -> None:
        super().__init__('sim_listener', context=context, start_parameter_services=False)
        self.last: dict[str, Any] = {}
        self.stamps: dict[str, list[int]] = {}
        for topic, (kind, qos) in self.TOPICS.items():
            self.create_subscription(kind, topic, self._keep(topic), qos)
        self.commands = self.create_publisher(JointState, '/vizzy/joint_commands', 10)

    def _keep(self, topic: str) -> Any:
        def keep(msg: Any) -> None:
            self.last[topic] = msg
            stamp = getattr(getattr(msg, 'header', None), 'stamp', None)
            if stamp is not None:
                self.stamps.setdefault(topic, []).append(stamp.sec * 10 ** 9 + stamp.nanosec)
        return keep

    def command(self, **targets: float) -> None:
        self.commands.publish(JointState(name=list(targets),
                                         position=[float(v) for v in targets.values()]))

    def joint(self, name: str) -> float:
        js = self.last['/joint_states']
        return float(js.position[list(js.name).index(name)])
