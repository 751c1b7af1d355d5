"""rclpy.parameter_client.AsyncParameterClient for the bundled runtime: another node's parameters
through its rcl_interfaces services, whether that node runs on the bundled runtime or on ROS 2.

Two wire formats, chosen per request from the service's endpoints:
- rmw_cyclonedds_cpp (and this runtime's param_services): the service's reader and writer carry
  USER_DATA `serviceid=`; every sample starts with the 16-byte request header (the client's writer
  handle and a sequence number), and a reply is matched to its request by that header.
- rmw_fastrtps_cpp (Jazzy's default): no serviceid; samples are the bare request/response, and Fast
  DDS carries the request identity in the RTPS inline QoS (PID_RELATED_SAMPLE_IDENTITY), which
  Cyclone neither writes nor shows. Requests therefore go one at a time and a reply answers the
  oldest request. A Fast DDS service sends every reply to every client of that service, so another
  client calling the same node at the same moment could have its reply taken for ours.

The reverse, a Fast DDS client calling a service of this runtime, cannot work: rmw_fastrtps_cpp's
client keeps only replies whose related sample identity names it
(ClientListener::on_data_available),
and Cyclone DDS has no way to send that inline QoS. (rmw_cyclonedds_cpp clients can: same format.)
"""

from __future__ import annotations

import collections
import contextlib
import threading
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from cyclonedds._clayer import ddspy_take
from cyclonedds.core import Listener
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from .. import dds, msgs
from .executors import Future
from .param_services import QOS, SERVICES, decode, encode, unique_id, user_data_value, wire_type
from .parameter import Parameter
from .qos import QoSProfile, qos_profile_services_default

if TYPE_CHECKING:
    from .node import Node

SERVICE_WAIT_S = 5.0  # how long a call waits for its service to be discovered
FAST_DDS_VENDOR = b'\x01\x0f'  # RTPS vendor id of eProsima Fast DDS, the first 2 bytes of its GUIDs


