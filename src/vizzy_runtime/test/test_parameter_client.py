"""The bundled runtime's AsyncParameterClient on a bundled node (rmw_cyclonedds_cpp's wire format:
replies matched to requests by the request header, several clients at once)."""

from __future__ import annotations

import threading
import uuid

import pytest

from vizzy_runtime.rclpy_compat.exceptions import ExternalShutdownException
from vizzy_runtime.rclpy_compat.executors import SingleThreadedExecutor
from vizzy_runtime.rclpy_compat.node import Node
from vizzy_runtime.rclpy_compat.parameter import (
    FloatingPointRange,
    Parameter,
    ParameterDescriptor,
    SetParametersResult,
)
from vizzy_runtime.rclpy_compat.parameter_client import AsyncParameterClient
from vizzy_runtime.testing import scaled

TIMEOUT = scaled(20.0)


@pytest.fixture
def remote(context):
    """A node with a ranged and a validated parameter, spun in its own thread."""
    node = Node(f'remote_{uuid.uuid4().hex[:8]}', namespace='/pc', context=context)
    node.declare_parameter('gain', 1.5, ParameterDescriptor(
        description='loop gain',
        floating_point_range=[FloatingPointRange(from_value=0.0, to_value=10.0)]))
    node.declare_parameter('label', 'left')
    node.add_on_set_parameters_callback(lambda params: SetParametersResult(
        successful=all(p.name != 'label' or p.value in ('left', 'right') for p in params),
        reason='label must be left or right'))
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)

    def spin() -> None:
        try:
            while context.ok():
                executor.spin_once(0.1)
        except ExternalShutdownException:
            pass

    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    yield node
    context.try_shutdown()
    thread.join(TIMEOUT)


def result(executor, future):
    executor.spin_until_future_complete(future, TIMEOUT)
    assert future.done(), 'no reply'
    return future.result()


def test_get_set_refuse_list_describe(context, remote):
    caller = Node('caller', context=context, start_parameter_services=False)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(caller)
    client = AsyncParameterClient(caller, remote.get_fully_qualified_name())
    assert client.wait_for_services(TIMEOUT)
    assert [v.double_value
            for v in result(executor, client.get_parameters(['gain'])).values] == [1.5]
    assert result(executor,
                  client.set_parameters([Parameter('gain', value=2.5)])).results[0].successful
    assert remote.get_parameter('gain').value == 2.5
    refused = result(executor, client.set_parameters([Parameter('gain', value=11.0)])).results[0]
    assert not refused.successful and 'out of range' in refused.reason.lower()
    refused = result(executor, client.set_parameters([Parameter('label', value='up')])).results[0]
    assert (refused.successful, refused.reason) == (False, 'label must be left or right')
    assert remote.get_parameter('gain').value == 2.5
    assert remote.get_parameter('label').value == 'left'
    assert {'gain', 'label',
            'use_sim_time'} <= set(result(executor, client.list_parameters()).result.names)
    descriptor = result(executor, client.describe_parameters(['gain'])).descriptors[0]
    assert ((descriptor.description, descriptor.floating_point_range[0].to_value)
            == ('loop gain', 10.0))


def test_two_clients_get_their_own_replies(context, remote):
    """Many requests in flight from two clients at once: each future gets its own reply."""
    caller = Node('caller2', context=context, start_parameter_services=False)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(caller)
    name = remote.get_fully_qualified_name()
    clients = [AsyncParameterClient(caller, name), AsyncParameterClient(caller, name)]
    assert all(c.wait_for_services(TIMEOUT) for c in clients)
    asked = [(clients[i % 2], ['gain'] if i % 3 else ['label', 'gain']) for i in range(12)]
    futures = [c.get_parameters(names) for c, names in asked]
    replies = [result(executor, f) for f in futures]
    assert [len(r.values) for r in replies] == [len(names) for _, names in asked]
    assert all(r.values[-1].double_value == 1.5 for r in replies)
    assert all(r.values[0].string_value == 'left'
               for r, (_, names) in zip(replies, asked, strict=True) if len(names) == 2)


def test_a_missing_node_fails_the_call(context):
    caller = Node('caller3', context=context, start_parameter_services=False)
    client = AsyncParameterClient(caller, '/no_such_node')
    assert not client.wait_for_services(0.5)
    assert not client.services_are_ready()
