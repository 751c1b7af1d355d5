"""vizzy_runtime.node_tools on the bundled runtime: parameter tables, guarded callbacks, main."""

import threading
import time
from typing import Any

import pytest

from vizzy_runtime import node_tools
from vizzy_runtime.node_tools import LatestWorker, declare_parameters, guarded, replace_timer
from vizzy_runtime.rclpy_compat.executors import SingleThreadedExecutor
from vizzy_runtime.rclpy_compat.node import Node
from vizzy_runtime.rclpy_compat.parameter import Parameter
from vizzy_runtime.testing import wait_until

PARAMETERS = (
    ('rate_hz', 10.0, 'Rate [Hz], in (0, 100].'),
    ('count', 3, 'How many, >= 1.'),
    ('lo', 1.0, 'Lower bound, < hi.'),
    ('hi', 2.0, 'Upper bound, > lo.'),
    ('frame_id', 'base_link', 'A frame (read-only).'),
)


def check(name: str, value: Any) -> str | None:
    if name == 'rate_hz' and not 0.0 < value <= 100.0:
        return f'rate_hz must be in (0, 100], got {value}'
    if name == 'count' and value < 1:
        return f'count must be >= 1, got {value}'
    return None


def check_all(values: dict[str, Any]) -> str | None:
    return 'lo must be < hi' if values['lo'] >= values['hi'] else None


class ToolNode(Node):
    def __init__(self, context: Any, overrides: dict[str, Any] | None = None) -> None:
        super().__init__('tool_node', context=context, parameter_overrides=[
            Parameter(n, value=v) for n, v in (overrides or {}).items()])
        self.changes: list[dict[str, Any]] = []
        self.p = declare_parameters(self, PARAMETERS, check, read_only={'frame_id'},
                                    check_all=check_all, on_change=self.changes.append)


def _set(node: Node, **values: Any) -> Any:
    return node.set_parameters_atomically([Parameter(n, value=v) for n, v in values.items()])


def test_startup_values_are_declared_described_and_read(context):
    node = ToolNode(context, {'rate_hz': 20.0})
    try:
        assert node.p == {'rate_hz': 20.0, 'count': 3, 'lo': 1.0, 'hi': 2.0,
                          'frame_id': 'base_link'}
        assert node.describe_parameter('count').description == 'How many, >= 1.'
        assert node.describe_parameter('frame_id').read_only
        assert not node.describe_parameter('rate_hz').read_only
    finally:
        node.destroy_node()


def test_bad_startup_values_raise_naming_the_node_and_every_problem(context):
    with pytest.raises(ValueError) as err:
        ToolNode(context, {'rate_hz': -1.0, 'count': 0, 'lo': 5.0})
    message = str(err.value)
    assert message.startswith('tool_node: bad parameters: ')
    assert 'rate_hz must be in (0, 100], got -1.0' in message
    assert 'count must be >= 1, got 0' in message
    assert 'lo must be < hi' in message


def test_invalid_sets_are_refused_with_the_reason_and_change_nothing(context):
    node = ToolNode(context)
    try:
        result = node.set_parameters([Parameter('rate_hz', value=0.0)])[0]
        assert not result.successful and result.reason == 'rate_hz must be in (0, 100], got 0.0'
        result = _set(node, lo=3.0)  # valid alone, not with hi
        assert not result.successful and result.reason == 'lo must be < hi'
        result = _set(node, rate_hz=50.0, count=0)  # one bad value refuses the whole set
        assert not result.successful and 'count' in result.reason
        assert not node.set_parameters([Parameter('frame_id', value='odom')])[0].successful
        assert node.p == {'rate_hz': 10.0, 'count': 3, 'lo': 1.0, 'hi': 2.0,
                          'frame_id': 'base_link'}
        assert node.get_parameter('rate_hz').value == 10.0
        assert node.changes == []
    finally:
        node.destroy_node()


def test_accepted_sets_update_the_dict_and_report_what_changed(context):
    node = ToolNode(context)
    p = node.p
    try:
        assert _set(node, lo=3.0, hi=4.0).successful
        assert node.set_parameters([Parameter('rate_hz', value=25.0)])[0].successful
        assert node.set_parameters([Parameter('count', value=3)])[0].successful  # unchanged
        assert node.p is p and p['lo'] == 3.0 and p['hi'] == 4.0 and p['rate_hz'] == 25.0
        assert node.changes == [{'lo': 3.0, 'hi': 4.0}, {'rate_hz': 25.0}]
        # parameters the table does not declare pass through untouched
        assert node.set_parameters([Parameter('use_sim_time', value=False)])[0].successful
        assert 'use_sim_time' not in p
    finally:
        node.destroy_node()


