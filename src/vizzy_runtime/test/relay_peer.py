"""A second process for the transport tests: relays /relay_in to /relay_out (any --type), via the rclpy API."""

import sys

from vizzy_runtime.ros import ExternalShutdownException, Node, message, rclpy


class Relay(Node):
    def __init__(self) -> None:
        super().__init__('relay')
        self.declare_parameter('type', 'sensor_msgs/msg/Image')
        msg_type = message(self.get_parameter('type').value)
        self.pub = self.create_publisher(msg_type, 'relay_out', 10)
        self.create_subscription(msg_type, 'relay_in', self.pub.publish, 10)
        self.get_logger().info('relay ready')


def main() -> None:
    rclpy.init(args=sys.argv)
    node = Relay()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
