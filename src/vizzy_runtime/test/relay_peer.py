"""A second process for the transport tests: relays /relay_in to /relay_out (any --type), via the
rclpy API."""

import sys

from vizzy_runtime.node_tools import run
from vizzy_runtime.ros import Node, message


class Relay(Node):
    def __init__(self) -> None:
        super().__init__('relay')
        self.declare_parameter('type', 'sensor_msgs/msg/Image')
        msg_type = message(self.get_parameter('type').value)
        self.pub = self.create_publisher(msg_type, 'relay_out', 10)
        self.create_subscription(msg_type, 'relay_in', self.pub.publish, 10)
        self.get_logger().info('relay ready')


def main() -> None:
    run(Relay, sys.argv)


if __name__ == '__main__':
    main()
