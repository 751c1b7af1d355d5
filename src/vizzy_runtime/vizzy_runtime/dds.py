"""Cyclone DDS transport for the bundled runtime, speaking exactly what ROS 2's rmw_cyclonedds_cpp
speaks.

- topic `rt/<fully qualified name>`, type `pkg::msg::dds_::T_` (final struct, real fields, so the
  XTypes type information Cyclone attaches is the message's own);
- payload: XCDR1 little endian with the encapsulation header, written and taken as raw bytes
  (rosbags' numpy-aware codec does the (de)serialization, not Cyclone's per-element Python one);
- QoS mapped one to one; DataRepresentation forced to XCDR1 (XCDR2 samples never reach ROS 2).

Loopback only unless VIZZY_DDS_LAN=1: see loopback_config().
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes as ct
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cyclonedds.idl.types as idl
from cyclonedds._clayer import ddspy_take
from cyclonedds.core import (
    DDSException,
    InstanceState,
    Listener,
    SampleState,
    ViewState,
    _data_available_fn,
)
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.idl import IdlStruct, make_idl_struct
from cyclonedds.idl.annotations import final
from cyclonedds.internal import DDS, dds_c_t, load_cyclonedds
from cyclonedds.pub import DataWriter, Publisher
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader, Subscriber
from cyclonedds.topic import Topic
from rosbags.interfaces import Nodetype

from . import msgs
from .loopback import bind_cyclone_to_loopback, lan_mode

ANY_STATE = SampleState.Any | ViewState.Any | InstanceState.Any
MAX_AUTO_PARTICIPANTS = 60
# participant USER_DATA as rmw_cyclonedds_cpp sets it (the default enclave)
ENCLAVE_USER_DATA = b'enclave=/;'


def loopback_config() -> str:
    """Cyclone configuration that keeps every packet on 127.0.0.1: loopback interface, no multicast,
    unicast discovery to the local participant ports only."""
    return (
        '<CycloneDDS><Domain id="any"><General>'
        '<Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>'
        '<AllowMulticast>false</AllowMulticast>'
        # loopback's MTU is 64 KiB: a VGA image in 15 datagrams instead of 63 Ethernet-sized ones
        '<MaxMessageSize>65500B</MaxMessageSize>'
        '</General>'
        '<Internal><SocketReceiveBufferSize min="default" max="8MiB"/>'
        # a node with many reliable writers must not take seconds to exit while its peers go too
        '<WriterLingerDuration>200ms</WriterLingerDuration></Internal>'
        '<Discovery>'
        '<ParticipantIndex>auto</ParticipantIndex>'
        f'<MaxAutoParticipantIndex>{MAX_AUTO_PARTICIPANTS}</MaxAutoParticipantIndex>'
        '<Peers><Peer address="127.0.0.1"/></Peers>'
        '</Discovery></Domain></CycloneDDS>'
    )


def domain_id() -> int:
    raw = os.environ.get('ROS_DOMAIN_ID', '0') or '0'
    try:
        value = int(raw)
    except ValueError:
        raise ValueError(f'ROS_DOMAIN_ID={raw!r} is not an integer') from None
    if not 0 <= value <= 232:
        raise ValueError(f'ROS_DOMAIN_ID={value} is outside 0..232')
    return value


_lock = threading.RLock()
_participant: DomainParticipant | None = None
_domain: Domain | None = None
_closed = False


class DdsClosedError(RuntimeError):
    """The process is exiting: its DDS participant is gone and no new one is made."""


def participant() -> DomainParticipant:
    """The process's one DDS participant (rmw_cyclonedds_cpp also uses one per context)."""
    global _participant, _domain
    with _lock:
        if _participant is None:
            if _closed:
                raise DdsClosedError('DDS is shut down: the process is exiting')
            did = domain_id()
            bind_cyclone_to_loopback()   # a library user's process was not preloaded
            if not lan_mode():
                _domain = Domain(did, loopback_config())
            _participant = DomainParticipant(did, qos=Qos(Policy.Userdata(ENCLAVE_USER_DATA)))
        return _participant


