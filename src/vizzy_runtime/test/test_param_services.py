"""Parameter services (vizzy_runtime.rclpy_compat.param_services) with rmw_cyclonedds_cpp's wire
format.

The client here is written against the wire format itself, from its own DDS participant: requests
are made by Cyclone's own serializer (struct = request header guid/seq, then the request fields),
replies are decoded by Cyclone's own deserializer, and service availability is judged the way
rmw_cyclonedds_cpp's rmw_service_server_is_available does (a matched request reader and reply
writer with one serviceid).
"""

from __future__ import annotations

import os
import random
import threading
import time
import uuid
from collections.abc import Callable
from typing import Any

import pytest

from vizzy_runtime import dds, msgs

if dds._participant is None:  # the process's participant does not exist yet: pick our own domain
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(100, 200)))

from cyclonedds._clayer import ddspy_take  # noqa: E402
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402

from vizzy_runtime.rclpy_compat import graph, param_services  # noqa: E402
from vizzy_runtime.rclpy_compat.context import Context  # noqa: E402
from vizzy_runtime.rclpy_compat.exceptions import ExternalShutdownException  # noqa: E402
from vizzy_runtime.rclpy_compat.executors import SingleThreadedExecutor  # noqa: E402
from vizzy_runtime.rclpy_compat.node import Node  # noqa: E402
from vizzy_runtime.rclpy_compat.parameter import (  # noqa: E402
    FloatingPointRange,
    ParameterDescriptor,
    SetParametersResult,
)
from vizzy_runtime.testing import scaled  # noqa: E402

TIMEOUT = scaled(15.0)
ParameterValueIdl = dds.idl_type('rcl_interfaces/msg/ParameterValue')
ParameterIdl = dds.idl_type('rcl_interfaces/msg/Parameter')


def wait_for(predicate: Callable[[], Any], what: str, timeout: float = TIMEOUT) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f'timed out waiting for {what}')
        time.sleep(0.02)


def value(type_: int, **field: Any) -> Any:
    fields = dict(bool_value=False, integer_value=0, double_value=0.0, string_value='',
                  byte_array_value=[],
                  bool_array_value=[], integer_array_value=[], double_array_value=[],
                  string_array_value=[])
    fields.update(field)
    return ParameterValueIdl(type=type_, **fields)


class Client:
    """A client of one service, as rmw_cyclonedds_cpp makes one: USER_DATA clientid on its request
    writer and reply reader; header guid = the request writer's instance handle, seq = a counter."""

    def __init__(self, dp: DomainParticipant, service: str, srv: str) -> None:
        self.request_cls = param_services.wire_type(f'rcl_interfaces/srv/{srv}_Request')
        self.response_cls = param_services.wire_type(f'rcl_interfaces/srv/{srv}_Response')
        self.response_type = f'rcl_interfaces/srv/{srv}_Response'
        qos = dds.QoS(reliable=True,
                      depth=10).to_dds(f'clientid={param_services.unique_id()};'.encode())
        self.writer = DataWriter(dp, Topic(dp, f'rq{service}Request', self.request_cls), qos)
        self.reader = DataReader(dp, Topic(dp, f'rr{service}Reply', self.response_cls), qos)
        self.seq = 0

    def server_available(self) -> bool:
        ids = {param_services.user_data_value(self.writer.get_matched_subscription_data(h).qos,
                                              'serviceid')
               for h in self.writer.get_matched_subscriptions()}
        return any(param_services.user_data_value(self.reader.get_matched_publication_data(h).qos,
                                                  'serviceid')
                   in ids - {None} for h in self.reader.get_matched_publications())

    def server_writer_guids(self) -> set[bytes]:
        return {self.reader.get_matched_publication_data(h).key.bytes
                for h in self.reader.get_matched_publications()}

    def call(self, **fields: Any) -> Any:
        """Send a request, return the reply decoded by Cyclone (after checking msgs decodes it the
        same)."""
        wait_for(self.server_available, 'the service')
        self.seq += 1
        guid = self.writer.instance_handle % 2**64  # the binding reports it signed
        self.writer.write(self.request_cls(guid=guid, seq=self.seq, **fields))
        deadline = time.monotonic() + TIMEOUT
        while time.monotonic() < deadline:
            for data, info in ddspy_take(self.reader._ref, dds.ANY_STATE, 16):
                reply = self.response_cls.deserialize(data)
                if info.valid_data and (reply.guid, reply.seq) == (guid, self.seq):
                    header, ours = param_services.decode(data, self.response_type)
                    assert header == (guid.to_bytes(8, 'little')
                                      + self.seq.to_bytes(8, 'little', signed=True))
                    # Cyclone's own bytes for the wire struct, padded to 4 bytes
                    own = reply.serialize()
                    assert own + b'\0' * (-len(own) % 4) == data  # as Cyclone's writer sends them
                    # msgs agrees
                    assert param_services.encode(header, ours, self.response_type) == data
                    return reply
            time.sleep(0.01)
        raise AssertionError(f'no reply from {self.reader.topic.name}')


