"""vizzy_runtime.node_tools on the bundled runtime: parameter tables, guarded callbacks, main."""

import signal
import threading
import time
from typing import Any

import pytest

from vizzy_runtime import node_tools
from vizzy_runtime.node_tools import (
    LatestWorker,
    Param,
    ParameterError,
    declare_parameters,
    guarded,
    replace_timer,
)
from vizzy_runtime.rclpy_compat.executors import SingleThreadedExecutor
from vizzy_runtime.rclpy_compat.node import Node
from vizzy_runtime.rclpy_compat.parameter import Parameter, SetParametersResult
from vizzy_runtime.testing import scaled, wait_until

PARAMETERS = (
    Param('rate_hz', 10.0, 'Rate [Hz], in (0, 100].', '(0, 100]'),
    Param('count', 3, 'How many, >= 1.', '[1, inf)'),
    Param('lo', 1.0, 'Lower bound, < hi.', constraints='below hi'),
    Param('hi', 2.0, 'Upper bound, > lo.', constraints='above lo'),
    Param('mode', 'fast', 'fast or exact.', choices=('fast', 'exact')),
    Param('frame_id', 'base_link', 'A frame (read-only).', read_only=True),
    ('legacy', 7, 'A bare (name, default, description) row: no rules.'),
)


def check(name: str, value: Any) -> str | None:
    if name == 'frame_id' and not value:
        return 'frame_id must not be empty'
    return None


def check_all(values: dict[str, Any]) -> str | None:
    return 'lo must be < hi' if values['lo'] >= values['hi'] else None


DEFAULTS = {'rate_hz': 10.0, 'count': 3, 'lo': 1.0, 'hi': 2.0, 'mode': 'fast',
            'frame_id': 'base_link', 'legacy': 7}


class ToolNode(Node):
    def __init__(self, context: Any, overrides: dict[str, Any] | None = None) -> None:
        super().__init__('tool_node', context=context, parameter_overrides=[
            Parameter(n, value=v) for n, v in (overrides or {}).items()])
        self.changes: list[dict[str, Any]] = []
        self.p = declare_parameters(self, PARAMETERS, check, check_all=check_all,
                                    on_change=self.changes.append)


def _set(node: Node, **values: Any) -> Any:
    return node.set_parameters_atomically([Parameter(n, value=v) for n, v in values.items()])


def test_param_rows_build_descriptors() -> None:
    rate, count = PARAMETERS[0].descriptor(), PARAMETERS[1].descriptor()
    assert [(r.from_value, r.to_value, r.step)
            for r in rate.floating_point_range] == [(0.0, 100.0, 0.0)]
    assert not len(rate.integer_range) and rate.additional_constraints == 'in (0, 100]'
    assert [(r.from_value, r.to_value) for r in count.integer_range] == [(1, 2 ** 63 - 1)]
    assert count.additional_constraints == ''       # an integer range says it all
    assert PARAMETERS[4].descriptor().additional_constraints == 'one of: fast, exact'
    assert PARAMETERS[2].descriptor().additional_constraints == 'below hi'
    assert PARAMETERS[5].descriptor().read_only
    # excluded integer bounds are the next integers; steps pass through
    seed = Param('seed', 0, 'Seed.', '[0, 2147483648)')
    assert seed.descriptor().integer_range[0].to_value == 2 ** 31 - 1
    stride = Param('stride', 8, 'Stride.', '[8, 64]', step=8).descriptor().integer_range[0]
    assert (stride.from_value, stride.to_value, stride.step) == (8, 64, 8)
    # a malformed table fails at import, not when a user sets a value
    for bad in (dict(range='0..1'), dict(range='[2, 1]'), dict(range='[1.5, 3]'),
                dict(range='[5, 9]')):
        with pytest.raises((TypeError, ValueError)):
            Param('x', 3, 'X.', **bad)
    with pytest.raises(ValueError):
        Param('m', 'slow', 'M.', choices=('fast',))


def test_startup_values_are_declared_described_and_read(context):
    node = ToolNode(context, {'rate_hz': 20.0})
    try:
        assert node.p == {**DEFAULTS, 'rate_hz': 20.0}
        assert node.describe_parameter('count').description == 'How many, >= 1.'
        assert node.describe_parameter('frame_id').read_only
        assert not node.describe_parameter('rate_hz').read_only
        assert node.describe_parameter('mode').additional_constraints == 'one of: fast, exact'
    finally:
        node.destroy_node()


