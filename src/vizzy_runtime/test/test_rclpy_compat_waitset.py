"""The bundled executor waits on a Cyclone waitset (issue 27): a subscription's reader has no
Python listener (Cyclone's receive thread ran one for every sample, then woke the executor: ~0.08
ms of CPU a message, bench/runtime_messages.py), each message costs the executor one pass over
its nodes, and a node's /clock is read in place (no message objects)."""

from __future__ import annotations

import struct
import threading
import uuid

import pytest

from vizzy_runtime import msgs
from vizzy_runtime.rclpy_compat.executors import SingleThreadedExecutor
from vizzy_runtime.rclpy_compat.node import Node, _decode_clock
from vizzy_runtime.testing import scaled, wait_until

String = msgs.get_message('std_msgs/msg/String')
Clock = msgs.get_message('rosgraph_msgs/msg/Clock')


def _count_passes(executor: SingleThreadedExecutor) -> list[int]:
    """[n]: the executor's passes over its nodes (_run_ready calls) so far, counted live."""
    passes = [0]
    run_ready = executor._run_ready

    def counted() -> bool:
        passes[0] += 1
        return run_ready()

    executor._run_ready = counted       # type: ignore[method-assign]
    return passes


def test_subscriptions_are_served_by_the_waitset_one_pass_a_message(context) -> None:
    topic = f'/waitset_{uuid.uuid4().hex[:8]}'
    node = Node(f'waitset_{uuid.uuid4().hex[:8]}', context=context,
                start_parameter_services=False)
    got: list[str] = []
    sub = node.create_subscription(String, topic, lambda m: got.append(m.data), 10)
    pub = node.create_publisher(String, topic, 10)
    assert sub._reader._on_data is None          # no Python in Cyclone's thread per sample
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    passes = _count_passes(executor)
    done = threading.Event()

    def spin() -> None:                 # not the main thread: no signal-check wake-ups
        while not done.is_set():
            executor.spin_once(0.5)

    try:
        assert pub.wait_for_subscribers(1, scaled(10.0))
        spinner = threading.Thread(target=spin, daemon=True)
        spinner.start()
        assert wait_until(lambda: passes[0] > 0, scaled(10.0))
        n, before = 30, passes[0]
        for i in range(n):
            pub.publish(String(data=str(i)))
            assert wait_until(lambda i=i: len(got) == i + 1, scaled(10.0))
        assert got == [str(i) for i in range(n)]
        # one pass a message (the old executor: a listener's wake-up, then two passes each);
        # a few more for the type check every 2 s and the 0.5 s timeouts
        assert passes[0] - before < 1.5 * n, passes[0] - before
    finally:
        done.set()
        executor.remove_node(node)
        node.destroy_node()


def test_destroyed_subscriptions_leave_the_waitset(context) -> None:
    topic = f'/waitset_{uuid.uuid4().hex[:8]}'
    node = Node(f'waitset_{uuid.uuid4().hex[:8]}', context=context,
                start_parameter_services=False)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    got: list[str] = []
    subs = [node.create_subscription(String, topic, lambda m: got.append(m.data), 10)
            for _ in range(3)]
    executor.spin_once(0.0)
    assert executor._waitset is not None
    assert executor._waitset.watched() == {s._wait_key for s in subs}
    node.destroy_subscription(subs[0])
    executor.spin_once(0.0)
    assert executor._waitset.watched() == {s._wait_key for s in subs[1:]}
    pub = node.create_publisher(String, topic, 10)
    assert pub.wait_for_subscribers(2, scaled(10.0))
    pub.publish(String(data='x'))
    assert wait_until(lambda: got == ['x', 'x'], scaled(10.0), spin=executor)
    executor.remove_node(node)
    node.destroy_node()


def test_spin_once_waits_for_work_not_for_its_own_add_node(context) -> None:
    """rclpy.spin_once(node, timeout_sec=t) adds the node to the executor (a notify() that sets
    the waitset's guard) and removes it after: the wait must not take that stale guard for news
    and return with nothing done (a `while: spin_once(node, 0.1)` loop then spun a whole core),
    but wait, as rclpy's does, until there is work (here a message) or t has passed."""
    from vizzy_runtime import rclpy_compat

    topic = f'/waitset_{uuid.uuid4().hex[:8]}'
    node = Node(f'waitset_{uuid.uuid4().hex[:8]}', context=context,
                start_parameter_services=False)
    got: list[str] = []
    node.create_subscription(String, topic, lambda m: got.append(m.data), 10)
    pub = node.create_publisher(String, topic, 10)
    executor = SingleThreadedExecutor(context=context)
    handled_at_return: list[int] = []

    def spin() -> None:
        rclpy_compat.spin_once(node, executor=executor, timeout_sec=scaled(60.0))
        handled_at_return.append(len(got))

    try:
        assert pub.wait_for_subscribers(1, scaled(10.0))
        spinner = threading.Thread(target=spin, daemon=True)
        spinner.start()
        spinner.join(0.5)                # the old executor had returned by now, having run nothing
        pub.publish(String(data='x'))
        spinner.join(scaled(60.0))
        assert handled_at_return == [1]  # it returned because the message came, and ran it
    finally:
        node.destroy_node()


def test_clock_samples_are_read_in_place() -> None:
    raw = bytes(msgs.serialize(Clock(clock=msgs.get_message('builtin_interfaces/msg/Time')(
        sec=1234, nanosec=567_000_000))))
    assert _decode_clock(raw) == (1234, 567_000_000)
    assert _decode_clock(memoryview(raw + b'\0\0\0')) == (1234, 567_000_000)   # padding
    big_endian = b'\x00\x00\x00\x00' + struct.pack('>iI', 7, 8)
    assert _decode_clock(big_endian) == (7, 8)             # through rosbags' deserializer
    for malformed in (raw[:10], raw + b'\0' * 4, b'\x07\x07' + raw[2:]):
        with pytest.raises(Exception, match='CDR|unpack|buffer'):
            _decode_clock(malformed)
