"""ROS 2 graph information on `ros_discovery_info`, as rmw_cyclonedds_cpp (Jazzy) publishes and
reads it.

ROS 2 tools (`ros2 node list`, `ros2 node info`, rqt_graph, the ros2 daemon) do not learn which node
owns which DDS reader/writer from DDS discovery: every participant publishes one
rmw_dds_common/msg/ParticipantEntitiesInfo sample on a dedicated DDS topic, and every other
participant keeps the latest sample per participant GID (rmw_dds_common GraphCache). This module
does both for the bundled runtime, process-wide (one DDS participant per process, see
dds.participant()):

- it publishes this process's nodes, each with the GUIDs of its DDS readers and writers,
  republished whole whenever a node or one of its readers/writers is created or destroyed
  (hooks in node.py call node_created / node_changed / node_destroyed);
- it reads the other participants' samples, so node_names_and_namespaces() lists every node of the
  graph, real ROS 2 ones included.

Wire facts, from upstream sources:
- rmw_cyclonedds_cpp src/rmw_node.cpp, rmw_context_impl_s::init(): topic "ros_discovery_info"
  created with avoid_ros_namespace_conventions (so no "rt" prefix); publisher QoS reliable,
  transient local, keep last 1; subscription the same but keep all, ignore_local_publications.
  The participant's USER_DATA is "enclave=<enclave>;" (handle_DCPSParticipant only adds a
  participant to its graph cache when that key is present).
- rmw_cyclonedds_cpp create_readwrite_qos(): writer_data_lifecycle autodispose off; transient local
  sets durability_service(0, history kind/depth, unlimited ...); automatic liveliness with an
  infinite lease; USER_DATA "typehash=RIHS01_...;" on every endpoint (Iron and later).
- rmw_cyclonedds_cpp convert_guid_to_gid(): the GID is the 16-byte dds_guid_t; rmw_dds_common
  convert_gid_to_msg() copies RMW_GID_STORAGE_SIZE (16 in Jazzy) bytes into Gid.data (char[16]).
- rmw_dds_common GraphCache::add_node / associate_reader / associate_writer: nodes, then readers
  and writers, in creation order; update_participant_entities() replaces a participant's whole
  entry.
The one deliberate difference: the writer's reliability max_blocking_time is 100 ms like every other
writer of this runtime (rmw uses infinity); it plays no part in matching.
"""

from __future__ import annotations

import atexit
import contextlib
import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from cyclonedds._clayer import ddspy_take
from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsParticipant
from cyclonedds.core import DDSException, InstanceState, Listener
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from .. import dds, msgs

if TYPE_CHECKING:
    from .node import Node

TOPIC_NAME = 'ros_discovery_info'
TYPENAME = 'rmw_dds_common/msg/ParticipantEntitiesInfo'
ENCLAVE_USER_DATA = dds.ENCLAVE_USER_DATA
_MAX_BLOCKING_NS = 100_000_000
_INFINITE_NS = 2**63 - 1


class NodeName(NamedTuple):
    """A node of the graph: namespace first, as the fully qualified name reads."""

    namespace: str
    name: str

    @property
    def fqn(self) -> str:
        return f'{self.namespace.rstrip("/")}/{self.name}'


@dataclass(frozen=True)
class NodeInfo:
    """One node as a ros_discovery_info sample announces it."""

    namespace: str
    name: str
    participant_gid: bytes
    reader_gids: tuple[bytes, ...]
    writer_gids: tuple[bytes, ...]
    local: bool  # a node of this process


def writer_qos() -> Qos:
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=_MAX_BLOCKING_NS),
        Policy.Durability.TransientLocal,
        Policy.DurabilityService(cleanup_delay=0, history=Policy.History.KeepLast(1),
                                 max_samples=-1,
                                 max_instances=-1, max_samples_per_instance=-1),
        Policy.History.KeepLast(1),
        Policy.Liveliness.Automatic(lease_duration=_INFINITE_NS),
        Policy.WriterDataLifecycle(autodispose=False),
        Policy.DataRepresentation(use_cdrv0_representation=True),
        Policy.Userdata(dds.type_hash_user_data(TYPENAME)),
    )


def reader_qos() -> Qos:
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=_MAX_BLOCKING_NS),
        Policy.Durability.TransientLocal,
        Policy.History.KeepAll,
        Policy.Liveliness.Automatic(lease_duration=_INFINITE_NS),
        Policy.IgnoreLocal.Participant,
        Policy.DataRepresentation(use_cdrv0_representation=True),
        Policy.Userdata(dds.type_hash_user_data(TYPENAME)),
    )