def test_bad_startup_values_raise_one_line_naming_the_node_and_every_problem(context):
    with pytest.raises(ParameterError) as err:
        ToolNode(context, {'rate_hz': -1.0, 'count': 0, 'lo': 5.0, 'mode': 'slow',
                           'legacy': 'seven'})
    message = str(err.value)
    assert isinstance(err.value, ValueError) and '\n' not in message
    assert message.startswith('tool_node: ')
    assert "parameter 'rate_hz' = -1.0: out of range (0, 100]" in message      # the descriptor
    assert "parameter 'count' = 0: out of range [1, inf)" in message
    assert "parameter 'legacy' = 'seven': expected integer, got string" in message
    assert "parameter 'mode' = 'slow': mode must be one of: fast, exact; got 'slow'" in message
    assert 'lo must be < hi' in message
    assert node_tools.startup_error_line(err.value) == message
    # the excluded bound itself, which the descriptor's inclusive range admits
    with pytest.raises(ParameterError, match=r"'rate_hz' = 0.0: rate_hz must be in \(0, 100\]"):
        ToolNode(context, {'rate_hz': 0.0})


def test_invalid_sets_are_refused_with_the_reason_and_change_nothing(context):
    node = ToolNode(context)
    try:
        result = node.set_parameters([Parameter('rate_hz', value=0.0)])[0]
        assert not result.successful and result.reason == 'rate_hz must be in (0, 100], got 0.0'
        result = node.set_parameters([Parameter('rate_hz', value=101.0)])[0]   # the descriptor
        assert not result.successful and result.reason.startswith('Parameter rate_hz out of range')
        result = node.set_parameters([Parameter('mode', value='slow')])[0]
        assert not result.successful and 'one of: fast, exact' in result.reason
        result = _set(node, lo=3.0)  # valid alone, not with hi
        assert not result.successful and result.reason == 'lo must be < hi'
        result = _set(node, rate_hz=50.0, count=0)  # one bad value refuses the whole set
        assert not result.successful and 'count' in result.reason
        result = node.set_parameters([Parameter('frame_id', value='odom')])[0]
        assert not result.successful and 'read-only' in result.reason
        assert node.p == DEFAULTS
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


def test_changes_apply_only_after_every_on_set_callback_accepted(context):
    node = ToolNode(context)
    try:
        # a refusing callback added before or after declare_parameters' own: either way the
        # dict (and on_change) never sees the refused value, since they follow post-set
        node.add_on_set_parameters_callback(lambda params: SetParametersResult(
            successful=all(p.name != 'count' or p.value != 5 for p in params), reason='no 5'))
        assert not node.set_parameters([Parameter('count', value=5)])[0].successful
        assert node.p['count'] == 3 and node.changes == []
        assert node.set_parameters([Parameter('count', value=6)])[0].successful
        assert node.p['count'] == 6 and node.changes == [{'count': 6}]
    finally:
        node.destroy_node()


def test_on_change_that_raises_is_logged_and_the_value_stays_set(context, capsys):
    node = Node('failing_apply', context=context)
    try:
        def apply(changed: dict[str, Any]) -> None:
            raise RuntimeError('cannot apply')

        p = declare_parameters(node, (Param('x', 1, 'X.', '[0, 10]'),), on_change=apply)
        assert node.set_parameters([Parameter('x', value=2)])[0].successful
        assert p['x'] == 2 and node.get_parameter('x').value == 2
        assert 'applying x failed: RuntimeError: cannot apply' in capsys.readouterr().err
    finally:
        node.destroy_node()


def test_a_check_that_raises_refuses_instead(context):
    node = Node('raising', context=context)
    try:
        def bad_check(name: str, value: Any) -> str | None:
            raise TypeError('boom')

        with pytest.raises(ParameterError, match="'x' = 1: x: TypeError: boom"):
            declare_parameters(node, (('x', 1, 'X.'),), bad_check)
        node.undeclare_parameter('x')
        p = declare_parameters(node, (('x', 1, 'X.'),),
                               lambda n, v: None if v < 5 else v.missing)
        result = node.set_parameters([Parameter('use_sim_time', value=True)])[0]
        assert result.successful
        result = node.set_parameters([Parameter('x', value=2)])[0]
        assert result.successful and p['x'] == 2
        result = node.set_parameters([Parameter('x', value=7)])[0]
        assert not result.successful and 'AttributeError' in result.reason and p['x'] == 2
    finally:
        node.destroy_node()


