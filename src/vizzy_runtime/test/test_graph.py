"""ros_discovery_info: what real ROS 2 tools read to know our nodes
(vizzy_runtime.rclpy_compat.graph).

Nodes here run without parameter services (test_param_services checks theirs are announced too).
Checked from the outside with plain Cyclone DDS (an observer participant with rmw_cyclonedds_cpp's
reader QoS): this process and a child process each publish one ParticipantEntitiesInfo whose GID is
their participant GUID and whose nodes list the GUIDs of their actual readers/writers.
"""

from __future__ import annotations

import json
import os
import queue
import random
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from vizzy_runtime import dds, msgs

if dds._participant is None:  # the process's participant does not exist yet: pick our own domain
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(100, 200)))

from cyclonedds._clayer import ddspy_take  # noqa: E402
from cyclonedds.builtin import (  # noqa: E402
    BuiltinDataReader,
    BuiltinTopicDcpsParticipant,
    BuiltinTopicDcpsPublication,
    BuiltinTopicDcpsSubscription,
)
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.qos import Policy, Qos  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402

from vizzy_runtime.rclpy_compat import graph  # noqa: E402
from vizzy_runtime.rclpy_compat.context import Context  # noqa: E402
from vizzy_runtime.rclpy_compat.node import Node  # noqa: E402
from vizzy_runtime.testing import scaled  # noqa: E402

PKG_ROOT = Path(__file__).resolve().parents[1]
T = graph.TYPENAME
TIMEOUT = scaled(15.0)


def wait_for(predicate: Callable[[], Any], what: str, timeout: float = TIMEOUT) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f'timed out waiting for {what}')
        time.sleep(0.02)


def wait_equal(get: Callable[[], Any], expected: Any, what: str) -> None:
    """Wait until get() == expected (samples before the last update may be seen first)."""
    last: list[Any] = []

    def check() -> bool:
        last[:] = [get()]
        return last[0] == expected

    try:
        wait_for(check, what)
    except AssertionError:
        assert last[0] == expected, what


CHILD = r'''
import json, sys
from vizzy_runtime import dds, msgs
from vizzy_runtime.rclpy_compat.context import Context
from vizzy_runtime.rclpy_compat.node import Node
suffix = sys.argv[1]
ctx = Context()
ctx.init(args=[])
S = msgs.get_message('std_msgs/msg/String')
talker = Node('talker_' + suffix, namespace='/graph_test', context=ctx,
              start_parameter_services=False)
pub = talker.create_publisher(S, 'chatter', 10)
listener = Node('listener_' + suffix, context=ctx, start_parameter_services=False)
sub = listener.create_subscription(S, '/graph_test/chatter', lambda m: None, 10)
print(json.dumps({'participant': dds.participant().guid.bytes.hex(),
                  'talker_writer': pub.guid.hex(),
                  'listener_reader': sub.guid.hex(),
                  'talker_events': talker._parameter_event_publisher.guid.hex(),
                  'listener_events': listener._parameter_event_publisher.guid.hex(),
                  'talker_rosout': talker._rosout_publisher.guid.hex(),
                  'listener_rosout': listener._rosout_publisher.guid.hex()}), flush=True)
for line in sys.stdin:
    if line.strip() == 'destroy talker':
        talker.destroy_node()
        print(json.dumps({'destroyed': 'talker'}), flush=True)
ctx.shutdown()
'''