def build_message(participant_gid: bytes,
                  nodes: list[tuple[str, str, list[bytes], list[bytes]]]) -> Any:
    """A ParticipantEntitiesInfo from (namespace, name, reader GUIDs, writer GUIDs) per node."""
    gid_cls = msgs.get_message('rmw_dds_common/msg/Gid')
    node_cls = msgs.get_message('rmw_dds_common/msg/NodeEntitiesInfo')

    def gid(raw: bytes) -> Any:
        if len(raw) != 16:
            raise ValueError(f'a DDS GUID has 16 bytes, got {len(raw)}')
        return gid_cls(data=np.frombuffer(raw, dtype=np.uint8).copy())

    return msgs.get_message(TYPENAME)(
        gid=gid(participant_gid),
        node_entities_info_seq=[
            node_cls(node_namespace=ns, node_name=name, reader_gid_seq=[gid(g) for g in readers],
                     writer_gid_seq=[gid(g) for g in writers])
            for ns, name, readers, writers in nodes])


def parse_message(
        raw: bytes | memoryview) -> tuple[bytes, list[tuple[str, str, list[bytes], list[bytes]]]]:
    """(participant GID, [(namespace, name, reader GUIDs, writer GUIDs)]) from a sample's CDR
    bytes."""
    msg = msgs.deserialize(raw, TYPENAME)
    return bytes(msg.gid.data), [
        (n.node_namespace, n.node_name, [bytes(g.data) for g in n.reader_gid_seq],
         [bytes(g.data) for g in n.writer_gid_seq])
        for n in msg.node_entities_info_seq]


class _Graph:
    """The process's ros_discovery_info writer and reader, and what they know."""

    def __init__(self) -> None:
        dp = dds.participant()
        self._gid = dp.guid.bytes
        self._lock = threading.RLock()   # local nodes and the writer: update and publish atomically
        self._cache_lock = threading.Lock()  # what the reader learnt
        self._nodes: list[Node] = []
        self._extra: dict[Node, tuple[list[bytes], list[bytes]]] = {}  # services' readers/writers
        self._topic = Topic(dp, TOPIC_NAME, dds.idl_type(TYPENAME))
        self._writer: DataWriter | None = None
        self._remote: dict[bytes, list[tuple[str, str, list[bytes], list[bytes]]]] = {}
        self._alive: set[bytes] = set()
        self._gone: set[bytes] = set()
        self.listening_since = time.monotonic()
        self._participants = BuiltinDataReader(dp, BuiltinTopicDcpsParticipant)
        self._reader = DataReader(dp, self._topic, reader_qos())
        # the listener keeps the keep-all reader drained; attached once refresh() can run
        self._reader.set_listener(Listener(on_data_available=lambda _r: self.refresh()))

    # --- publishing ------------------------------------------------------------------------
    def _entities(self, node: Node) -> tuple[str, str, list[bytes], list[bytes]]:
        readers, writers = self._extra.get(node, ([], []))
        return (node.get_namespace(), node.get_name(),
                [s.guid for s in list(node.subscriptions)] + readers,
                [p.guid for p in list(node.publishers)] + writers)

    def local_nodes(self) -> list[tuple[str, str, list[bytes], list[bytes]]]:
        with self._lock:
            return [self._entities(node) for node in self._nodes]

    def publish(self) -> None:
        with self._lock:
            if self._writer is None:
                self._writer = DataWriter(dds.participant(), self._topic, writer_qos())
            data = bytes(msgs.serialize(build_message(self._gid, self.local_nodes()), TYPENAME))
            ret = dds.write_serialized(self._writer._ref, data)
            if ret < 0:
                raise DDSException(ret, f'writing {TOPIC_NAME}')

    def add(self, node: Node) -> None:
        with self._lock:
            if node not in self._nodes:
                self._nodes.append(node)
            self.publish()

    def changed(self, node: Node) -> None:
        with self._lock:
            if node in self._nodes:
                self.publish()

    def set_extra(self, node: Node, readers: list[bytes], writers: list[bytes]) -> None:
        with self._lock:
            self._extra[node] = (list(readers), list(writers))
            if node in self._nodes:
                self.publish()

    def remove(self, node: Node) -> None:
        with self._lock:
            self._extra.pop(node, None)
            if node in self._nodes:
                self._nodes.remove(node)
                self.publish()

    # --- reading ---------------------------------------------------------------------------
    def refresh(self) -> None:
        """Take what the reader and the participant builtin topic received (listener thread or
        caller).

        Samples first, participants second: a participant's sample always arrives before its
        disposal, so taking in this order never keeps a gone participant's last sample alive."""
        with self._cache_lock:
            while True:
                taken = ddspy_take(self._reader._ref, dds.ANY_STATE, 256)
                if isinstance(taken, int) or not taken:
                    break  # an error code here means the reader is being deleted: nothing to take
                for raw, info in taken:
                    if not info.valid_data:
                        continue
                    try:
                        gid, nodes = parse_message(raw)
                    except Exception:  # noqa: BLE001 - a malformed sample from a peer is ignored
                        continue
                    self._remote[gid] = nodes
            while samples := self._participants.take(N=256):
                for sample in samples:
                    key = sample.key.bytes
                    if sample.sample_info.instance_state == InstanceState.Alive:
                        self._alive.add(key)
                        self._gone.discard(key)
                    else:
                        self._alive.discard(key)
                        self._gone.add(key)
            for key in self._gone & self._remote.keys():
                del self._remote[key]

    def close(self) -> None:
        """Delete the reader at interpreter exit, so its listener never calls into a finalizing
        Python."""
        with contextlib.suppress(Exception):  # already gone with the participant
            self._reader._delete(self._reader._ref)

    def snapshot(self) -> list[NodeInfo]:
        self.refresh()
        out = [NodeInfo(ns, name, self._gid, tuple(r), tuple(w), True)
               for ns, name, r, w in self.local_nodes()]
        with self._cache_lock:
            for gid, nodes in self._remote.items():
                if gid in self._alive:
                    out.extend(NodeInfo(ns, name, gid, tuple(r), tuple(w), False)
                               for ns, name, r, w in nodes)
        return out