def test_startup_error_line_reads_rclpy_parameter_exceptions(context):
    from vizzy_runtime.rclpy_compat import exceptions as exc
    from vizzy_runtime.rclpy_compat.arguments import RosArgumentError

    node = Node('plain', context=context, parameter_overrides=[Parameter('levels', value='abc'),
                                                              Parameter('gain', value=-3)])
    try:
        with pytest.raises(exc.InvalidParameterTypeException) as err:
            node.declare_parameter('levels', 5)
        assert node_tools.startup_error_line(err.value) == (
            "plain: parameter 'levels' = 'abc': expected integer, got string")
        with pytest.raises(exc.InvalidParameterValueException) as err:
            node.declare_parameter('gain', 1, Param('gain', 1, 'G.', '[0, 10]').descriptor())
        assert node_tools.startup_error_line(err.value) == (
            "plain: parameter 'gain' = -3: Parameter gain out of range. Min: 0, Max: 10, value: -3")
    finally:
        node.destroy_node()
    assert node_tools.startup_error_line(RosArgumentError(
        "--params-file p.yaml: not valid YAML (while parsing\n  a flow)")) == (
        '--params-file p.yaml: not valid YAML (while parsing a flow)')
    assert node_tools.startup_error_line(ValueError('unrelated')) is None
    assert node_tools.startup_error_line(RuntimeError('boom')) is None


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
        assert wait_until(lambda: len(ticks) >= 3, scaled(5.0), spin=executor)
        timer = replace_timer(node, timer, 0.01, lambda: ticks.append(2))
        assert wait_until(lambda: 2 in ticks, scaled(5.0), spin=executor)
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

        def get_global_executor(self) -> None:
            events.append('executor')

        def spin(self, node: Any) -> None:
            events.append('spin')
            raise KeyboardInterrupt

        def try_shutdown(self) -> None:
            events.append('shutdown')

    monkeypatch.setattr(node_tools, 'rclpy', FakeRclpy())
    # as a console script (no args) the main first re-executes itself with the loopback-bind
    # shim (loopback.py); here that would replace the test process
    monkeypatch.setattr(node_tools, 'exec_loopback_bound', lambda: events.append('exec'))

    def run_then_record_exit(main: Any) -> None:   # the real one ends the process (os._exit)
        try:
            main()
        except BaseException as exc:
            events.append(('exit', type(exc).__name__))
        else:
            events.append(('exit', None))

    monkeypatch.setattr(node_tools, 'run_then_exit', run_then_record_exit)
    # run() leaves SIGINT ignored (a node's process then exits); this test process goes on, and
    # the processes later tests start would inherit SIG_IGN: restore the handlers afterwards
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    main = node_tools.main_for(FakeNode)
    main(['x'])
    # the executor exists before the node's start-up (a signal there must not break it)
    assert events == [('init', ['x']), 'executor', 'spin', 'destroy', 'shutdown']

    events.clear()

    def failing_factory() -> Any:
        raise ValueError('bad parameters')

    try:
        node_tools.main_for(failing_factory)()
        assert events == ['exec', ('init', None), 'executor', 'shutdown', ('exit', 'ValueError')]
    finally:
        for sig, handler in handlers.items():
            signal.signal(sig, handler)


def test_latest_worker_runs_the_newest_item_and_drops_the_rest() -> None:
    gate, seen = threading.Event(), []

    def handle(item):
        gate.wait(scaled(5.0))              # busy on the first item until the test opens the gate
        seen.append(item)

    worker = LatestWorker('test_worker', handle)
    try:
        assert not worker.put(1)
        assert wait_until(lambda: not worker._waiting, scaled(5.0))   # 1 taken, the thread is busy
        assert not worker.put(2)
        assert worker.put(3) and worker.put(4)                  # 2 and 3 replaced while waiting
        gate.set()
        assert wait_until(lambda: seen == [1, 4], scaled(5.0))
    finally:
        worker.close()
    assert not worker._thread.is_alive()


def test_latest_worker_spaces_starts_by_the_period() -> None:
    starts = []
    worker = LatestWorker('test_worker', lambda item: starts.append(time.monotonic()),
                          min_period_s=lambda: 0.2)
    try:
        worker.put(1)
        assert wait_until(lambda: len(starts) == 1, scaled(5.0))
        worker.put(2)
        assert wait_until(lambda: len(starts) == 2, scaled(5.0))
    finally:
        worker.close()
    assert starts[1] - starts[0] >= 0.2 - 1e-3


def test_throttled_warnings_log_once_per_kind_and_period() -> None:
    from vizzy_runtime.input_health import ThrottledWarnings

    lines: list[str] = []

    class Logger:
        def warning(self, text: str) -> None:
            lines.append(text)

    class FakeNode:
        def get_logger(self) -> Logger:
            return Logger()

    warn = ThrottledWarnings(FakeNode(), period_s=60.0)
    assert warn('tf', 'no transform') and not warn('tf', 'no transform again')
    assert warn('clock', 'clock jumped back')            # another kind: its own period
    assert warn('tf', 'a short period', period_s=0.0)    # a per-call period overrides
    assert lines == ['no transform', 'clock jumped back', 'a short period']


def test_has_subscribers_asks_the_publisher_and_counts_a_broken_one_as_read() -> None:
    class Pub:
        def __init__(self, count: int | None) -> None:
            self.count = count

        def get_subscription_count(self) -> int:
            if self.count is None:
                raise RuntimeError('destroyed')
            return self.count

    assert not node_tools.has_subscribers(Pub(0))
    assert node_tools.has_subscribers(Pub(2))
    assert node_tools.has_subscribers(Pub(None))     # publish() will say what is wrong
