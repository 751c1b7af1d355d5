"""`vizzy param list|get|set|describe`: ros2 param's verbs through the rcl_interfaces services, for
nodes on the bundled runtime and on ROS 2 (rmw_fastrtps_cpp or rmw_cyclonedds_cpp) alike."""

from __future__ import annotations

import argparse
import sys
from typing import Any

import yaml

TYPE_NAMES = ['not set', 'boolean', 'integer', 'double', 'string', 'byte array', 'boolean array',
              'integer array', 'double array', 'string array']


def _client(ns: argparse.Namespace) -> tuple[Any, Any, Any]:
    """(node, executor, client) on the bundled runtime, the remote node's services found."""
    from .rclpy_compat.context import Context
    from .rclpy_compat.executors import SingleThreadedExecutor
    from .rclpy_compat.node import Node
    from .rclpy_compat.parameter_client import AsyncParameterClient

    context = Context()
    context.init([])
    node = Node('_vizzy_param', context=context, start_parameter_services=False)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    name = ns.node if ns.node.startswith('/') else f'/{ns.node}'
    client = AsyncParameterClient(node, name)
    if not client.wait_for_services(ns.timeout):
        context.try_shutdown()
        raise TimeoutError(f'node {name}: no parameter services within {ns.timeout:g} s '
                           '(is it running on this ROS_DOMAIN_ID?)')
    return node, executor, client


def _result(executor: Any, client: Any, future: Any, timeout: float, what: str) -> Any:
    executor.spin_until_future_complete(future, timeout)
    if not future.done():
        client.forget(future)
        raise TimeoutError(f'{what}: no reply within {timeout:g} s')
    return future.result()


def _value_text(value: Any) -> str:
    from .rclpy_compat.parameter import parameter_value_to_python
    python = parameter_value_to_python(value)
    return repr(python) if isinstance(python, (list, bytes)) else str(python)  # arrays as lists


INT64 = (-(1 << 63), (1 << 63) - 1)     # a ROS 2 integer parameter is an int64


def parse_value(name: str, text: str) -> Any:
    """A parameter value as `ros2 param set` reads it (YAML): a Parameter, or ValueError with
    the reason in one line (not YAML, no parameter type, an integer beyond int64)."""
    from .rclpy_compat.parameter import Parameter
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ValueError(f'not YAML ({" ".join(str(err).split())})') from None
    ints = [v for v in (value if isinstance(value, list) else [value])
            if isinstance(v, int) and not isinstance(v, bool)]
    if any(not INT64[0] <= v <= INT64[1] for v in ints):
        raise ValueError('an integer beyond the 64-bit range of a ROS 2 integer parameter')
    try:
        return Parameter(name, value=value)
    except (TypeError, ValueError) as err:
        raise ValueError(str(err)) from None


def cmd_param(ns: argparse.Namespace) -> int:
    param = None
    if ns.param_verb == 'set':        # a bad value is refused before any node is asked
        try:
            param = parse_value(ns.name, ns.value)
        except ValueError as err:
            print(f'vizzy: {ns.name}: cannot read value {ns.value!r}: {err}', file=sys.stderr)
            return 2
    node, executor, client = _client(ns)
    try:
        name = client.remote_node_name
        if ns.param_verb == 'list':
            reply = _result(executor, client, client.list_parameters(), ns.timeout, name)
            for param in sorted(reply.result.names):
                print(f'  {param}')
            return 0
        if ns.param_verb == 'get':
            reply = _result(executor, client, client.get_parameters([ns.name]), ns.timeout, name)
            if not reply.values or reply.values[0].type == 0:
                print(f'vizzy: {name}: parameter {ns.name!r} not set', file=sys.stderr)
                return 1
            value = reply.values[0]
            print(f'{TYPE_NAMES[value.type].capitalize()} value is: {_value_text(value)}')
            return 0
        if ns.param_verb == 'describe':
            reply = _result(executor, client, client.describe_parameters([ns.name]), ns.timeout,
                            name)
            if not reply.descriptors:
                print(f'vizzy: {name}: parameter {ns.name!r} not declared', file=sys.stderr)
                return 1
            d = reply.descriptors[0]
            print(f'Parameter name: {d.name}\n  Type: {TYPE_NAMES[d.type]}')
            if d.description:
                print(f'  Description: {d.description}')
            if d.additional_constraints:
                print(f'  Constraints: {d.additional_constraints}')
            for r in list(d.floating_point_range) + list(d.integer_range):
                print(f'  Range: [{r.from_value}, {r.to_value}]'
                      + (f' step {r.step}' if r.step else ''))
            if d.read_only:
                print('  Read only: true')
            return 0
        # set: the value was read (parse_value) above
        reply = _result(executor, client, client.set_parameters([param]), ns.timeout, name)
        result = reply.results[0]
        if result.successful:
            print('Set parameter successful')
            return 0
        print(f'Setting parameter failed: {result.reason}', file=sys.stderr)
        return 1
    finally:
        client.destroy()
        node.destroy_node()
        node.context.try_shutdown()


def add_parser(sub: Any) -> None:
    param = sub.add_parser('param', help="a node's parameters (like ros2 param)").add_subparsers(
        dest='param_verb', required=True)
    for verb, args in (('list', ()), ('get', ('name',)), ('describe', ('name',)),
                       ('set', ('name', 'value'))):
        p = param.add_parser(verb)
        p.add_argument('node', help='node name, e.g. /foveation')
        for arg in args:
            p.add_argument(arg)
        p.add_argument('--timeout', type=float, default=5.0,
                       help='seconds to wait for the node and for each reply (default 5)')
        p.set_defaults(func=cmd_param)