@pytest.fixture
def served(context: Context):
    """A node with parameters, spun by an executor thread, and a client participant."""
    suffix = uuid.uuid4().hex[:8]
    node = Node(f'params_{suffix}', namespace='/ptest', context=context)
    node.declare_parameter('gain', 1.5, ParameterDescriptor(
        description='loop gain',
        floating_point_range=[FloatingPointRange(from_value=0.0, to_value=10.0)]))
    node.declare_parameter('count', 3)
    node.declare_parameter('label', 'left')
    node.declare_parameter('nested.a.b', 7)
    callback_threads: list[int] = []

    def on_set(params: list[Any]) -> Any:
        callback_threads.append(threading.get_ident())
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(on_set)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    spinning: list[int] = []

    def spin() -> None:
        spinning.append(threading.get_ident())
        try:
            while context.ok():
                executor.spin_once(0.1)
        except ExternalShutdownException:
            pass

    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    # the domain (loopback configuration) exists before the client participant joins
    dds.participant()
    dp = DomainParticipant(dds.domain_id())
    fqn = node.get_fully_qualified_name()
    clients = {name: Client(dp, f'{fqn}/{name}', srv)
               for name, srv in param_services.SERVICES.items()}
    yield node, clients, callback_threads, spinning
    context.try_shutdown()
    thread.join(TIMEOUT)


def test_srv_types_and_request_bytes() -> None:
    param_services.register_types()
    reg = msgs.registry()
    assert ([n for n, _ in reg.fields('rcl_interfaces/srv/ListParameters_Request')]
            == ['prefixes', 'depth'])
    assert (reg.constants('rcl_interfaces/srv/ListParameters_Request')
            == [('DEPTH_RECURSIVE', 'uint64', 0)])
    assert msgs.dds_type_name('rcl_interfaces/srv/GetParameters_Request') == \
        'rcl_interfaces::srv::dds_::GetParameters_Request_'
    # encode(): encapsulation + header + fields, byte for byte what Cyclone makes of the wire struct
    t = 'rcl_interfaces/srv/SetParameters_Request'
    header = (0x1122334455667788).to_bytes(8, 'little') + (42).to_bytes(8, 'little')
    msg = msgs.get_message(t)(parameters=[
        msgs.get_message('rcl_interfaces/msg/Parameter')(name='x', value=msgs.get_message(
            'rcl_interfaces/msg/ParameterValue')(type=3, double_value=0.5))])
    theirs = param_services.wire_type(t)(guid=0x1122334455667788, seq=42, parameters=[
        ParameterIdl(name='x', value=value(3, double_value=0.5))]).serialize()
    assert param_services.encode(header, msg, t) == theirs
    got_header, decoded = param_services.decode(theirs, t)
    assert got_header == header and decoded.parameters[0].value.double_value == 0.5


