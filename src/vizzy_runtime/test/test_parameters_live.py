"""ROS-native parameters on the runtime under test (the bundled one, or the real rclpy with
VIZZY_RUNTIME=ros): descriptor ranges the middleware itself enforces, node_tools' tables
validated on-set and applied post-set, /parameter_events, and start-up errors as one line."""

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from vizzy_runtime.node_tools import Param, ParameterError, declare_parameters, startup_error_line
from vizzy_runtime.ros import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    Node,
    Parameter,
    QoSProfile,
    SingleThreadedExecutor,
    message,
)
from vizzy_runtime.testing import real_rclpy_env, real_rclpy_python, repo_root, scaled, wait_until

ParameterEvent = message('rcl_interfaces/msg/ParameterEvent')

TABLE = (
    Param('levels', 5, 'Pyramid levels, in [1, 10].', '[1, 10]'),
    Param('rate_hz', 15.0, 'Rate [Hz], in (0, 120].', '(0, 120]'),
    Param('mode', 'fast', 'fast or exact.', choices=('fast', 'exact')),
    Param('frame', 'base_link', 'A frame (read-only).', read_only=True),
)


class TableNode(Node):
    def __init__(self, context: Any, overrides: dict[str, Any] | None = None) -> None:
        super().__init__('param_table', context=context, parameter_overrides=[
            Parameter(n, value=v) for n, v in (overrides or {}).items()])
        self.applied: list[dict[str, Any]] = []
        self.p = declare_parameters(self, TABLE, on_change=self.applied.append)


@pytest.mark.live
def test_descriptor_ranges_are_refused_by_the_middleware(context):
    node = Node('plain_ranges', context=context)      # no node_tools callback: descriptors only
    try:
        for spec in TABLE[:2]:
            node.declare_parameter(spec.name, spec.default, spec.descriptor())
        results = node.set_parameters([
            Parameter('levels', value=11), Parameter('levels', value=0),
            Parameter('levels', value=10), Parameter('rate_hz', value=120.5),
            Parameter('rate_hz', value=0.0), Parameter('rate_hz', value='fast')])
        assert [r.successful for r in results] == [False, False, True, False, True, False]
        assert results[0].reason == 'Parameter levels out of range. Min: 1, Max: 10, value: 11'
        assert results[3].reason == (
            'Parameter rate_hz out of range Min: 0.0, Max: 120.0, value: 120.5')
        assert results[5].reason.startswith('Wrong parameter type')
        assert node.get_parameter('levels').value == 10
        described = node.describe_parameter('levels')
        assert [(r.from_value, r.to_value, r.step) for r in described.integer_range] == [(1, 10, 0)]
        described = node.describe_parameter('rate_hz')
        assert described.additional_constraints == 'in (0, 120]'
    finally:
        node.destroy_node()


@pytest.mark.live
def test_refused_overrides_raise_rclpys_exceptions_read_as_one_line(context):
    node = Node('plain_overrides', context=context, parameter_overrides=[
        Parameter('levels', value=-3), Parameter('name', value=4)])
    try:
        with pytest.raises(InvalidParameterValueException) as err:
            node.declare_parameter('levels', 5, TABLE[0].descriptor())
        assert startup_error_line(err.value) == (
            "plain_overrides: parameter 'levels' = -3: "
            'Parameter levels out of range. Min: 1, Max: 10, value: -3')
        with pytest.raises(InvalidParameterTypeException) as err:
            node.declare_parameter('name', 'x')
        assert startup_error_line(err.value) == (
            "plain_overrides: parameter 'name' = 4: expected string, got integer")
    finally:
        node.destroy_node()


@pytest.mark.live
def test_a_table_that_cannot_start_raises_one_line(context):
    with pytest.raises(ParameterError) as err:
        TableNode(context, {'levels': -3, 'rate_hz': 0.0, 'mode': 'slow', 'frame': 7})
    assert startup_error_line(err.value) == str(err.value) == (
        "param_table: parameter 'levels' = -3: out of range [1, 10]; "
        "parameter 'frame' = 7: expected string, got integer; "
        "parameter 'rate_hz' = 0.0: rate_hz must be in (0, 120], got 0.0; "
        "parameter 'mode' = 'slow': mode must be one of: fast, exact; got 'slow'")