def _delete_participant_at_exit() -> None:
    """Delete the participant (and with it every reader, writer and listener), then the domain,
    before the interpreter tears itself down, and make no new ones after: a listener called from
    a Cyclone thread into a finalizing interpreter crashes the process (seen as a rare SIGSEGV at
    node exit), and an entity deleted in finalization can wait for ever on such a thread
    (process_exit.py). A daemon thread that publishes later gets DdsClosedError instead."""
    global _participant, _domain, _closed
    with _lock:
        _closed = True
        for entity in (_participant, _domain):
            if entity is not None:
                with contextlib.suppress(Exception):  # already gone
                    entity._delete(entity._ref)
        _participant = _domain = None


atexit.register(_delete_participant_at_exit)


# --- types -------------------------------------------------------------------------------------

_PRIM: dict[str, Any] = {
    'bool': bool, 'byte': idl.byte, 'char': idl.uint8, 'int8': idl.int8, 'uint8': idl.uint8,
    'int16': idl.int16, 'uint16': idl.uint16, 'int32': idl.int32, 'uint32': idl.uint32,
    'int64': idl.int64, 'uint64': idl.uint64, 'float32': idl.float32, 'float64': idl.float64,
}
_idl_cache: dict[str, type[IdlStruct]] = {}


def idl_type(typename: str) -> type[IdlStruct]:
    """A final IdlStruct named like ROS 2's DDS type, with the message's real fields."""
    typename = msgs.normalize_type_name(typename)
    with _lock:
        cls = _idl_cache.get(typename)
        if cls is None:
            reg = msgs.registry()
            fields = {name: _idl_field(desc) for name, desc in reg.fields(typename)}
            dds_name = msgs.dds_type_name(typename)
            cls = make_idl_struct(dds_name.replace('::', '_'), dds_name, fields)
            final(cls)
            _idl_cache[typename] = cls
        return cls


def _idl_field(desc: Any) -> Any:
    kind, rest = desc
    if kind == Nodetype.BASE:
        name, bound = rest
        if name in ('string', 'bounded_string'):
            # cyclonedds's idl types are generic through their metaclass, unseen by mypy
            return idl.bounded_str[bound] if bound else str  # type: ignore[misc]
        return _PRIM[name]
    if kind == Nodetype.NAME:
        return idl_type(rest)
    sub, length = rest
    if kind == Nodetype.ARRAY:
        return idl.array[_idl_field(sub), length]  # type: ignore[misc]
    if length:  # cyclonedds's idl types are generic through their metaclass, unseen by mypy
        return idl.sequence[_idl_field(sub), length]  # type: ignore[misc]
    return idl.sequence[_idl_field(sub)]  # type: ignore[misc]


# --- QoS ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class QoS:
    """The QoS subset ROS 2 maps one to one onto DDS (rmw_cyclonedds_cpp's mapping)."""

    reliable: bool = True
    transient_local: bool = False
    keep_all: bool = False
    depth: int = 10
    deadline_ns: int | None = None
    lifespan_ns: int | None = None
    liveliness_manual: bool = False
    liveliness_lease_ns: int | None = None

    def to_dds(self, user_data: bytes | None = None) -> Qos:
        policies: list[Any] = [
            Policy.Reliability.Reliable(max_blocking_time=100_000_000) if self.reliable
            else Policy.Reliability.BestEffort,
            Policy.Durability.TransientLocal if self.transient_local
            else Policy.Durability.Volatile,
            Policy.History.KeepAll if self.keep_all
            else Policy.History.KeepLast(max(1, self.depth)),
            Policy.DataRepresentation(use_cdrv0_representation=True),
        ]
        if self.deadline_ns:
            policies.append(Policy.Deadline(self.deadline_ns))
        if self.lifespan_ns:
            policies.append(Policy.Lifespan(self.lifespan_ns))
        if self.liveliness_lease_ns or self.liveliness_manual:
            lease = self.liveliness_lease_ns or 2**63 - 1
            policies.append(Policy.Liveliness.ManualByTopic(lease) if self.liveliness_manual
                            else Policy.Liveliness.Automatic(lease))
        if user_data:
            policies.append(Policy.Userdata(user_data))
        return Qos(*policies)

    @staticmethod
    def from_dds(qos: Qos) -> QoS:
        """The ROS-relevant part of a discovered endpoint's QoS (bag recording, topic info)."""
        reliable = transient_local = keep_all = False
        depth = 1
        for policy in qos:
            if isinstance(policy, Policy.Reliability.Reliable):
                reliable = True
            elif policy == Policy.Durability.TransientLocal:
                transient_local = True
            elif isinstance(policy, Policy.History.KeepLast):
                depth = policy.depth
            elif policy == Policy.History.KeepAll:
                keep_all = True
        return QoS(reliable=reliable, transient_local=transient_local, keep_all=keep_all,
                   depth=depth)