class Child:
    """A second process with two nodes, driven line by line over stdin/stdout."""

    def __init__(self, suffix: str) -> None:
        env = dict(os.environ, ROS_DOMAIN_ID=os.environ['ROS_DOMAIN_ID'], PYTHONFAULTHANDLER='1',
                   PYTHONPATH=os.pathsep.join([str(PKG_ROOT), os.environ.get('PYTHONPATH', '')]))
        self.proc = subprocess.Popen([sys.executable, '-c', CHILD, suffix], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True, env=env)
        self._lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self._lines.put(line)

    def read(self) -> dict[str, Any]:
        try:
            return json.loads(self._lines.get(timeout=TIMEOUT))
        except queue.Empty:
            raise AssertionError(f'child said nothing within {TIMEOUT} s (exit code '
                                 f'{self.proc.poll()})') from None

    def send(self, line: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(line + '\n')
        self.proc.stdin.flush()

    def close(self) -> int:
        if self.proc.stdin and not self.proc.stdin.closed:
            self.proc.stdin.close()
        try:
            return self.proc.wait(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            raise


class Observer:
    """A separate participant reading ros_discovery_info as rmw_cyclonedds_cpp's graph reader does
    (reliable, transient local, keep all), twice: raw CDR decoded by msgs.deserialize, and decoded
    by Cyclone's own deserializer of dds.idl_type(ParticipantEntitiesInfo)."""

    def __init__(self) -> None:
        # the domain (loopback configuration) exists before this participant joins
        dds.participant()
        self.dp = DomainParticipant(dds.domain_id())
        qos = Qos(Policy.Reliability.Reliable(max_blocking_time=100_000_000),
                  Policy.Durability.TransientLocal,
                  Policy.History.KeepAll, Policy.DataRepresentation(use_cdrv0_representation=True))
        topic = Topic(self.dp, 'ros_discovery_info', dds.idl_type(T))
        self.raw_reader = DataReader(self.dp, topic, qos)
        self.typed_reader = DataReader(self.dp, topic, qos)
        self.raw: dict[bytes, bytes] = {}
        self.typed: dict[bytes, Any] = {}

    def poll(self) -> None:
        taken = ddspy_take(self.raw_reader._ref, dds.ANY_STATE, 1000)
        for data, info in taken:
            if info.valid_data:
                self.raw[bytes(msgs.deserialize(data, T).gid.data)] = data
        for sample in self.typed_reader.take(N=1000):
            self.typed[bytes(sample.gid.data)] = sample

    def nodes(self, gid: bytes) -> dict[tuple[str, str], tuple[list[bytes], list[bytes]]] | None:
        """{(namespace, name): (reader GUIDs, writer GUIDs)} of the latest sample of a participant,
        after checking that both decodings agree and that the bytes are Cyclone's own
        serialization."""
        self.poll()
        if gid not in self.raw or gid not in self.typed:
            return None
        msg = msgs.deserialize(self.raw[gid], T)
        typed = self.typed[gid]
        assert self.raw[gid] == typed.serialize(), 'wire bytes differ from cyclonedds serialization'
        ours = {(n.node_namespace, n.node_name): ([bytes(g.data) for g in n.reader_gid_seq],
                                                   [bytes(g.data) for g in n.writer_gid_seq])
                for n in msg.node_entities_info_seq}
        theirs = {(n.node_namespace, n.node_name): ([bytes(g.data) for g in n.reader_gid_seq],
                                                     [bytes(g.data) for g in n.writer_gid_seq])
                  for n in typed.node_entities_info_seq}
        assert ours == theirs
        return ours


@pytest.fixture(scope='module')
def observer():
    return Observer()


def test_cdr_is_byte_identical_to_cyclone_serializer() -> None:
    idl_pei, idl_node, idl_gid = (dds.idl_type(t) for t in (
        T, 'rmw_dds_common/msg/NodeEntitiesInfo', 'rmw_dds_common/msg/Gid'))
    rng = np.random.default_rng(7)

    def guid() -> bytes:
        return rng.integers(0, 256, 16, dtype=np.uint8).tobytes()

    cases = [[], [('/', 'a', [], [])],
             [('/ns/deeper', 'node_with_longer_name', [guid()], [guid(), guid()]),
                                         ('/', 'xy', [guid(), guid(), guid()], []),
                                         ('/x', 'abc', [], [guid()])]]
    for nodes in cases:
        gid = guid()
        ours = bytes(msgs.serialize(graph.build_message(gid, nodes), T))
        theirs = idl_pei(gid=idl_gid(data=list(gid)), node_entities_info_seq=[
            idl_node(node_namespace=ns, node_name=name,
                     reader_gid_seq=[idl_gid(data=list(g)) for g in r],
                     writer_gid_seq=[idl_gid(data=list(g)) for g in w])
                     for ns, name, r, w in nodes]).serialize()
        assert ours == theirs
        assert graph.parse_message(ours) == (gid, nodes)


@pytest.mark.slow
def test_two_processes_announce_their_nodes(context: Context, observer: Observer) -> None:
    suffix = uuid.uuid4().hex[:8]
    String = msgs.get_message('std_msgs/msg/String')
    local = Node(f'local_{suffix}', namespace='/graph_test', context=context,
                 start_parameter_services=False)
    local_pub = local.create_publisher(String, 'chatter', 10)
    local_sub = local.create_subscription(String, 'other', lambda m: None, 10)
    own_gid = dds.participant().guid.bytes
    local_key = ('/graph_test', f'local_{suffix}')

    child = Child(suffix)
    try:
        ids = child.read()
        child_gid = bytes.fromhex(ids['participant'])
        assert child_gid != own_gid
        talker_key, listener_key = ('/graph_test', f'talker_{suffix}'), ('/', f'listener_{suffix}')

        # this process: GID = participant GUID, the node's reader and writer GUIDs (every node
        # also writes /rosout and /parameter_events, as rclpy's do, in that order)
        events = [local._rosout_publisher.guid, local._parameter_event_publisher.guid]
        wait_equal(lambda: (observer.nodes(own_gid) or {}).get(local_key),
                   ([local_sub.guid], [*events, local_pub.guid]), 'own sample')

        # the child: both nodes, each with the GUIDs of its actual endpoints
        talker_events, listener_events = ([bytes.fromhex(ids[f'{n}_rosout']),
                                           bytes.fromhex(ids[f'{n}_events'])]
                                          for n in ('talker', 'listener'))
        wait_equal(lambda: observer.nodes(child_gid),
                   {talker_key: ([], [*talker_events, bytes.fromhex(ids['talker_writer'])]),
                    listener_key: ([bytes.fromhex(ids['listener_reader'])], listener_events)},
                   'child sample')

        # our graph reader sees the other process's nodes (and lists its own from local state)
        wait_for(lambda: {graph.NodeName(*talker_key), graph.NodeName(*listener_key),
                          graph.NodeName(*local_key)} <= set(graph.node_names_and_namespaces()),
                 'both processes in node_names_and_namespaces()')
        info = {(n.namespace, n.name): n for n in graph.snapshot()}
        assert info[talker_key].participant_gid == child_gid and not info[talker_key].local
        assert info[talker_key].writer_gids == (*talker_events, bytes.fromhex(ids['talker_writer']))
        assert info[local_key].local and info[local_key].participant_gid == own_gid

        # destroying a node in the child republishes its sample without it
        child.send('destroy talker')
        assert child.read() == {'destroyed': 'talker'}
        wait_equal(lambda: observer.nodes(child_gid),
                   {listener_key: ([bytes.fromhex(ids['listener_reader'])], listener_events)},
                   'child sample without the talker')
        wait_for(lambda: graph.NodeName(*talker_key) not in graph.node_names_and_namespaces(),
                 'talker gone')

        # destroying an entity here republishes our sample
        local.destroy_publisher(local_pub)
        wait_equal(lambda: (observer.nodes(own_gid) or {}).get(local_key),
                   ([local_sub.guid], events),
                   'own sample without the publisher')
        local_pub2 = local.create_publisher(String, 'again', 10)
        wait_equal(lambda: (observer.nodes(own_gid) or {}).get(local_key),
                   ([local_sub.guid], [*events, local_pub2.guid]),
                   'own sample with the new publisher')
    finally:
        assert child.close() == 0

    # the child's participant is gone: its nodes leave the graph
    wait_for(lambda: graph.NodeName(*listener_key) not in graph.node_names_and_namespaces(),
             'child gone')

    local.destroy_node()
    wait_for(lambda: (n := observer.nodes(own_gid)) is not None and local_key not in n,
             'own node gone')
    assert graph.NodeName(*local_key) not in graph.node_names_and_namespaces()


def test_endpoints_carry_rmw_cyclonedds_qos_and_user_data(
        context: Context, observer: Observer) -> None:
    Node(f'qos_{uuid.uuid4().hex[:8]}', context=context)  # makes sure the writer exists
    own_gid = dds.participant().guid.bytes
    publications = BuiltinDataReader(observer.dp, BuiltinTopicDcpsPublication)
    subscriptions = BuiltinDataReader(observer.dp, BuiltinTopicDcpsSubscription)
    participants = BuiltinDataReader(observer.dp, BuiltinTopicDcpsParticipant)

    def find(reader: BuiltinDataReader) -> Any:
        for sample in reader.take(N=1000):
            if (sample.topic_name == 'ros_discovery_info'
                    and sample.participant_key.bytes == own_gid):
                return sample
        return None

    writer = wait_for(lambda: find(publications), 'our ros_discovery_info writer')
    reader = wait_for(lambda: find(subscriptions), 'our ros_discovery_info reader')
    assert (writer.type_name == reader.type_name
            == 'rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_')
    wq, rq = list(writer.qos), list(reader.qos)
    for q in (wq, rq):
        assert any(isinstance(p, Policy.Reliability.Reliable) for p in q)
        assert Policy.Durability.TransientLocal in q
        assert Policy.Userdata(dds.type_hash_user_data(T)) in q
    assert Policy.History.KeepLast(1) in wq
    assert Policy.History.KeepAll in rq

    def enclave() -> bool:
        return any(s.key.bytes == own_gid
                   and Policy.Userdata(graph.ENCLAVE_USER_DATA) in list(s.qos or [])
                   for s in participants.take(N=1000))

    wait_for(enclave, 'our participant announcing USER_DATA enclave=/;')
