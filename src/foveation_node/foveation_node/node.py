"""The `foveation` node (thesis chapter 2).

Placeholder until the foveation issue: checks each left image and republishes it unchanged
on /foveation/image.
"""

from __future__ import annotations

from typing import Any

from vizzy_runtime.convert import ConversionError, image_to_numpy
from vizzy_runtime.ros import (
    ExternalShutdownException, Node, ParameterDescriptor, SetParametersResult, message,
    qos_profile_sensor_data, rclpy)

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
        for name, default, description in PARAMETERS:
            self.declare_parameter(name, default, ParameterDescriptor(description=description))
        self._p = {n: self.get_parameter(n).value for n, _, _ in PARAMETERS}
        problems = [p for p in (check_parameter(n, v) for n, v in self._p.items()) if p]
        if problems:
            raise ValueError('foveation: bad parameters: ' + '; '.join(problems))
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self._pub = self.create_publisher(Image, OUTPUT_TOPIC, qos_profile_sensor_data)
        self.create_subscription(Image, INPUT_TOPIC, self._on_image, qos_profile_sensor_data)
        self.get_logger().info(
            f'placeholder: republishing {"/".join(ENCODINGS)} images from {INPUT_TOPIC} '
            f'unchanged on {OUTPUT_TOPIC}')

    def _on_image(self, msg: Any) -> None:
        try:
            problem = image_problem(msg, self._p['max_width'], self._p['max_height'])
            if problem:
                self.get_logger().warning(f'{INPUT_TOPIC}: dropped image: {problem}',
                                          throttle_duration_sec=5.0)
                return
            self._pub.publish(msg)
        except Exception as exc:  # one bad message never kills the node
            self.get_logger().error(f'{INPUT_TOPIC}: failed on an image: '
                                    f'{type(exc).__name__}: {exc}', throttle_duration_sec=5.0)

    def _on_set_parameters(self, params: list[Any]) -> Any:
        for param in params:
            problem = check_parameter(param.name, param.value)
            if problem:
                return SetParametersResult(successful=False, reason=problem)
        for param in params:
            if param.name in self._p:
                self._p[param.name] = param.value
        return SetParametersResult(successful=True)


def main(args: list[str] | None = None) -> None:
    rclpy.init(args=args)
    node = FoveationNode()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