def type_hash_user_data(typename: str) -> bytes:
    """USER_DATA that rmw_cyclonedds_cpp (Jazzy) puts on every endpoint: `typehash=RIHS01_…;`."""
    try:
        typehash = msgs.registry().store.hash_rihs01(msgs.normalize_type_name(typename))
        return f'typehash={typehash};'.encode()
    except Exception:  # noqa: BLE001 - a hash is informative only, never a reason to fail
        return b''


# --- matched status (not wrapped by the Python binding) ------------------------------------------

def _status_fn(name: str, struct: type) -> Any:
    fn = getattr(DDS._dll_handle, name)
    fn.restype = dds_c_t.returnv
    fn.argtypes = [dds_c_t.entity, ct.POINTER(struct)]
    return fn


_pub_matched = _status_fn('dds_get_publication_matched_status', dds_c_t.publication_matched_status)
_sub_matched = _status_fn('dds_get_subscription_matched_status',
                          dds_c_t.subscription_matched_status)


def _matched(fn: Any, struct: type, ref: int) -> int:
    status = struct()
    ret = fn(ref, ct.byref(status))
    if ret < 0:
        raise DDSException(ret, fn.__name__)
    return int(status.current_count)




# --- endpoints ---------------------------------------------------------------------------------

_topics: dict[tuple[str, str], Topic] = {}


def dds_topic_name(ros_topic: str) -> str:
    if not ros_topic.startswith('/'):
        raise ValueError(f'topic {ros_topic!r} is not fully qualified')
    return 'rt' + ros_topic


def ros_topic_name(dds_topic: str) -> str | None:
    return dds_topic[2:] if dds_topic.startswith('rt/') else None


def _topic(ros_topic: str, typename: str) -> Topic:
    key = (ros_topic, typename)
    with _lock:
        topic = _topics.get(key)
        if topic is None:
            topic = Topic(participant(), dds_topic_name(ros_topic), idl_type(typename))
            _topics[key] = topic
        return topic


class _SampleContainer(ct.Structure):
    """What cyclonedds-python's serdata type reads a sample from (ddspy_sample_container_t)."""
    _fields_ = [('usample', ct.c_void_p), ('usample_size', ct.c_size_t)]


_libddsc = load_cyclonedds()
_dds_write = _libddsc.dds_write
_dds_write.argtypes = [ct.c_int32, ct.c_void_p]
_dds_write.restype = ct.c_int32
_dds_write_ts = _libddsc.dds_write_ts
_dds_write_ts.argtypes = [ct.c_int32, ct.c_void_p, ct.c_int64]
_dds_write_ts.restype = ct.c_int32


def write_serialized(writer_ref: int, data: bytes, timestamp_ns: int | None = None) -> int:
    """dds_write of serialized bytes with the GIL released.

    cyclonedds-python's ddspy_write keeps the GIL inside dds_write. When the topic has a reader in
    this process, local delivery waits for that reader's listener, which a Cyclone thread runs as a
    Python callback that needs the GIL: a deadlock. A ctypes call releases the GIL for its duration.
    """
    buf = ct.c_char_p(data)  # points into `data` itself (no copy); kept alive by this frame
    container = _SampleContainer(ct.cast(buf, ct.c_void_p), len(data))
    if timestamp_ns is None:
        return int(_dds_write(writer_ref, ct.byref(container)))
    return int(_dds_write_ts(writer_ref, ct.byref(container), timestamp_ns))


