"""The `foveation` node (thesis chapter 2).

Placeholder until the foveation issue: checks each left image and republishes it unchanged
on /foveation/image.
"""

from __future__ import annotations

from typing import Any

from vizzy_runtime.convert import ConversionError, image_to_numpy
from vizzy_runtime.node_tools import declare_parameters, guarded, main_for
from vizzy_runtime.ros import Node, message, qos_profile_sensor_data

Image = message('sensor_msgs/msg/Image')

INPUT_TOPIC = '/vizzy/left/image_raw'
OUTPUT_TOPIC = '/foveation/image'
ENCODINGS = ('rgb8', 'bgr8')

# (name, default, description): the node declares exactly these.
PARAMETERS: tuple[tuple[str, Any, str], ...] = (
    ('max_width', 4096, 'Widest accepted input image [px], in [1, 16384]; wider are dropped.'),
    ('max_height', 4096, 'Tallest accepted input image [px], in [1, 16384]; taller are dropped.'),
)


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is."""
    if name in ('max_width', 'max_height') and not 1 <= value <= 16384:
        return f'{name} must be in [1, 16384] px, got {value}'
    return None


def image_problem(msg: Any, max_width: int, max_height: int) -> str | None:
    """Why an input image cannot be used, or None if it can."""
    if msg.encoding not in ENCODINGS:
        return f'encoding {msg.encoding!r} is not one of {", ".join(ENCODINGS)}'
    if msg.width > max_width or msg.height > max_height:
        return f'{msg.width}x{msg.height} exceeds max_width x max_height {max_width}x{max_height}'
    try:
        image_to_numpy(msg)
    except ConversionError as exc:
        return str(exc)
    return None


class FoveationNode(Node):
    """Checks left images and republishes them (pass-through placeholder)."""

    def __init__(self) -> None:
        super().__init__('foveation')
        self._p = declare_parameters(self, PARAMETERS, check_parameter)

        self._pub = self.create_publisher(Image, OUTPUT_TOPIC, qos_profile_sensor_data)
        self.create_subscription(
            Image, INPUT_TOPIC, guarded(self, f'{INPUT_TOPIC}: failed on an image', self._on_image),
            qos_profile_sensor_data)
        self.get_logger().info(
            f'placeholder: republishing {"/".join(ENCODINGS)} images from {INPUT_TOPIC} '
            f'unchanged on {OUTPUT_TOPIC}')

    def _on_image(self, msg: Any) -> None:
        problem = image_problem(msg, self._p['max_width'], self._p['max_height'])
        if problem:
            self.get_logger().warning(f'{INPUT_TOPIC}: dropped image: {problem}',
                                      throttle_duration_sec=5.0)
            return
        self._pub.publish(msg)


main = main_for(FoveationNode)


if __name__ == '__main__':
    main()