def test_list_parameters_semantics() -> None:
    names = ['a', 'b.c', 'b.d.e', 'f.g']
    result = param_services.list_parameters(names, [], 0)
    assert result.names == names and result.prefixes == ['b', 'b.d', 'f']
    assert param_services.list_parameters(names, [], 1).names == ['a']
    assert param_services.list_parameters(names, ['b'], 1).names == ['b.c']
    assert param_services.list_parameters(names, ['b'], 2).names == ['b.c', 'b.d.e']
    assert param_services.list_parameters(names, ['b'], 0).names == ['b.c', 'b.d.e']


def test_parameter_services_answer_like_rclpy(served: Any) -> None:
    node, clients, callback_threads, spinning = served

    reply = clients['get_parameters'].call(names=['gain', 'count', 'label'])
    assert [(v.type, v.double_value, v.integer_value, v.string_value) for v in reply.values] == \
        [(3, 1.5, 0, ''), (2, 0.0, 3, ''), (4, 0.0, 0, 'left')]
    # rclpy: all or none
    assert clients['get_parameters'].call(names=['gain', 'missing']).values == []

    types = clients['get_parameter_types'].call(names=['gain', 'count', 'label']).types
    assert list(types) == [3, 2, 4]
    assert list(clients['get_parameter_types'].call(names=['missing']).types) == []

    result = clients['list_parameters'].call(prefixes=[], depth=0).result
    assert {'gain', 'count', 'label', 'nested.a.b', 'use_sim_time'} <= set(result.names)
    assert 'nested.a' in result.prefixes
    assert clients['list_parameters'].call(prefixes=['nested'], depth=1).result.names == []
    assert clients['list_parameters'].call(prefixes=['nested'],
                                           depth=2).result.names == ['nested.a.b']

    [descriptor] = clients['describe_parameters'].call(names=['gain']).descriptors
    assert (descriptor.name, descriptor.type, descriptor.description) == ('gain', 3, 'loop gain')
    assert [(r.from_value, r.to_value) for r in descriptor.floating_point_range] == [(0.0, 10.0)]
    assert clients['describe_parameters'].call(names=['missing']).descriptors == []

    results = clients['set_parameters'].call(parameters=[
        ParameterIdl(name='gain', value=value(3, double_value=2.5)),
        ParameterIdl(name='gain', value=value(3, double_value=20.0)),  # outside [0, 10]
        ParameterIdl(name='count', value=value(4, string_value='x')),  # wrong type
        ParameterIdl(name='missing', value=value(2, integer_value=1))]).results
    assert [r.successful for r in results] == [True, False, False, False]
    assert all(r.reason for r in results[1:])
    assert node.get_parameter('gain').value == 2.5

    result = clients['set_parameters_atomically'].call(parameters=[
        ParameterIdl(name='gain', value=value(3, double_value=3.0)),
        ParameterIdl(name='count', value=value(4, string_value='bad'))]).result
    assert not result.successful and node.get_parameter('gain').value == 2.5
    result = clients['set_parameters_atomically'].call(parameters=[
        ParameterIdl(name='gain', value=value(3, double_value=3.0)),
        ParameterIdl(name='count', value=value(2, integer_value=5))]).result
    assert result.successful
    assert (node.get_parameter('gain').value, node.get_parameter('count').value) == (3.0, 5)

    # the on-set callbacks ran in the executor's thread
    assert callback_threads and set(callback_threads) == set(spinning)


def test_services_are_announced_and_leave_with_the_node(served: Any) -> None:
    node, clients, _, _ = served
    for client in clients.values():
        wait_for(client.server_available, 'every service')
    ours = {n.name: n for n in graph.snapshot() if n.local}[node.get_name()]
    # each reply writer the clients matched (DDS discovery) is one of the node's announced writers
    writers = set().union(*(c.server_writer_guids() for c in clients.values()))
    assert len(writers) == 6 and writers <= set(ours.writer_gids)
    assert len(ours.reader_gids) == 6  # the request readers (no subscriptions on this node)
    node.destroy_node()
    for client in clients.values():
        wait_for(lambda client=client: not client.server_available(), 'the service gone')
    assert node.get_name() not in {n.name for n in graph.snapshot() if n.local}