class RawWriter:
    """A DDS writer for a ROS topic that sends already serialized CDR bytes."""

    def __init__(self, ros_topic: str, typename: str, qos: QoS) -> None:
        self.topic_name = ros_topic
        self.typename = msgs.normalize_type_name(typename)
        self.qos = qos
        self._writer = DataWriter(participant(), _topic(ros_topic, self.typename),
                                  qos.to_dds(type_hash_user_data(self.typename)))

    @property
    def guid(self) -> bytes:
        return self._writer.guid.bytes

    def write(self, payload: bytes | bytearray | memoryview,
              timestamp_ns: int | None = None) -> None:
        data = payload if isinstance(payload, bytes) else bytes(payload)
        if len(data) % 4:
            data += b'\0' * (4 - len(data) % 4)
        ret = write_serialized(self._writer._ref, data, timestamp_ns)
        if ret < 0:
            raise DDSException(ret, f'writing to {self.topic_name}')

    def matched_count(self) -> int:
        return _matched(_pub_matched, dds_c_t.publication_matched_status, self._writer._ref)

class RawReader:
    """A DDS reader for a ROS topic handing out raw CDR bytes and their source timestamps."""

    def __init__(self, ros_topic: str, typename: str, qos: QoS,
                 on_data: Callable[[RawReader], None] | None = None) -> None:
        self.topic_name = ros_topic
        self.typename = msgs.normalize_type_name(typename)
        self.qos = qos
        self._on_data = on_data
        self._early = False  # data (e.g. latched samples) may arrive before DataReader() returns
        listener: Listener | None = None
        if on_data:
            # the C callback calls _data_available itself: cyclonedds' own wrapper looks the
            # reader up in a weak dictionary for every sample first (a node's /clock: 100 a second)
            listener = Listener()
            on_sample = lambda _entity, _arg: self._data_available()  # noqa: E731
            self._listener_fn = _data_available_fn(on_sample)  # type: ignore[misc]
            listener._set_data_available(listener._ref, self._listener_fn)
            listener._on_data_available = self._listener_fn   # the reader keeps its listener
        self._reader = DataReader(participant(), _topic(ros_topic, self.typename),
                                  qos.to_dds(type_hash_user_data(self.typename)), listener=listener)
        if self._early and on_data:
            on_data(self)

    def _data_available(self) -> None:
        if not hasattr(self, '_reader'):
            self._early = True
        elif self._on_data is not None:
            self._on_data(self)

    @property
    def entity(self) -> DataReader:
        return self._reader

    @property
    def guid(self) -> bytes:
        return self._reader.guid.bytes

    def take(self, n: int = 64) -> list[tuple[bytes, int]]:
        """Up to n samples as (cdr bytes, source timestamp ns); invalid (dispose) samples
        skipped."""
        ret = ddspy_take(self._reader._ref, ANY_STATE, n)
        if isinstance(ret, int):
            raise DDSException(ret, f'taking from {self.topic_name}')
        return [(data, info.source_timestamp) for data, info in ret if info.valid_data]

    def matched_count(self) -> int:
        return _matched(_sub_matched, dds_c_t.subscription_matched_status, self._reader._ref)


# --- waiting in the executor's thread ---------------------------------------------------------

def _c_fn(name: str, restype: Any, *argtypes: Any) -> Any:
    fn = getattr(_libddsc, name)
    fn.argtypes, fn.restype = list(argtypes), restype
    return fn


# ctypes calls (the GIL is released while Cyclone blocks in dds_waitset_wait)
_create_waitset = _c_fn('dds_create_waitset', ct.c_int32, ct.c_int32)
_waitset_attach = _c_fn('dds_waitset_attach', ct.c_int32, ct.c_int32, ct.c_int32, ct.c_ssize_t)
_waitset_wait = _c_fn('dds_waitset_wait', ct.c_int32, ct.c_int32, ct.POINTER(ct.c_ssize_t),
                      ct.c_size_t, ct.c_int64)