@pytest.mark.live
def test_sets_are_validated_on_set_and_applied_post_set(context):
    node = TableNode(context)
    try:
        seen: list[list[str]] = []
        node.add_post_set_parameters_callback(lambda params: seen.append([p.name for p in params]))
        refused = node.set_parameters([
            Parameter('rate_hz', value=0.0),        # node_tools: the excluded bound
            Parameter('levels', value=11),          # the descriptor's range
            Parameter('mode', value='slow'),        # node_tools: the choices
            Parameter('frame', value='odom')])      # the descriptor's read_only
        assert not any(r.successful for r in refused)
        assert refused[0].reason == 'rate_hz must be in (0, 120], got 0.0'
        assert refused[1].reason == 'Parameter levels out of range. Min: 1, Max: 10, value: 11'
        assert 'one of: fast, exact' in refused[2].reason
        assert refused[3].reason == 'Trying to set a read-only parameter: frame.'
        assert node.applied == [] and seen == []
        result = node.set_parameters_atomically([Parameter('levels', value=7),
                                                 Parameter('rate_hz', value=30.0)])
        assert result.successful
        assert node.p['levels'] == 7 and node.p['rate_hz'] == 30.0
        assert node.applied == [{'levels': 7, 'rate_hz': 30.0}]
        assert seen == [['levels', 'rate_hz']]
    finally:
        node.destroy_node()


@pytest.mark.live
def test_declarations_and_changes_go_out_on_parameter_events(context):
    events: list[Any] = []
    listener = Node('parameter_events_listener', context=context)
    listener.create_subscription(ParameterEvent, '/parameter_events', events.append,
                                 QoSProfile(depth=1000))   # rclpy's profile: reliable, volatile
    talker = Node('parameter_events_talker', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(listener)
    try:
        assert wait_until(
            lambda: talker._parameter_event_publisher.get_subscription_count() > 0, scaled(20.0),
            spin=executor)
        talker.declare_parameter('gain', 2, Param('gain', 2, 'G.', '[0, 10]').descriptor())
        assert talker.set_parameters([Parameter('gain', value=3)])[0].successful
        assert not talker.set_parameters([Parameter('gain', value=99)])[0].successful

        def ours() -> list[Any]:
            return [e for e in events if e.node == '/parameter_events_talker']

        def names(field: str) -> list[tuple[str, int]]:
            return [(p.name, p.value.integer_value) for e in ours() for p in getattr(e, field)]

        assert wait_until(lambda: ('gain', 3) in names('changed_parameters'), scaled(20.0),
                          spin=executor)
        assert ('gain', 2) in names('new_parameters')
        assert ('gain', 99) not in names('changed_parameters')   # refused: no event
        assert all(e.stamp.sec > 0 for e in ours())
    finally:
        executor.remove_node(listener)
        talker.destroy_node()
        listener.destroy_node()


def _start_foveation(executable: Path, env: dict[str, str], *args: str) -> Any:
    return subprocess.run([str(executable), '--ros-args', *args], env=env, capture_output=True,
                          text=True, timeout=scaled(120))


@pytest.mark.slow
@pytest.mark.parametrize('tier', ['bundled', 'ros'])
def test_a_node_started_with_a_bad_parameter_says_so_in_one_line(tier):
    """`foveation --ros-args -p levels:=abc` (and an out-of-range -p) on each venv's executable:
    exit status 2 and exactly one line naming node, parameter and rule: no traceback, not even
    from destroying the half-built node."""
    if tier == 'ros':
        bin_dir, env = real_rclpy_python().parent, real_rclpy_env()
    else:
        bin_dir = Path(sys.executable).parent
        env = dict(real_rclpy_env(), VIZZY_RUNTIME='bundled')
        if not (bin_dir / 'foveation').exists():
            bin_dir = repo_root() / '.venv' / 'bin'
    for args, line in [
            (('-p', 'levels:=abc'),
             "foveation: parameter 'levels' = 'abc': expected integer, got string"),
            (('-p', 'levels:=-3'), "foveation: parameter 'levels' = -3: out of range [1, 10]")]:
        done = _start_foveation(bin_dir / 'foveation', env, *args)
        assert done.returncode == 2, done.stderr[-3000:]
        assert 'Traceback' not in done.stderr, done.stderr[-3000:]
        assert done.stderr.strip() == line, done.stderr[-2000:]
