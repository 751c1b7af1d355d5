"""InputHealth: refusals counted per topic and reason, logged once then throttled, and reported on
/diagnostics (diagnostic_msgs/DiagnosticArray) as the node's status. Live: both runtimes."""

from __future__ import annotations

import time

import pytest

from vizzy_runtime.input_health import DIAGNOSTICS_TOPIC, InputHealth
from vizzy_runtime.node_tools import guarded
from vizzy_runtime.ros import Node, SingleThreadedExecutor, message
from vizzy_runtime.testing import scaled

pytestmark = pytest.mark.live

DiagnosticArray = message('diagnostic_msgs/msg/DiagnosticArray')
DiagnosticStatus = message('diagnostic_msgs/msg/DiagnosticStatus')


def _spin_until(executor, predicate, timeout: float = scaled(20.0)) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        executor.spin_once(timeout_sec=0.05)
    return predicate()


def test_refusals_are_counted_logged_once_and_reported(context, capfd):
    node = Node('health_subject', context=context)
    node.input_health = InputHealth(node, period_s=0.2)
    listener = Node('health_listener', context=context)
    reports: list = []
    listener.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, reports.append, 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(listener)
    try:
        for _ in range(30):
            node.input_health.refuse('/cam/image_raw', 'unknown encoding', "'yuv9'")
        node.input_health.refuse('/cam/camera_info', 'unusable K')
        for _ in range(5):
            node.input_health.accept('/cam/image_raw')
        # a guarded callback's exception counts as a refusal of its topic
        guarded(node, 'failed on an image', lambda msg: 1 / 0, topic='/cam/image_raw')(None)

        def reported() -> bool:
            mine = [s for a in reports for s in a.status if s.name == '/health_subject']
            return any(s.level == DiagnosticStatus.WARN and len(s.values) == 4 for s in mine)

        assert _spin_until(executor, reported), [a.status for a in reports]
        status = [s for a in reports for s in a.status if s.name == '/health_subject'][-1]
        values = {kv.key: kv.value for kv in status.values}
        assert values == {'/cam/camera_info: unusable K': '1',
                          '/cam/image_raw: failed on an image: ZeroDivisionError': '1',
                          '/cam/image_raw: unknown encoding': '30',
                          '/cam/image_raw: accepted': '5'}
        assert '32 input(s) refused in the last period' in status.message
        # nothing new: back to OK, the totals kept
        assert _spin_until(executor, lambda: any(
            s.name == '/health_subject' and s.level == DiagnosticStatus.OK
            for a in reports[-3:] for s in a.status))
        err = capfd.readouterr().err
        assert err.count("/cam/image_raw: refused: unknown encoding: 'yuv9'") == 1, err
        assert err.count('/cam/camera_info: refused: unusable K') == 1, err
        assert 'refused: failed on an image: ZeroDivisionError: division by zero' in err, err
    finally:
        node.destroy_node()
        listener.destroy_node()