def test_a_check_that_raises_refuses_instead(context):
    node = Node('raising', context=context)
    try:
        def bad_check(name: str, value: Any) -> str | None:
            raise TypeError('boom')

        with pytest.raises(TypeError):
            declare_parameters(node, (('x', 1, 'X.'),), bad_check)
        node.undeclare_parameter('x')
        p = declare_parameters(node, (('x', 1, 'X.'),),
                               lambda n, v: None if isinstance(v, int) else v.missing)
        result = node.set_parameters([Parameter('use_sim_time', value=True)])[0]
        assert result.successful
        result = node.set_parameters([Parameter('x', value=2)])[0]
        assert result.successful and p['x'] == 2
    finally:
        node.destroy_node()


def test_guarded_logs_throttled_and_returns(context, capsys):
    node = Node('guarded_node', context=context)
    try:
        calls = []

        def callback(msg: Any) -> str:
            calls.append(msg)
            if msg == 'bad':
                raise ValueError(f'cannot use {msg!r}')
            return 'ok'

        safe = guarded(node, '/topic: failed on a message', callback, throttle_s=60.0)
        assert safe('good') == 'ok'
        assert safe('bad') is None
        assert safe('bad') is None  # throttled: logged once
        assert safe('good') == 'ok'
        assert calls == ['good', 'bad', 'bad', 'good']
        errors = [line for line in capsys.readouterr().err.splitlines() if '[ERROR]' in line]
        assert len(errors) == 1
        assert errors[0].endswith("[guarded_node]: /topic: failed on a message: "
                                  "ValueError: cannot use 'bad'")

        @guarded(node, 'decorated', throttle_s=0.0)
        def always_fails() -> None:
            raise RuntimeError('again')

        always_fails()
        always_fails()
        errors = [line for line in capsys.readouterr().err.splitlines() if '[ERROR]' in line]
        assert len(errors) == 2  # throttle_s=0: every failure is logged
        assert all(e.endswith('[guarded_node]: decorated: RuntimeError: again') for e in errors)
        assert always_fails.__name__ == 'always_fails'
    finally:
        node.destroy_node()


def test_guarded_timer_keeps_firing_and_can_be_replaced(context, capsys):
    node = Node('ticking', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        ticks = []
        timers_before = len(node.timers)

        def tick() -> None:
            ticks.append(1)
            raise ZeroDivisionError('tick')

        timer = node.create_timer(0.01, guarded(node, 'tick failed', tick))
        assert wait_until(lambda: len(ticks) >= 3, 5.0, spin=executor)
        timer = replace_timer(node, timer, 0.01, lambda: ticks.append(2))
        assert wait_until(lambda: 2 in ticks, 5.0, spin=executor)
        assert len(node.timers) == timers_before + 1  # the old one is gone
        errors = [line for line in capsys.readouterr().err.splitlines() if '[ERROR]' in line]
        assert errors and all(e.endswith('tick failed: ZeroDivisionError: tick') for e in errors)
        assert 'timer callback raised' not in '\n'.join(errors)  # guarded, not the executor
    finally:
        executor.remove_node(node)
        node.destroy_node()


def test_main_for_runs_the_standard_main(monkeypatch):
    events = []

    class FakeNode:
        def destroy_node(self) -> None:
            events.append('destroy')

    class FakeRclpy:
        def init(self, args: Any = None) -> None:
            events.append(('init', args))

        def spin(self, node: Any) -> None:
            events.append('spin')
            raise KeyboardInterrupt

        def try_shutdown(self) -> None:
            events.append('shutdown')

    monkeypatch.setattr(node_tools, 'rclpy', FakeRclpy())
    main = node_tools.main_for(FakeNode)
    main(['x'])
    assert events == [('init', ['x']), 'spin', 'destroy', 'shutdown']

    events.clear()

    def failing_factory() -> Any:
        raise ValueError('bad parameters')

    with pytest.raises(ValueError):
        node_tools.main_for(failing_factory)()
    assert events == [('init', None), 'shutdown']


def test_latest_worker_runs_the_newest_item_and_drops_the_rest() -> None:
    gate, seen = threading.Event(), []

    def handle(item):
        gate.wait(5.0)              # busy on the first item until the test opens the gate
        seen.append(item)

    worker = LatestWorker('test_worker', handle)
    try:
        assert not worker.put(1)
        assert wait_until(lambda: not worker._waiting, 5.0)     # 1 taken, the thread is busy
        assert not worker.put(2)
        assert worker.put(3) and worker.put(4)                  # 2 and 3 replaced while waiting
        gate.set()
        assert wait_until(lambda: seen == [1, 4], 5.0)
    finally:
        worker.close()
    assert not worker._thread.is_alive()


def test_latest_worker_spaces_starts_by_the_period() -> None:
    starts = []
    worker = LatestWorker('test_worker', lambda item: starts.append(time.monotonic()),
                          min_period_s=lambda: 0.2)
    try:
        worker.put(1)
        assert wait_until(lambda: len(starts) == 1, 5.0)
        worker.put(2)
        assert wait_until(lambda: len(starts) == 2, 5.0)
    finally:
        worker.close()
    assert starts[1] - starts[0] >= 0.2 - 1e-3
