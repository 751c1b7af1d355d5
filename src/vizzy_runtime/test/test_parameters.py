"""Parameters as rclpy has them: descriptors, ranges, callbacks, overrides from -p and params
files."""

import pytest

from vizzy_runtime.rclpy_compat import arguments
from vizzy_runtime.rclpy_compat import exceptions as exc
from vizzy_runtime.rclpy_compat.node import Node
from vizzy_runtime.rclpy_compat.parameter import (
    FloatingPointRange,
    IntegerRange,
    Parameter,
    ParameterDescriptor,
    SetParametersResult,
)

PARAMS_YAML = """
/**:
  ros__parameters:
    shared: 1
fovea:
  ros__parameters:
    levels: 5
    sigma: 100.0
    untouched: y
/vizzy/fovea:
  ros__parameters:
    levels: 6
    sigma: 90.0
    nested:
      f0: 30
other:
  ros__parameters:
    levels: 99
"""


def test_params_file_precedence_and_nesting(context, tmp_path):
    f = tmp_path / 'p.yaml'
    f.write_text(PARAMS_YAML)
    node = Node('fovea', context=context, namespace='/vizzy',
                cli_args=['--ros-args', '--params-file', str(f), '-p', 'sigma:=80.5'])
    assert node.declare_parameter('levels', 3).value == 6          # its fully qualified entry
    assert node.declare_parameter('sigma', 1.0).value == 80.5      # -p after the file wins
    # int in YAML for a double: coerced
    assert node.declare_parameter('nested.f0', 1.0).value == 30.0
    assert node.declare_parameter('shared', 0).value == 1          # /** applies to every node
    assert node.declare_parameter('untouched', 'x').value == 'x'  # `fovea:` is /fovea (rcl)
    root = Node('fovea', context=context,
                cli_args=['--ros-args', '--params-file', str(f), '-p', 'sigma:=80.5'])
    assert root.declare_parameter('untouched', 'x').value == 'y'
    assert root.declare_parameter('levels', 3).value == 5


def test_missing_or_broken_params_file_is_a_clear_error(tmp_path):
    with pytest.raises(arguments.RosArgumentError, match='no such file'):
        arguments.parse(['--ros-args', '--params-file', str(tmp_path / 'missing.yaml')])
    bad = tmp_path / 'bad.yaml'
    bad.write_text('fovea:\n  levels: 5\n')
    with pytest.raises(arguments.RosArgumentError, match='outside any ros__parameters'):
        arguments.parse(['--ros-args', '--params-file', str(bad)])
    with pytest.raises(arguments.RosArgumentError, match="expected 'from:=to'"):
        arguments.parse(['--ros-args', '-r', 'image'])
    with pytest.raises(arguments.RosArgumentError, match='unknown --ros-args argument'):
        arguments.parse(['--ros-args', '--frobnicate'])


def test_descriptor_ranges_types_and_read_only(context):
    node = Node('ranged', context=context)
    node.declare_parameter('rate', 10.0, ParameterDescriptor(
        description='Hz', floating_point_range=[FloatingPointRange(from_value=1.0, to_value=30.0)]))
    node.declare_parameter('levels', 5, ParameterDescriptor(
        integer_range=[IntegerRange(from_value=1, to_value=7, step=1)]))
    node.declare_parameter('frame', 'base_link', ParameterDescriptor(read_only=True))
    ok, too_big, wrong_type, ro, bad_int = node.set_parameters([
        Parameter('rate', value=20.0), Parameter('rate', value=31.0),
        Parameter('rate', value='fast'),
        Parameter('frame', value='ego'), Parameter('levels', value=8)])
    assert ok.successful and node.get_parameter('rate').value == 20.0
    # rclpy's reasons, word for word
    assert not too_big.successful
    assert too_big.reason == 'Parameter rate out of range Min: 1.0, Max: 30.0, value: 31.0'
    assert not wrong_type.successful
    assert wrong_type.reason == "Wrong parameter type, expected 'Type.DOUBLE' got 'Type.STRING'"
    assert not ro.successful and ro.reason == 'Trying to set a read-only parameter: frame.'
    assert not bad_int.successful and bad_int.reason.startswith('Parameter levels out of range.')
    # the bounds admit values within rclpy's 1e-6 relative tolerance; NaN is never in range
    assert node.set_parameters([Parameter('rate', value=30.0 + 1e-5)])[0].successful
    assert not node.set_parameters([Parameter('rate', value=float('nan'))])[0].successful
    with pytest.raises(exc.InvalidParameterValueException):
        Node('ranged2', context=context,
             cli_args=['--ros-args', '-p', 'rate:=99.0']).declare_parameter(
            'rate', 10.0,
            ParameterDescriptor(
                floating_point_range=[FloatingPointRange(from_value=1.0, to_value=30.0)]))


def test_set_callbacks_can_reject_and_see_declarations(context):
    node = Node('cb', context=context)
    seen = []

    def validate(params):
        seen.extend(p.name for p in params)
        bad = [p.name for p in params if p.name == 'fovea_sigma' and p.value <= 0]
        return SetParametersResult(successful=not bad,
                                   reason='fovea_sigma must be > 0' if bad else '')

    node.add_on_set_parameters_callback(validate)
    node.declare_parameter('fovea_sigma', 100.0)
    result = node.set_parameters([Parameter('fovea_sigma', value=-1.0)])[0]
    assert not result.successful and result.reason == 'fovea_sigma must be > 0'
    assert node.get_parameter('fovea_sigma').value == 100.0
    assert seen == ['fovea_sigma', 'fovea_sigma']
    with pytest.raises(exc.ParameterNotDeclaredException):
        node.get_parameter('nope')
    with pytest.raises(exc.ParameterAlreadyDeclaredException):
        node.declare_parameter('fovea_sigma', 1.0)
    with pytest.raises(exc.ParameterNotDeclaredException):  # as rclpy: raised, not a result
        node.set_parameters([Parameter('nope', value=1)])


def test_parameter_messages_round_trip():
    for value in (True, 3, 2.5, 'x', [1, 2], [1.5, 2.0], ['a', 'b'], [True, False]):
        p = Parameter('p', value=value)
        assert Parameter.from_parameter_msg(p.to_parameter_msg()).value == value
