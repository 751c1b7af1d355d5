"""rcl_interfaces parameter services, so `ros2 param get/set/list/describe/dump` work on our nodes.

Like rclpy's ParameterService, every node (unless start_parameter_services=False) serves
<node>/describe_parameters, get_parameters, get_parameter_types, list_parameters, set_parameters and
set_parameters_atomically, with rclpy's semantics. Requests are answered in the executor thread (the
node's spin), like any rclpy callback: each request reader's listener only flags its service ready
and wakes the executor, which serves node.services.

Wire format, as rmw_cyclonedds_cpp speaks it (src/rmw_node.cpp: rmw_init_cs,
rmw_take_response_request,
rmw_send_response, check_for_response_reader, check_for_service_reader_writer;
src/serdata.hpp/.cpp):
- service S: requests on DDS topic `rq<S>Request`, replies on `rr<S>Reply`, types
  `rcl_interfaces::srv::dds_::<Srv>_Request_` / `<Srv>_Response_`;
- every sample: the 4-byte CDR encapsulation header, cdds_request_header_t {uint64 guid; int64 seq}
  (the client's request writer instance handle and its request counter, little endian), then the
  request or response fields (16 header bytes keep their CDR alignment unchanged); a reply echoes
  the request's header;
- the service's reader and writer carry USER_DATA `serviceid=<id>;` (one id for both: clients look
for a
  reply writer with the id of a matched request reader); clients carry `clientid=<id>;`, and a
  service replies once its reply writer has matched the reader with the requesting writer's clientid
  (rmw waits up to 100 ms for it);
- QoS: rclpy's ParameterService uses qos_profile_parameters (reliable, volatile, keep last 1000).
Cyclone's Python binding checks every written sample against the topic's type, so the DDS type of a
service topic here is the request/response struct with the two header fields first: same type name,
same bytes on the wire. Not mirrored: Jazzy also puts the service type's `typehash=` in USER_DATA
(informational: graph tools show it; rosbags cannot compute a service type hash).
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import cyclonedds.idl.types as idl
from cyclonedds._clayer import ddspy_take
from cyclonedds.core import DDSException, Listener
from cyclonedds.idl import IdlStruct, make_idl_struct
from cyclonedds.idl.annotations import final
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from rosbags.typesys import get_types_from_msg

from .. import dds, msgs
from . import graph
from .exceptions import ParameterNotDeclaredException, ParameterUninitializedException
from .parameter import Parameter, SetParametersResult

if TYPE_CHECKING:
    from .node import Node

# rcl_interfaces (Jazzy) service definitions, comments left out:
# https://github.com/ros2/rcl_interfaces/tree/jazzy/rcl_interfaces/srv/<Name>.srv
SRV_DEFINITIONS = {
    'DescribeParameters': 'string[] names\n---\nParameterDescriptor[] descriptors\n',
    'GetParameters': 'string[] names\n---\nParameterValue[] values\n',
    'GetParameterTypes': 'string[] names\n---\nuint8[] types\n',
    'ListParameters': 'uint64 DEPTH_RECURSIVE=0\nstring[] prefixes\nuint64 '
                      'depth\n---\nListParametersResult result\n',
    'SetParameters': 'Parameter[] parameters\n---\nSetParametersResult[] results\n',
    'SetParametersAtomically': 'Parameter[] parameters\n---\nSetParametersResult result\n',
}
SERVICES = {  # service name under the node -> service type (rclpy ParameterService)
    'describe_parameters': 'DescribeParameters',
    'get_parameters': 'GetParameters',
    'get_parameter_types': 'GetParameterTypes',
    'list_parameters': 'ListParameters',
    'set_parameters': 'SetParameters',
    'set_parameters_atomically': 'SetParametersAtomically',
}
QOS = dds.QoS(reliable=True, transient_local=False, depth=1000)  # rclpy qos_profile_parameters
RESPONSE_READER_WAIT_S = 0.1  # rmw_send_response's wait for the client's reply reader
PARAMETER_SEPARATOR = '.'

_lock = threading.Lock()
_wire_types: dict[str, type[IdlStruct]] = {}
_next_id = 0


def register_types() -> None:
    """Add rcl_interfaces/srv/<Srv>_Request and _Response to the message registry (once)."""
    store = msgs.registry().store
    with _lock:
        texts: dict[str, Any] = {}
        for srv, text in SRV_DEFINITIONS.items():
            for half, part in zip(('Request', 'Response'), text.split('---\n'), strict=True):
                name = f'rcl_interfaces/srv/{srv}_{half}'
                if name not in store.fielddefs:
                    # rosbags resolves bare type names in the parsed type's own folder: parse as msg
                    parsed = get_types_from_msg(part, f'rcl_interfaces/msg/{srv}_{half}')
                    texts[name] = parsed[f'rcl_interfaces/msg/{srv}_{half}']
        if texts:
            store.register(texts)


def wire_type(typename: str) -> type[IdlStruct]:
    """The DDS type of a service topic: cdds_request_header_t's guid and seq, then the fields."""
    register_types()
    with _lock:
        cls = _wire_types.get(typename)
        if cls is None:
            fields = {'guid': idl.uint64, 'seq': idl.int64,
                      **dds.idl_type(typename).__annotations__}
            dds_name = msgs.dds_type_name(typename)
            cls = make_idl_struct(dds_name.replace('::', '_') + 'wire', dds_name, fields)
            final(cls)
            _wire_types[typename] = cls
        return cls