class ServiceClient:
    """A client of one rcl_interfaces service (request writer + reply reader), futures completed by
    the node's executor like rclpy's."""

    def __init__(self, node: Node, service: str, srv: str) -> None:
        self.service = service
        self.request_type = f'rcl_interfaces/srv/{srv}_Request'
        self.response_type = f'rcl_interfaces/srv/{srv}_Response'
        self._node = node
        self._lock = threading.Lock()
        self._seq = 0
        self._headed: dict[tuple[int, int], Future] = {}  # (guid, seq) -> future, header format
        self._bare: collections.deque[tuple[bytes, Future]] = collections.deque()  # Fast DDS format
        self._bare_sent: Future | None = None
        self.ready = False  # set by the reply listeners; the executor calls serve()
        dp = dds.participant()
        self._qos = QOS.to_dds(f'clientid={unique_id()};'.encode())
        # Cyclone checks every sample against its topic's type, so each format has its own pair:
        # the wire struct (header fields first, as a bundled service's) now; the bare request and
        # response (Fast DDS services; they announce no type information and so match both) once a
        # service without serviceid shows up.
        self._writer = DataWriter(dp, Topic(dp, f'rq{service}Request',
                                            wire_type(self.request_type)), self._qos)
        self._reader: DataReader | None = DataReader(
            dp, Topic(dp, f'rr{service}Reply', wire_type(self.response_type)), self._qos,
            listener=Listener(on_data_available=lambda _r: self._on_reply()))
        self._bare_writer: DataWriter | None = None
        self._bare_reader: DataReader | None = None
        self._guid = self._writer.instance_handle % 2**64  # the binding reports it signed
        self._headed_format = True
        node.clients.append(self)

    def _request_readers(self) -> list[tuple[bytes, str | None]]:
        """(GUID, serviceid or None) of each matched request reader whose data Cyclone has."""
        out = []
        for handle in self._writer.get_matched_subscriptions():
            data = self._writer.get_matched_subscription_data(handle)
            if data is not None:  # None: matched a moment ago or going away; ask again later
                out.append((data.key.bytes, user_data_value(data.qos, 'serviceid')))
        return out

    def _service_ids(self) -> set[str]:
        return {sid for _, sid in self._request_readers() if sid is not None}

    def _is_fast_dds_service(self) -> bool:
        """A request reader of rmw_fastrtps_cpp: eProsima's vendor id opens its GUID, no
        serviceid."""
        return any(guid[:2] == FAST_DDS_VENDOR and sid is None
                   for guid, sid in self._request_readers())

    def _bare_endpoints(self) -> tuple[DataWriter, DataReader]:
        with self._lock:
            if self._bare_writer is None or self._bare_reader is None:
                dp = dds.participant()
                self._bare_writer = DataWriter(
                    dp, Topic(dp, f'rq{self.service}Request', dds.idl_type(self.request_type)),
                    self._qos)
                self._bare_reader = DataReader(
                    dp, Topic(dp, f'rr{self.service}Reply', dds.idl_type(self.response_type)),
                    self._qos,
                    listener=Listener(on_data_available=lambda _r: self._on_reply()))
                # the wire-typed reader would only log a failed deserialization per reply
                headed, self._reader = self._reader, None
                if headed is not None:
                    headed._delete(headed._ref)
            return self._bare_writer, self._bare_reader

    def service_is_ready(self) -> bool:
        """A request reader and a reply writer are matched: the same service's (one serviceid) for
        rmw_cyclonedds_cpp's format, a Fast DDS pair otherwise."""
        requests = self._service_ids()
        reader = self._reader
        if requests and reader is not None:
            replies = {user_data_value(getattr(reader.get_matched_publication_data(h), 'qos', None),
                                       'serviceid') for h in reader.get_matched_publications()}
            if requests & replies:
                self._headed_format = True
                return True
            return False
        if not self._is_fast_dds_service():
            return False
        writer, bare_reader = self._bare_endpoints()
        if writer.get_matched_subscriptions() and bare_reader.get_matched_publications():
            self._headed_format = False
            return True
        return False

    def wait_for_service(self, timeout_sec: float | None = None) -> bool:
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not self.service_is_ready():
            if deadline is not None and time.monotonic() >= deadline:
                return False
            time.sleep(0.02)
        return True

    def call_async(self, request: Any) -> Future:
        """Send a request; its future completes in the executor. Unlike rclpy's, this waits (up to
        SERVICE_WAIT_S) for the service to be discovered: the wire format depends on it."""
        future = Future()
        if not self.wait_for_service(SERVICE_WAIT_S):
            future.set_exception(RuntimeError(f'{self.service}: no such service'))
            return future
        if self._headed_format:  # as service_is_ready found it (matched-endpoint data can blink)
            with self._lock:
                self._seq += 1
                header = self._guid.to_bytes(8, 'little') + self._seq.to_bytes(8, 'little',
                                                                               signed=True)
                self._headed[(self._guid, self._seq)] = future
                self._write(self._writer, encode(header, request, self.request_type), future)
            return future
        ser = bytes(msgs.serialize(request, self.request_type))
        with self._lock:
            self._bare.append((ser + b'\0' * (-len(ser) % 4), future))
            self._send_next_bare()
        return future

    def _write(self, writer: DataWriter, data: bytes, future: Future) -> None:
        ret = dds.write_serialized(writer._ref, data)
        if ret < 0:
            future.set_exception(RuntimeError(f'{self.service}: request not sent (DDS error '
                                              f'{ret})'))

    def _send_next_bare(self) -> None:
        """Fast DDS format: one request in flight (caller holds the lock)."""
        while self._bare_sent is None and self._bare and self._bare_writer is not None:
            data, future = self._bare.popleft()
            if future.done():  # cancelled while queued
                continue
            self._bare_sent = future
            self._write(self._bare_writer, data, future)
            if future.done():
                self._bare_sent = None

    def _on_reply(self) -> None:
        self.ready = True
        self._node.context.notify()

    def serve(self) -> None:
        """Complete the futures of the replies that arrived (executor thread)."""
        self.ready = False
        for reader, bare in ((self._reader, False), (self._bare_reader, True)):
            while reader is not None:
                taken = ddspy_take(reader._ref, dds.ANY_STATE, 64)
                if isinstance(taken, int) or not taken:
                    break
                for data, info in taken:
                    if info.valid_data:
                        self._reply(bytes(data), bare)

    def _reply(self, data: bytes, bare: bool) -> None:
        with self._lock:
            if not bare:
                try:
                    header, response = decode(data, self.response_type)
                except Exception:  # noqa: BLE001
                    return  # not ours to read: no request of ours is waiting on it
                key = (int.from_bytes(header[:8], 'little'),
                       int.from_bytes(header[8:], 'little', signed=True))
                future = self._headed.pop(key, None)  # None: the reply to another client
                if future is None:
                    return
            elif self._bare_sent is not None:
                future, self._bare_sent = self._bare_sent, None
                try:
                    response = msgs.deserialize(data, self.response_type)
                except Exception as err:  # noqa: BLE001 - a reply we cannot read fails its request
                    future.set_exception(RuntimeError(f'{self.service}: unreadable reply: {err}'))
                    self._send_next_bare()
                    return
                self._send_next_bare()
            else:
                return  # a Fast DDS service's reply to another client
        if not future.done():
            future.set_result(response)

    def forget(self, future: Future) -> None:
        """Stop waiting for a request's reply (e.g. after a timeout)."""
        with self._lock:
            for key, pending in list(self._headed.items()):
                if pending is future:
                    del self._headed[key]
            if self._bare_sent is future:
                self._bare_sent = None
                self._send_next_bare()

    def destroy(self) -> None:
        if self in self._node.clients:
            self._node.clients.remove(self)
        for entity in (self._writer, self._reader, self._bare_writer, self._bare_reader):
            if entity is None:
                continue
            with contextlib.suppress(Exception):  # already gone
                entity._delete(entity._ref)


