"""A process for test_mixed_transport: publishes or counts 640x480 rgb8 images with sensor-data QoS,
on whichever runtime runs it (the bundled one, or the real rclpy under .venv-ros), driven by lines
on stdin and reporting on stdout.

    image_peer.py sub TOPIC                    ready, matched (a publisher seen), got N per image;
                                               'stop' on stdin (or EOF): exits
    image_peer.py pub TOPIC SUBS FRAMES HZ     ready, matched (SUBS subscribers); 'go' on stdin:
                                               FRAMES images at HZ, then sent N; 'stop'/EOF: exits
"""

import sys
import threading
import time

import numpy as np

from vizzy_runtime.convert import numpy_to_image
from vizzy_runtime.ros import Node, message, qos_profile_sensor_data, rclpy

LIMIT_S = 300.0  # never outlive a test that lost track of us


def say(line: str) -> None:
    print(line, flush=True)


def commands() -> 'list[str]':
    """Lines from stdin as they come (a thread appends; EOF appends 'stop')."""
    lines: list[str] = []

    def read() -> None:
        for line in sys.stdin:
            lines.append(line.strip())
        lines.append('stop')
    threading.Thread(target=read, daemon=True).start()
    return lines


def subscriber(node: Node, topic: str, lines: 'list[str]', deadline: float) -> None:
    count = [0]

    def on_image(_msg) -> None:
        count[0] += 1
        say(f'got {count[0]}')
    node.create_subscription(message('sensor_msgs/msg/Image'), topic, on_image,
                             qos_profile_sensor_data)
    say('ready')
    matched = False
    while 'stop' not in lines and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
        if not matched and node.count_publishers(topic) >= 1:
            matched = True
            say('matched')


def publisher(node: Node, topic: str, subs: int, frames: int, rate_hz: float,
              lines: 'list[str]', deadline: float) -> None:
    frame = np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)
    msg = numpy_to_image(frame, 'rgb8')
    pub = node.create_publisher(type(msg), topic, qos_profile_sensor_data)
    say('ready')
    while pub.get_subscription_count() < subs and time.monotonic() < deadline:
        time.sleep(0.01)
    say('matched')
    while 'go' not in lines and 'stop' not in lines and time.monotonic() < deadline:
        time.sleep(0.01)
    start = time.monotonic()
    sent = 0
    while sent < frames and 'stop' not in lines:
        delay = start + sent / rate_hz - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(time.time_ns(), 1_000_000_000)
        pub.publish(msg)
        sent += 1
    say(f'sent {sent}')
    while 'stop' not in lines and time.monotonic() < deadline:
        time.sleep(0.01)


def main() -> None:
    role, topic = sys.argv[1], sys.argv[2]
    lines = commands()
    deadline = time.monotonic() + LIMIT_S
    rclpy.init(args=[])
    node = Node(f'image_peer_{role}')
    try:
        if role == 'sub':
            subscriber(node, topic, lines, deadline)
        else:
            subs, frames, rate_hz = int(sys.argv[3]), int(sys.argv[4]), float(sys.argv[5])
            publisher(node, topic, subs, frames, rate_hz, lines, deadline)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
