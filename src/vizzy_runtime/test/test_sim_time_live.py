"""Sim time as rclpy has it: with use_sim_time the node's ROS clock reads zero and its timers do
not fire until the first /clock; then they follow /clock, not the wall clock. Without it, the
clock is the system clock.

Marked live: runs on the bundled runtime and on the real rclpy (scripts/test_ros.sh).
"""

from __future__ import annotations

import time

import pytest

from vizzy_runtime.ros import Node, Parameter, SingleThreadedExecutor, message
from vizzy_runtime.testing import publish_until, scaled, wait_until

pytestmark = pytest.mark.live

Clock = message('rosgraph_msgs/msg/Clock')
PERIOD_NS = 50_000_000
START_NS = 100_010_000_000   # off the timer's 50 ms grid (rcl fires twice when exactly on it)


def _clock(ns: int) -> object:
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = divmod(ns, 1_000_000_000)
    return msg


def _spin_for(executor: SingleThreadedExecutor, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(0.02)


def test_sim_time_clock_is_zero_and_timers_wait_for_clock(context):
    node = Node('sim_time_subject', context=context,
                parameter_overrides=[Parameter('use_sim_time', value=True)])
    source = Node('sim_time_source', context=context)
    clock_pub = source.create_publisher(Clock, '/clock', 10)
    ticks: list[int] = []
    node.create_timer(PERIOD_NS / 1e9, lambda: ticks.append(node.get_clock().now().nanoseconds))
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(source)
    try:
        clock = node.get_clock()
        assert clock.ros_time_is_active
        assert clock.now().nanoseconds == 0

        _spin_for(executor, 0.5)     # ten periods of wall time, no /clock: nothing fires
        assert ticks == [] and clock.now().nanoseconds == 0

        # the first /clock: the clock jumps to it and the timer fires (once it is due)
        assert publish_until(lambda: clock_pub.publish(_clock(START_NS)),
                             lambda: clock.now().nanoseconds == START_NS, executor)
        assert wait_until(lambda: len(ticks) >= 1, scaled(5.0), spin=executor)
        assert all(t == START_NS for t in ticks)

        # /clock frozen: wall time passes, the timer does not fire
        count = len(ticks)
        _spin_for(executor, 0.3)
        assert len(ticks) == count

        # one period of sim time later: one more tick, at that time
        later = START_NS + PERIOD_NS
        assert publish_until(lambda: clock_pub.publish(_clock(later)),
                             lambda: clock.now().nanoseconds == later, executor)
        assert wait_until(lambda: len(ticks) == count + 1, scaled(5.0), spin=executor)
        assert ticks[-1] == later
    finally:
        executor.remove_node(source)
        executor.remove_node(node)
        source.destroy_node()
        node.destroy_node()


def test_without_sim_time_the_clock_is_the_system_clock(context):
    node = Node('sim_time_off', context=context,
                parameter_overrides=[Parameter('use_sim_time', value=True)])
    try:
        assert node.get_clock().now().nanoseconds == 0
        assert node.set_parameters([Parameter('use_sim_time', value=False)])[0].successful
        clock = node.get_clock()
        assert not clock.ros_time_is_active
        assert abs(clock.now().nanoseconds - time.time_ns()) < 1_000_000_000
    finally:
        node.destroy_node()
