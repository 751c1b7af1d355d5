"""/rosout as rcl has it: every node publishes its log records as rcl_interfaces/msg/Log (reliable,
transient local, keep last 1000, so a late rqt_console or Foxglove still gets the recent ones),
unless it was created with enable_rosout=False.

Marked live: runs on the bundled runtime and on the real rclpy (scripts/test_ros.sh).
"""

from __future__ import annotations

import sys
import time
import uuid

import pytest

from vizzy_runtime.ros import (
    DurabilityPolicy,
    HistoryPolicy,
    Node,
    QoSProfile,
    ReliabilityPolicy,
    SingleThreadedExecutor,
    message,
)
from vizzy_runtime.testing import scaled, wait_until

pytestmark = pytest.mark.live

Log = message('rcl_interfaces/msg/Log')
# what rqt_console subscribes with
ROSOUT_QOS = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_LAST,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _listen(context, records: list) -> tuple[Node, SingleThreadedExecutor]:
    listener = Node(f'rosout_listener_{uuid.uuid4().hex[:8]}', context=context,
                    enable_rosout=False)
    listener.create_subscription(Log, '/rosout', records.append, ROSOUT_QOS)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(listener)
    return listener, executor


def test_a_nodes_warning_reaches_rosout_with_its_level_and_name(context):
    talker = Node('rosout_talker', namespace='/rosout_test', context=context)
    records: list = []
    listener, executor = _listen(context, records)
    executor.add_node(talker)
    try:
        text = f'careful: {uuid.uuid4().hex}'
        before = time.time_ns()
        line = sys._getframe().f_lineno + 1
        talker.get_logger().warning(text)
        talker.get_logger().get_child('part').error(text)
        assert wait_until(lambda: len([r for r in records if r.msg == text]) == 2, scaled(10.0),
                          spin=executor), [r.msg for r in records]
        warning, error = [r for r in records if r.msg == text]
        assert (warning.level, error.level) == (30, 40)
        assert int(warning.level) == int(Log.WARN)
        assert warning.name == 'rosout_test.rosout_talker'     # the logger's name
        assert error.name == 'rosout_test.rosout_talker.part'  # a child logger goes out too
        assert warning.file.endswith('test_rosout_live.py')
        assert warning.function == 'test_a_nodes_warning_reaches_rosout_with_its_level_and_name'
        assert warning.line == line
        stamp = warning.stamp.sec * 1_000_000_000 + warning.stamp.nanosec
        assert before - 1_000_000 <= stamp <= time.time_ns()   # the system clock
    finally:
        for node in (talker, listener):
            executor.remove_node(node)
            node.destroy_node()


def test_rosout_is_transient_local_and_enable_rosout_false_is_honoured(context):
    suffix = uuid.uuid4().hex[:8]
    talker = Node(f'rosout_early_{suffix}', context=context)
    silent = Node(f'rosout_silent_{suffix}', context=context, enable_rosout=False)
    silent.get_logger().warning('not on /rosout')
    talker.get_logger().info('said before anyone listened')
    records: list = []
    listener, executor = _listen(context, records)   # a late joiner, like rqt_console
    try:
        assert wait_until(lambda: any(r.name == talker.get_name() for r in records), scaled(10.0),
                          spin=executor)
        record = next(r for r in records if r.name == talker.get_name())
        assert (record.msg, record.level) == ('said before anyone listened', 20)
        talker.get_logger().info('a later one')
        assert wait_until(lambda: any(r.msg == 'a later one' for r in records), scaled(10.0),
                          spin=executor)
        assert not [r for r in records if r.name == silent.get_name()]
    finally:
        executor.remove_node(listener)
        for node in (listener, silent, talker):
            node.destroy_node()