def encode(header: bytes, msg: Any, typename: str) -> bytes:
    """Wire bytes of a request or reply: encapsulation, the 16-byte request header, the fields."""
    ser = bytes(msgs.serialize(msg, typename))
    data = ser[:4] + header + ser[4:]
    return data + b'\0' * (-len(data) % 4)


def decode(data: bytes, typename: str) -> tuple[bytes, Any]:
    """(16-byte request header, message) of a request or reply's wire bytes."""
    data = bytes(data)
    return data[4:20], msgs.deserialize(data[:4] + data[20:], typename)


def user_data_value(qos: Any, key: str) -> str | None:
    """A `key=value;` entry of an endpoint's USER_DATA (rmw::impl::cpp::parse_key_value)."""
    for policy in qos or []:
        if isinstance(policy, Policy.Userdata):
            for item in policy.data.decode(errors='replace').split(';'):
                k, sep, v = item.partition('=')
                if sep and k == key:
                    return v
    return None


def unique_id() -> str:
    """A client/service id as rmw_cyclonedds_cpp makes it (get_unique_csid, csid_to_string): the
    participant's GUID prefix and a big-endian counter, bytes in hex joined by dots."""
    global _next_id
    with _lock:
        _next_id += 1
        raw = dds.participant().guid.bytes[:12] + _next_id.to_bytes(4, 'big')
    return f'{raw[0]:2x}' + ''.join(f'.{b:x}' for b in raw[1:])


class _Service:
    """One service of a node: a request reader and a reply writer on rmw_cyclonedds_cpp's topics."""

    def __init__(self, node: Node, name: str, srv: str,
                 handler: Callable[[Node, Any, Any], None]) -> None:
        self.name = f'{node.get_fully_qualified_name().rstrip("/")}/{name}'
        self.request_type = f'rcl_interfaces/srv/{srv}_Request'
        self.response_type = f'rcl_interfaces/srv/{srv}_Response'
        self._node = node
        self._handler = handler
        self.ready = True  # set by the request listener; the executor calls serve()
        dp = dds.participant()
        qos = QOS.to_dds(f'serviceid={unique_id()};'.encode())
        self._reader = DataReader(dp, Topic(dp, f'rq{self.name}Request',
                                            wire_type(self.request_type)), qos,
                                  listener=Listener(
                                      on_data_available=lambda _r: self._on_request()))
        self._writer = DataWriter(dp, Topic(dp, f'rr{self.name}Reply',
                                            wire_type(self.response_type)), qos)

    @property
    def reader_guid(self) -> bytes:
        return self._reader.guid.bytes

    @property
    def writer_guid(self) -> bytes:
        return self._writer.guid.bytes

    def _on_request(self) -> None:
        self.ready = True
        self._node.context.notify()

    def serve(self) -> None:
        """Answer every waiting request (executor thread)."""
        self.ready = False
        while True:
            taken = ddspy_take(self._reader._ref, dds.ANY_STATE, 64)
            if isinstance(taken, int) or not taken:
                return
            for data, info in taken:
                if info.valid_data:
                    self._answer(data, info.publication_handle)

    def _answer(self, data: bytes, client_writer: int) -> None:
        try:
            header, request = decode(data, self.request_type)
        except Exception as err:  # noqa: BLE001 - a malformed request never stops the node
            self._node.get_logger().error(f'[{self.name}] dropped a malformed request ({len(data)} '
                                          f'bytes): {err}')
            return
        response = msgs.get_message(self.response_type)()
        try:
            self._handler(self._node, request, response)
        except Exception as err:  # noqa: BLE001 - e.g. a set-parameters callback that raised
            self._node.get_logger().error(f'[{self.name}] request failed: {type(err).__name__}: '
                                          f'{err}')
            return
        if self._client_present(client_writer):
            ret = dds.write_serialized(self._writer._ref,
                                       encode(header, response, self.response_type))
            if ret < 0:
                self._node.get_logger().error(f'[{self.name}] reply not sent: '
                                              f'{DDSException(ret, "write")}')

    def _client_present(self, client_writer: int) -> bool:
        """False if the client is gone; else wait (up to RESPONSE_READER_WAIT_S) until the reply
        writer has matched the reader of the client that sent the request, as rmw_send_response
        does."""
        deadline = time.monotonic() + RESPONSE_READER_WAIT_S
        while True:
            endpoint = self._reader.get_matched_publication_data(client_writer)
            if endpoint is None and client_writer not in self._reader.get_matched_publications():
                return False
            # endpoint None while matched: Cyclone's matched-endpoint data can lag the match
            clientid = None if endpoint is None else user_data_value(endpoint.qos, 'clientid')
            if endpoint is not None and (clientid is None or any(
                    user_data_value(getattr(self._writer.get_matched_subscription_data(h), 'qos',
                                            None),
                                    'clientid') == clientid
                    for h in self._writer.get_matched_subscriptions())):
                return True
            if time.monotonic() > deadline:
                # write anyway: delivered if the reader matches in time, dropped otherwise
                return True
            time.sleep(0.01)

    def destroy(self) -> None:
        for entity in (self._reader, self._writer):
            with contextlib.suppress(Exception):  # already gone
                entity._delete(entity._ref)