_graph: _Graph | None = None
_graph_lock = threading.Lock()


def _get() -> _Graph:
    global _graph
    with _graph_lock:
        if _graph is None:
            _graph = _Graph()
            atexit.register(_graph.close)
        return _graph


# --- hooks (node.py) ------------------------------------------------------------------------

def node_created(node: Node) -> None:
    """A node came to life: announce it (with whatever readers/writers it already has)."""
    _get().add(node)


def node_changed(node: Node) -> None:
    """One of a node's readers/writers was created or destroyed: republish. A node being destroyed
    publishes once, when it is gone (node_destroyed), not once per entity."""
    if _graph is not None and not getattr(node, '_destroyed', False):
        _graph.changed(node)


def node_destroyed(node: Node) -> None:
    if _graph is not None:
        _graph.remove(node)


def set_extra_endpoints(node: Node, readers: list[bytes], writers: list[bytes]) -> None:
    """DDS readers/writers of a node besides its subscriptions/publishers (its services'), announced
    with it until it is destroyed."""
    _get().set_extra(node, readers, writers)


# --- queries (CLI) --------------------------------------------------------------------------

def snapshot(timeout_sec: float = 0.0) -> list[NodeInfo]:
    """Every node of the graph with its participant and reader/writer GUIDs: this process's nodes
    and those announced on ros_discovery_info by other live participants (this runtime or real ROS
    2). See node_names_and_namespaces() for timeout_sec."""
    graph = _get()
    remaining = timeout_sec - (time.monotonic() - graph.listening_since)
    if remaining > 0:
        time.sleep(remaining)
    return graph.snapshot()


def announced_participants() -> set[bytes]:
    """GIDs of the live participants whose ros_discovery_info sample this process has received
    (nodes or not): with the DDS participants seen, what tells a CLI it has heard everyone."""
    graph = _get()
    graph.refresh()
    with graph._cache_lock:
        return set(graph._remote) & graph._alive


def node_names_and_namespaces(timeout_sec: float = 0.0) -> list[NodeName]:
    """Every node of the graph as NodeName(namespace, name), sorted and without duplicates.

    NOTE the order is (namespace, name), unlike rclpy's Node.get_node_names_and_namespaces()
    which gives (name, namespace); the fields are named, use .namespace / .name / .fqn.

    Discovery is asynchronous: a process only knows what reached it since it started listening
    (its first node, or its first call here). timeout_sec is a discovery window: the answer waits
    until the process has listened for at least that long, so a short-lived CLI passes e.g. 1.0
    while a long-running node, already listening for longer, gets its answer at once."""
    return sorted({NodeName(n.namespace, n.name) for n in snapshot(timeout_sec)})


__all__ = ['ENCLAVE_USER_DATA', 'NodeInfo', 'NodeName', 'TOPIC_NAME', 'TYPENAME',
           'announced_participants', 'build_message', 'node_changed', 'node_created',
           'node_destroyed', 'node_names_and_namespaces',
           'parse_message', 'reader_qos', 'set_extra_endpoints', 'snapshot', 'writer_qos']
