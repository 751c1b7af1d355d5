"""The `mot_planner` node (thesis chapter 5): resource-constrained multiple object tracking.

Placeholder until the MOT issue: checks each left image and publishes an empty TrackArray
with the image's header on /mot/tracks.
"""

from __future__ import annotations

from typing import Any

from vizzy_runtime.convert import ConversionError, image_to_numpy
from vizzy_runtime.node_tools import declare_parameters, guarded, main_for
from vizzy_runtime.ros import Node, message, qos_profile_sensor_data

Image = message('sensor_msgs/msg/Image')
TrackArray = message('active_vision_msgs/msg/TrackArray')

IMAGE_TOPIC = '/vizzy/left/image_raw'
TRACKS_TOPIC = '/mot/tracks'
ENCODINGS = ('rgb8', 'bgr8')

# (name, default, description): the node declares exactly these.
PARAMETERS: tuple[tuple[str, Any, str], ...] = (
    ('k_max', 3, 'K_max: most search regions processed per frame (section 5.3.4), >= 1.'),
    ('s_max', 0.1,
     'S_max: largest fraction of the image area processed per frame (section 5.3.4), in (0, 1].'),
)


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is."""
    if name == 'k_max' and value < 1:
        return f'k_max must be >= 1, got {value}'
    if name == 's_max' and not 0.0 < value <= 1.0:
        return f's_max must be in (0, 1], got {value}'
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


class MotPlannerNode(Node):
    """Checks images and publishes (for now empty) track arrays."""

    def __init__(self) -> None:
        super().__init__('mot_planner')
        self._p = declare_parameters(self, PARAMETERS, check_parameter)

        self._pub = self.create_publisher(TrackArray, TRACKS_TOPIC, 10)
        self.create_subscription(
            Image, IMAGE_TOPIC, guarded(self, f'{IMAGE_TOPIC}: failed on an image', self._on_image),
            qos_profile_sensor_data)
        self.get_logger().info(
            f'placeholder: one empty TrackArray on {TRACKS_TOPIC} per image from {IMAGE_TOPIC} '
            f'(k_max={self._p["k_max"]}, s_max={self._p["s_max"]})')

    def _on_image(self, msg: Any) -> None:
        problem = image_problem(msg)
        if problem:
            self.get_logger().warning(f'{IMAGE_TOPIC}: dropped image: {problem}',
                                      throttle_duration_sec=5.0)
            return
        self._pub.publish(TrackArray(header=msg.header))


main = main_for(MotPlannerNode)


if __name__ == '__main__':
    main()