_create_readcondition = _c_fn('dds_create_readcondition', ct.c_int32, ct.c_int32, ct.c_uint32)
_create_guardcondition = _c_fn('dds_create_guardcondition', ct.c_int32, ct.c_int32)
_set_guardcondition = _c_fn('dds_set_guardcondition', ct.c_int32, ct.c_int32, ct.c_bool)
_dds_delete = _c_fn('dds_delete', ct.c_int32, ct.c_int32)
_NEVER_NS = 2**63 - 1        # DDS_INFINITY


class WaitSet:
    """A Cyclone waitset on readers' data and a guard condition, for an executor's thread.

    The executor blocks in wait() (GIL released) until a watched reader holds samples, wake() is
    called (any thread) or the timeout passes. A reader watched this way needs no Python
    listener: a Python callback from Cyclone's receive thread for every sample, then a
    threading wake-up of the executor, cost each received message ~0.075 ms of CPU more
    (issue 27; bench/runtime_messages.py)."""

    def __init__(self) -> None:
        dp = participant()
        self._ref = self._check(_create_waitset(dp._ref), 'creating a waitset')
        self._guard = self._check(_create_guardcondition(dp._ref), 'creating a guard condition')
        self._check(_waitset_attach(self._ref, self._guard, 0), 'attaching a guard condition')
        self._conditions: dict[int, int] = {}     # key (> 0) -> read condition
        self._xs = (ct.c_ssize_t * 8)()

    @staticmethod
    def _check(ret: int, what: str) -> int:
        if ret < 0:
            raise DDSException(ret, what)
        return ret

    def watch(self, key: int, reader: RawReader) -> None:
        """Wake wait() while reader holds samples (read or not); wait() then returns key."""
        if key <= 0 or key in self._conditions:
            raise ValueError(f'waitset key {key} is not positive or already watched')
        cond = self._check(_create_readcondition(reader.entity._ref, ANY_STATE),
                           f'watching {reader.topic_name}')
        self._conditions[key] = cond
        if _waitset_attach(self._ref, cond, key) < 0:
            self.unwatch(key)
            raise DDSException(-1, f'attaching {reader.topic_name} to a waitset')
        if len(self._xs) <= len(self._conditions):
            self._xs = (ct.c_ssize_t * (2 * len(self._conditions) + 1))()

    def unwatch(self, key: int) -> None:
        cond = self._conditions.pop(key, None)
        if cond is not None:
            _dds_delete(cond)       # detaches it (an error: gone with its reader already)

    def watched(self) -> set[int]:
        return set(self._conditions)

    def wake(self) -> None:
        """Make the current or next wait() return (any thread)."""
        _set_guardcondition(self._guard, True)

    def wait(self, timeout_s: float | None) -> list[int]:
        """Block up to timeout_s (None: for ever) until a watched reader has data or wake() was
        called; the keys of the readers holding data (wake() is cleared)."""
        timeout = _NEVER_NS if timeout_s is None else max(0, int(timeout_s * 1e9))
        xs = self._xs
        n = self._check(_waitset_wait(self._ref, xs, len(xs), timeout), 'waiting')
        if n == 0:
            return []
        _set_guardcondition(self._guard, False)
        return [key for key in xs[:min(n, len(xs))] if key > 0]

    def close(self) -> None:
        """Delete the waitset and its conditions (the readers stay)."""
        for key in list(self._conditions):
            self.unwatch(key)
        _dds_delete(self._guard)
        _dds_delete(self._ref)

    def __del__(self) -> None:
        with contextlib.suppress(Exception):   # at exit: DDS (or this module) may be gone
            self.close()


@dataclass(frozen=True)
class Endpoint:
    """A discovered DDS endpoint carrying a ROS topic (or, from Discovery.service_endpoints(), a
    service's request or reply topic: topic is then the service name, typename the service type
    pkg/srv/Name)."""

    topic: str
    typename: str
    qos: QoS
    guid: bytes
    participant_guid: bytes
    is_writer: bool
    dds_qos: Any = None       # the full discovered QoS (cyclonedds Qos): `vizzy topic info -v`
    type_hash: str = ''       # RIHS01_... from the endpoint's USER_DATA, '' if it has none
    is_request: bool = False  # service endpoints: the request topic (rq...Request)