# --- handlers: rclpy's ParameterService callbacks (rclpy/parameter_service.py) -----------------

def _describe_parameters(node: Node, request: Any, response: Any) -> None:
    out = []
    for name in request.names:
        try:
            out.append(node.describe_parameter(name))
        except ParameterNotDeclaredException:
            out = []
            break
    response.descriptors = out


def _get_parameters(node: Node, request: Any, response: Any) -> None:
    out = []
    for name in request.names:
        try:
            out.append(node.get_parameter(name).get_parameter_value())
        except (ParameterNotDeclaredException, ParameterUninitializedException):
            out = []
            break
    response.values = out


def _get_parameter_types(node: Node, request: Any, response: Any) -> None:
    out: list[int] = []
    for name in request.names:
        if not node.has_parameter(name):  # rclpy Node.get_parameter_type raises for these
            out = []
            break
        out.append(int(node.get_parameter(name).type_))
    response.types = out


def list_parameters(names: list[str], prefixes: list[str], depth: int) -> Any:
    """rclpy Node.list_parameters over `names` (rcl_interfaces/msg/ListParametersResult)."""
    result = msgs.get_message('rcl_interfaces/msg/ListParametersResult')()

    def shallow(s: str) -> bool:
        return s.count(PARAMETER_SEPARATOR) < depth

    recursive = not prefixes and depth == 0  # DEPTH_RECURSIVE
    for name in names:
        if (not recursive and not (not prefixes and shallow(name))
                and not any(name == prefix or (name.startswith(prefix + PARAMETER_SEPARATOR)
                                               and (depth == 0 or shallow(name[len(prefix) + 1:])))
                            for prefix in prefixes)):
            continue
        result.names.append(name)
        last = name.rfind(PARAMETER_SEPARATOR)
        if last != -1 and name[:last] not in result.prefixes:
            result.prefixes.append(name[:last])
    return result


def _list_parameters(node: Node, request: Any, response: Any) -> None:
    response.result = list_parameters(list(node._parameters), list(request.prefixes),
                                      int(request.depth))


def _set_one_atomically(node: Node, params: list[Any]) -> Any:
    try:
        return node.set_parameters_atomically([Parameter.from_parameter_msg(p) for p in params])
    except (ParameterNotDeclaredException, TypeError, ValueError) as err:
        return SetParametersResult(successful=False, reason=str(err))


def _set_parameters(node: Node, request: Any, response: Any) -> None:
    response.results = [_set_one_atomically(node, [p]) for p in request.parameters]


def _set_parameters_atomically(node: Node, request: Any, response: Any) -> None:
    response.result = _set_one_atomically(node, list(request.parameters))


_HANDLERS = {
    'describe_parameters': _describe_parameters,
    'get_parameters': _get_parameters,
    'get_parameter_types': _get_parameter_types,
    'list_parameters': _list_parameters,
    'set_parameters': _set_parameters,
    'set_parameters_atomically': _set_parameters_atomically,
}


class ParameterServices:
    """A node's six parameter services, answered from its executor."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self.services = [_Service(node, name, srv, _HANDLERS[name])
                         for name, srv in SERVICES.items()]
        node.services.extend(self.services)  # the executor serves node.services, as rclpy's does
        graph.set_extra_endpoints(node, readers=[s.reader_guid for s in self.services],
                                  writers=[s.writer_guid for s in self.services])

    def destroy(self) -> None:
        for service in self.services:
            if service in self._node.services:
                self._node.services.remove(service)
            service.destroy()


_running: dict[Node, ParameterServices] = {}


def start(node: Node) -> None:
    """Serve the node's parameters (hook in Node.__init__, before the node is announced)."""
    _running[node] = ParameterServices(node)


def stop(node: Node) -> None:
    """Hook in Node.destroy_node."""
    services = _running.pop(node, None)
    if services is not None:
        services.destroy()
