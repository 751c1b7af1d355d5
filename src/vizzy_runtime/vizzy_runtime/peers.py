"""Who else is on the DDS domain: the ROS 2 processes and the nodes they announce, heard for as
long as discovery needs and no longer (`vizzy node list`, and the launcher's check that the
graph's node names are free before it starts one).

Fixed waits miss real ROS 2 processes on other DDS implementations: a Fast DDS
(rmw_fastrtps_cpp) participant is seen at once, but Cyclone often learns its readers and writers
only ~1.1 s later, and its ros_discovery_info sample (the node names) only with Fast DDS's next
periodic heartbeat, ~3 s after matching: its first sample to a reader it had just matched reached
Cyclone before Cyclone knew the writer, and it does not resend on Cyclone's pre-emptive ACKNACK.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from typing import Any


class Peers:
    """The other ROS 2 processes (participants with rmw's `enclave=` USER_DATA) of the domain, so
    a short-lived CLI can wait until it has heard what they announce, not a fixed time."""

    # a participant seen this long without both readers and writers has no more (another CLI)
    ENDPOINT_GRACE_S = 2.0

    def __init__(self) -> None:
        from cyclonedds.builtin import (
            BuiltinDataReader,
            BuiltinTopicDcpsParticipant,
            BuiltinTopicDcpsPublication,
            BuiltinTopicDcpsSubscription,
        )

        from . import dds
        dp = dds.participant()
        self._self = dp.guid.bytes
        self._participants = BuiltinDataReader(dp, BuiltinTopicDcpsParticipant)
        self._endpoints = [BuiltinDataReader(dp, BuiltinTopicDcpsPublication),
                           BuiltinDataReader(dp, BuiltinTopicDcpsSubscription)]
        self.first_seen: dict[bytes, float] = {}   # live peers
        self.with_writers: set[bytes] = set()
        self.with_readers: set[bytes] = set()
        self.announcing: set[bytes] = set()        # peers with a ros_discovery_info writer

    def poll(self) -> None:
        from cyclonedds.core import InstanceState
        try:
            for s in self._participants.take(N=256):
                key = s.key.bytes
                if s.sample_info.instance_state != InstanceState.Alive:
                    self.first_seen.pop(key, None)
                elif key != self._self and b'enclave=' in user_data(s.qos):
                    self.first_seen.setdefault(key, time.monotonic())
            for reader, seen in zip(self._endpoints, (self.with_writers, self.with_readers),
                                    strict=True):
                for s in reader.take(N=1000):
                    if s.sample_info.instance_state == InstanceState.Alive:
                        seen.add(s.participant_key.bytes)
                        if s.topic_name == 'ros_discovery_info' and seen is self.with_writers:
                            self.announcing.add(s.participant_key.bytes)
        except Exception:  # noqa: BLE001 - decoding a peer being torn down can fail: look again
            pass

    def endpoints_known(self) -> bool:
        """Every live peer's readers and writers have been seen. A ROS 2 process has both (at
        least ros_discovery_info's); they come in one burst per kind, but the two kinds from Fast
        DDS up to ~1 s apart. A peer seen for ENDPOINT_GRACE_S without both has no more."""
        now = time.monotonic()
        return all((key in self.with_writers and key in self.with_readers)
                   or now - t > self.ENDPOINT_GRACE_S for key, t in self.first_seen.items())

    def unheard(self, heard: set[bytes]) -> set[bytes]:
        """Live peers that announce their nodes on ros_discovery_info but are not in heard."""
        return {key for key in self.first_seen if key in self.announcing and key not in heard}


def user_data(qos: Any) -> bytes:
    from cyclonedds.qos import Policy
    for policy in qos or ():
        if isinstance(policy, Policy.Userdata):
            return bytes(policy.data)
    return b''


def listen(wait: float, settled: Callable[[], bool], max_extra: float = 5.0,
           start: float | None = None) -> None:
    """Listen until `wait` seconds after start (default: now), then until settled(), at most
    max_extra seconds more."""
    start = time.monotonic() if start is None else start
    while True:
        elapsed = time.monotonic() - start
        if elapsed >= wait and (settled() or elapsed >= wait + max_extra):
            return
        time.sleep(0.05)


def discover_nodes(wait: float) -> list[Any]:
    """Every node of the domain (rclpy_compat.graph.NodeInfo, one per node and view of it), once
    each peer's endpoints and node announcements have been heard: `wait` seconds at least, then
    up to a few more while a peer is still being discovered."""
    from .rclpy_compat import graph
    start = time.monotonic()
    peers = Peers()

    def endpoints_known() -> bool:
        peers.poll()
        return peers.endpoints_known()

    # Only then read ros_discovery_info: a Fast DDS writer that learns of our reader after we
    # learnt of it delivers its latched sample at once, not ~3 s later with its next heartbeat.
    listen(min(wait, 0.25), endpoints_known, max_extra=3.0, start=start)
    graph.snapshot()

    def settled() -> bool:
        return endpoints_known() and not peers.unheard(graph.announced_participants())

    listen(wait, settled, start=start)
    return graph.snapshot()


def full_name(info: Any) -> str:
    return f'{info.namespace.rstrip("/")}/{info.name}'


def shared_names(infos: Iterable[Any]) -> list[tuple[str, int]]:
    """(full name, how many) of each node name more than one node of the graph has."""
    counts: dict[str, int] = {}
    seen = set()
    for info in infos:        # one node may be known twice (its own process's view and the wire)
        key = (info.namespace, info.name, info.participant_gid, info.reader_gids,
               info.writer_gids)
        if key in seen:
            continue
        seen.add(key)
        counts[full_name(info)] = counts.get(full_name(info), 0) + 1
    return sorted((name, n) for name, n in counts.items() if n > 1)