def service_of(dds_topic: str, dds_type: str) -> tuple[str, str, bool] | None:
    """(service name, pkg/srv/Name, is_request) of a service's DDS topic as rmw_cyclonedds_cpp
    and rmw_fastrtps_cpp name them (`rq/<name>Request` + `pkg::srv::dds_::Name_Request_`,
    `rr/<name>Reply` + `..._Response_`); None for anything else."""
    for prefix, suffix, half in (('rq/', 'Request', '_Request_'), ('rr/', 'Reply', '_Response_')):
        if dds_topic.startswith(prefix) and dds_topic.endswith(suffix) and dds_type.endswith(half):
            parts = dds_type[:-len(half)].split('::')
            if len(parts) == 4 and parts[1] == 'srv' and parts[2] == 'dds_':
                name = dds_topic[2:-len(suffix)]
                return name, f'{parts[0]}/srv/{parts[3]}', prefix == 'rq/'
    return None


def _type_hash(qos: Any) -> str:
    for policy in qos or ():
        if isinstance(policy, Policy.Userdata):
            for item in bytes(policy.data).decode(errors='replace').split(';'):
                key, _, value = item.partition('=')
                if key == 'typehash':
                    return value
    return ''


class Discovery:
    """Keeps the ROS topics seen on the DDS builtin publication/subscription topics."""

    def __init__(self) -> None:
        from cyclonedds.builtin import (
            BuiltinDataReader,
            BuiltinTopicDcpsPublication,
            BuiltinTopicDcpsSubscription,
        )
        dp = participant()
        self._readers = [(BuiltinDataReader(dp, BuiltinTopicDcpsPublication), True),
                         (BuiltinDataReader(dp, BuiltinTopicDcpsSubscription), False)]
        self._endpoints: dict[bytes, Endpoint] = {}
        self._services: dict[bytes, Endpoint] = {}

    def service_endpoints(self) -> list[Endpoint]:
        """The services' request/reply readers and writers seen (Endpoint.topic: the service
        name, .typename: pkg/srv/Name). A server has a request reader, a client a request
        writer."""
        self.endpoints()
        return list(self._services.values())

    def endpoints(self) -> list[Endpoint]:
        for reader, is_writer in self._readers:
            try:
                samples = reader.take(N=1000)
            except Exception:  # noqa: BLE001 - cyclonedds' endpoint decoding can fail on a peer
                continue       # being torn down; the next call sees the graph again
            for sample in samples:
                info = getattr(sample, 'sample_info', None)
                alive = info is None or info.instance_state == InstanceState.Alive
                key = sample.key.bytes
                ros_topic = ros_topic_name(sample.topic_name or '')
                typename = msgs.ros_type_from_dds(sample.type_name or '')
                if not alive:
                    self._endpoints.pop(key, None)
                    self._services.pop(key, None)
                elif ros_topic and typename:
                    self._endpoints[key] = Endpoint(ros_topic, typename, QoS.from_dds(sample.qos),
                                                    key,
                                                    sample.participant_key.bytes, is_writer,
                                                    sample.qos, _type_hash(sample.qos))
                elif service := service_of(sample.topic_name or '', sample.type_name or ''):
                    self._services[key] = Endpoint(service[0], service[1],
                                                   QoS.from_dds(sample.qos), key,
                                                   sample.participant_key.bytes, is_writer,
                                                   sample.qos, _type_hash(sample.qos),
                                                   service[2])
        return list(self._endpoints.values())

    def topics(self) -> dict[str, str]:
        """ROS topic name -> type name, for every topic with a writer or a reader."""
        return {ep.topic: ep.typename for ep in self.endpoints()}


def delete(entity: RawReader | RawWriter) -> None:
    """Delete a reader or writer now (not at garbage collection), so peers see it go."""
    inner = getattr(entity, '_reader', None) or getattr(entity, '_writer', None)
    if inner is not None:
        with contextlib.suppress(Exception):  # already gone
            inner._delete(inner._ref)


__all__ = [
    'QoS', 'RawReader', 'RawWriter', 'WaitSet', 'delete', 'dds_topic_name', 'domain_id', 'idl_type',
    'lan_mode', 'loopback_config', 'participant', 'ros_topic_name', 'Publisher', 'Subscriber',
]