class AsyncParameterClient:
    """rclpy's AsyncParameterClient: each call returns a Future whose result is the service's
    response (e.g. GetParameters_Response with `values`)."""

    def __init__(self, node: Node, remote_node_name: str,
                 qos_profile: QoSProfile = qos_profile_services_default,
                 callback_group: Any = None) -> None:
        # callback_group: accepted (one executor thread runs every callback); the services' QoS
        # is rmw's for services (param_services.QOS): another profile is refused, not ignored
        if qos_profile != qos_profile_services_default:
            raise NotImplementedError(f'AsyncParameterClient(qos_profile={qos_profile!r}): the '
                                      'bundled runtime uses the services default QoS only')
        name = remote_node_name if remote_node_name.startswith('/') else \
            f'{node.get_namespace().rstrip("/")}/{remote_node_name}'
        self.remote_node_name = name
        self._clients = {verb: ServiceClient(node, f'{name}/{verb}', srv)
                         for verb, srv in SERVICES.items()}

    def services_are_ready(self) -> bool:
        return all(client.service_is_ready() for client in self._clients.values())

    def wait_for_services(self, timeout_sec: float | None = None) -> bool:
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        for client in self._clients.values():
            remaining = None if deadline is None else max(0.0, deadline - time.monotonic())
            if not client.wait_for_service(remaining):
                return False
        return True

    def _call(self, verb: str, callback: Callable[[Future], None] | None, **fields: Any) -> Future:
        client = self._clients[verb]
        future = client.call_async(msgs.get_message(client.request_type)(**fields))
        if callback is not None:
            future.add_done_callback(callback)
        return future

    def list_parameters(self, prefixes: Sequence[str] | None = None, depth: int | None = None,
                        callback: Callable[[Future], None] | None = None) -> Future:
        return self._call('list_parameters', callback, prefixes=list(prefixes or []),
                          depth=depth or 0)

    def get_parameters(self, names: Sequence[str],
                       callback: Callable[[Future], None] | None = None) -> Future:
        return self._call('get_parameters', callback, names=list(names))

    def get_parameter_types(self, names: Sequence[str],
                            callback: Callable[[Future], None] | None = None) -> Future:
        return self._call('get_parameter_types', callback, names=list(names))

    def describe_parameters(self, names: Sequence[str],
                            callback: Callable[[Future], None] | None = None) -> Future:
        return self._call('describe_parameters', callback, names=list(names))

    def set_parameters(self, parameters: Sequence[Parameter | Any],
                       callback: Callable[[Future], None] | None = None) -> Future:
        return self._call('set_parameters', callback, parameters=_to_msgs(parameters))

    def set_parameters_atomically(self, parameters: Sequence[Parameter | Any],
                                  callback: Callable[[Future], None] | None = None) -> Future:
        return self._call('set_parameters_atomically', callback, parameters=_to_msgs(parameters))

    def delete_parameters(self, names: Sequence[str],
                          callback: Callable[[Future], None] | None = None) -> Future:
        """As rclpy: setting a parameter to NOT_SET undeclares it (where the node allows it)."""
        return self.set_parameters([Parameter(name) for name in names], callback)

    def forget(self, future: Future) -> None:
        """Stop waiting for the reply to this future's request (after a timeout)."""
        for client in self._clients.values():
            client.forget(future)

    def destroy(self) -> None:
        for client in self._clients.values():
            client.destroy()


def _to_msgs(parameters: Sequence[Parameter | Any]) -> list[Any]:
    return [p.to_parameter_msg() if isinstance(p, Parameter) else p for p in parameters]
