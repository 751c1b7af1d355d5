"""Junk on /clock (negative time, nanosec beyond a second) is refused and counted; the node keeps
running and its clock follows the next valid sample. Bundled runtime only: the real rclpy's
TimeSource raises from its /clock callback on a negative time (see docs/architecture.md)."""

from __future__ import annotations

import time

from vizzy_runtime.rclpy_compat.executors import SingleThreadedExecutor
from vizzy_runtime.rclpy_compat.node import Node
from vizzy_runtime.rclpy_compat.parameter import Parameter
from vizzy_runtime.ros import message
from vizzy_runtime.testing import scaled, wait_until

Clock = message('rosgraph_msgs/msg/Clock')


def _clock(sec: int, nanosec: int) -> object:
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = sec, nanosec
    return msg


def test_invalid_clock_samples_are_refused_and_counted(context, capfd):
    node = Node('clock_subject', context=context,
                parameter_overrides=[Parameter('use_sim_time', value=True)])
    source = Node('clock_junk', context=context)
    pub = source.create_publisher(Clock, '/clock', 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(source)
    fired: list[int] = []
    node.create_timer(0.05, lambda: fired.append(node.get_clock().now().nanoseconds))

    def spin_until(predicate, timeout: float = scaled(20.0)) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return True
            executor.spin_once(0.02)
        return predicate()

    assert wait_until(lambda: pub.get_subscription_count() > 0, scaled(20))
    pub.publish(_clock(5, 0))
    assert spin_until(lambda: node.get_clock().now().nanoseconds == 5_000_000_000)
    junk = (_clock(-1, 0), _clock(-2**31, 999_999_999), _clock(7, 1_000_000_000),
            _clock(8, 2**32 - 1))
    for count, msg in enumerate(junk, 1):  # one at a time: /clock subscriptions keep the last only
        pub.publish(msg)
        assert spin_until(lambda count=count: node.clock_refused == count)
    assert node.get_clock().now().nanoseconds == 5_000_000_000  # unchanged by junk
    pub.publish(_clock(6, 500_000_000))
    assert spin_until(lambda: node.get_clock().now().nanoseconds == 6_500_000_000)
    assert spin_until(lambda: bool(fired))  # timers still run on the node's clock
    err = capfd.readouterr().err
    assert err.count('/clock: refused sample') == 1, err  # the first one, then every 100th
    assert 'refused sample 1 (sec=-1, nanosec=0)' in err, err
