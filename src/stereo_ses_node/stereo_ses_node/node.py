"""The `stereo_ses` node (thesis chapter 3): stereo reconstruction into the Sensory Ego-Sphere.

Placeholder until the stereo/SES issue: checks the left and right images and publishes an
empty /ses/cells cloud (fields x, y, z, information) on a timer.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vizzy_runtime.convert import ConversionError, array_to_pointcloud2, image_to_numpy
from vizzy_runtime.node_tools import declare_parameters, guarded, main_for, replace_timer
from vizzy_runtime.ros import Node, message, qos_profile_sensor_data

Header = message('std_msgs/msg/Header')
Image = message('sensor_msgs/msg/Image')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')

IMAGE_TOPICS = {'left': '/vizzy/left/image_raw', 'right': '/vizzy/right/image_raw'}
CELLS_TOPIC = '/ses/cells'
ENCODINGS = ('rgb8', 'bgr8')
# One SES cell: mean position [m] in the SES frame and scalar information (inverse variance).
CELL_DTYPE = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('information', '<f4')])

# (name, default, description): the node declares exactly these.
PARAMETERS: tuple[tuple[str, Any, str], ...] = (
    ('publish_rate_hz', 2.0, 'Rate of /ses/cells [Hz], in (0, 100].'),
    ('frame_id', 'ego', 'Frame of the SES cells (head-centred, world-fixed orientation).'),
)


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is."""
    if name == 'publish_rate_hz' and not 0.0 < value <= 100.0:
        return f'publish_rate_hz must be in (0, 100], got {value}'
    if name == 'frame_id' and not value:
        return 'frame_id must not be empty'
    return None


def image_problem(msg: Any) -> str | None:
    """Why an input image cannot be used, or None if it can."""
    if msg.encoding not in ENCODINGS:
        return f'encoding {msg.encoding!r} is not one of {", ".join(ENCODINGS)}'
    try:
        image_to_numpy(msg)
    except ConversionError as exc:
        return str(exc)
    return None


class StereoSesNode(Node):
    """Receives the stereo pair and publishes the (for now empty) Sensory Ego-Sphere cells."""

    def __init__(self) -> None:
        super().__init__('stereo_ses')
        self._p = declare_parameters(self, PARAMETERS, check_parameter,
                                     on_change=self._on_parameters_changed)

        self._counts = {eye: 0 for eye in IMAGE_TOPICS}
        self._cells_pub = self.create_publisher(PointCloud2, CELLS_TOPIC, 10)
        for eye, topic in IMAGE_TOPICS.items():
            self.create_subscription(
                Image, topic, guarded(self, f'{topic}: failed on an image',
                                      lambda msg, eye=eye: self._on_image(eye, msg)),
                qos_profile_sensor_data)
        self._timer = self.create_timer(1.0 / self._p['publish_rate_hz'], self._on_timer)
        self.get_logger().info(
            f'placeholder: checking {IMAGE_TOPICS["left"]} and {IMAGE_TOPICS["right"]}, '
            f'publishing empty SES cells on {CELLS_TOPIC} at {self._p["publish_rate_hz"]} Hz')

    def _on_image(self, eye: str, msg: Any) -> None:
        problem = image_problem(msg)
        if problem:
            self.get_logger().warning(f'{IMAGE_TOPICS[eye]}: dropped image: {problem}',
                                      throttle_duration_sec=5.0)
            return
        self._counts[eye] += 1

    def _on_timer(self) -> None:
        header = Header(stamp=self.get_clock().now().to_msg(), frame_id=self._p['frame_id'])
        self._cells_pub.publish(array_to_pointcloud2(np.zeros(0, dtype=CELL_DTYPE), header))
        self.get_logger().debug(f'heartbeat: {self._counts["left"]} left and '
                                f'{self._counts["right"]} right images since the last one')
        self._counts = {eye: 0 for eye in IMAGE_TOPICS}

    def _on_parameters_changed(self, changed: dict[str, Any]) -> None:
        if 'publish_rate_hz' in changed:
            self._timer = replace_timer(self, self._timer, 1.0 / changed['publish_rate_hz'],
                                        self._on_timer)


main = main_for(StereoSesNode)


if __name__ == '__main__':
    main()
