"""`vizzy topic list|echo|hz|info|pub`: ros2 topic's verbs, flags and output layout (Jazzy's
ros2topic), on the bundled runtime's DDS.

    vizzy topic list [-t]
    vizzy topic echo <topic> [type] [--once | -n N] [-l LEN | -f] [--no-arr] [--no-str]
                     [--flow-style]
    vizzy topic hz <topic> [--window N] [--duration S]
    vizzy topic info <topic> [-v]
    vizzy topic pub <topic> <type> ['<yaml>' | --stdin] [-r HZ] [-p N] [-1 | -t TIMES] [-w N]
                    [--max-wait-time-secs S] [--keep-alive S] [-s] [--qos-... ]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Sequence
from typing import Any

from .cli_types import (
    die,
    nonnegative_int,
    nonnegative_seconds,
    positive_int,
    positive_number,
    positive_seconds,
)

INFINITE_NS = 2**63 - 1             # DDS_INFINITY: rclpy prints such a duration as 'Infinite'
UNKNOWN_NODE = ('_NODE_NAME_UNKNOWN_', '_NODE_NAMESPACE_UNKNOWN_')   # rmw's, for unowned ones


def known_type(typename: str) -> str:
    """'pkg/msg/Type' (also 'pkg/Type') if the bundled typestore knows it, else ValueError in
    ros2's words."""
    from . import msgs
    try:
        name = msgs.normalize_type_name(typename)
    except ValueError:
        raise ValueError(f"The passed message type '{typename}' is invalid (expected "
                         'pkg/msg/Type)') from None
    if name not in msgs.registry().store.fielddefs:
        raise ValueError(f"The passed message type '{typename}' is invalid: no such type "
                         '(`vizzy interface list -m` lists the known ones)')
    return name


def wait_for_type(topic: str, typename: str | None, timeout: float) -> tuple[str, Any]:
    """(type, QoS to read with) of a topic's publishers, waiting up to timeout s for one (only
    as long when typename is given, then going on without)."""
    from . import dds
    disc = dds.Discovery()
    deadline = time.monotonic() + timeout
    while True:
        writers = [ep for ep in disc.endpoints() if ep.is_writer and ep.topic == topic]
        if writers or (typename and time.monotonic() > deadline):
            break
        if time.monotonic() > deadline:
            raise TimeoutError(f'no publisher on {topic} after {timeout:g} s (give its type to '
                               'wait anyway)')
        time.sleep(0.05)
    types = {ep.typename for ep in writers}
    if typename is None:
        if len(types) > 1:
            raise ValueError(f'{topic} has publishers of several types: {", ".join(sorted(types))}')
        typename = types.pop()
    # Adapt to the publishers like ros2 topic echo: reliable only if all are, latched if all are.
    qos = dds.QoS(reliable=bool(writers) and all(ep.qos.reliable for ep in writers),
                  transient_local=bool(writers) and all(ep.qos.transient_local for ep in writers),
                  depth=10)
    return typename, qos


def _listen_for_endpoints(wait: float) -> None:
    from .peers import Peers, listen
    peers = Peers()

    def settled() -> bool:
        peers.poll()
        return peers.endpoints_known()

    listen(wait, settled)   # discovery is asynchronous: listen before answering


# --- list / echo / hz ---------------------------------------------------------------------------

def cmd_topic_list(ns: argparse.Namespace) -> int:
    from . import dds
    disc = dds.Discovery()
    _listen_for_endpoints(ns.wait)
    topics: dict[str, set[str]] = {}
    for ep in disc.endpoints():
        topics.setdefault(ep.topic, set()).add(ep.typename)
    for name in sorted(topics):
        print(f'{name} [{", ".join(sorted(topics[name]))}]' if ns.show_types else name)
    return 0


def cmd_topic_echo(ns: argparse.Namespace) -> int:
    from . import dds, msgs
    from .msg_yaml import to_yaml
    given = ns.message_type or ns.type
    typename, qos = wait_for_type(ns.topic, given and known_type(given), ns.timeout)
    if ns.message_type is None and ns.type is None:
        known_type(typename)      # a publisher's type the typestore lacks: one line, not a trace
    reader = dds.RawReader(ns.topic, typename, qos)
    count = 1 if ns.once else ns.count
    truncate = None if ns.full_length else ns.truncate_length
    shown = 0
    while count is None or shown < count:
        batch = reader.take(16)
        if not batch:
            time.sleep(0.005)
            continue
        for raw, _stamp in batch:
            try:
                text = to_yaml(msgs.deserialize(raw, typename), truncate_length=truncate,
                               no_arr=ns.no_arr, no_str=ns.no_str, flow_style=ns.flow_style)
                print(text, end='---\n', flush=True)
            except Exception as err:  # noqa: BLE001 - report and keep echoing
                print(f'vizzy: {ns.topic}: cannot decode a {typename} sample: {err}',
                      file=sys.stderr)
            shown += 1
            if count is not None and shown >= count:
                break
    return 0


def rate_stats(stamps: Sequence[float]) -> dict[str, float]:
    """ros2 topic hz's figures from receive times (s)."""
    import numpy as np
    gaps = np.diff(np.asarray(stamps, dtype=float))
    if gaps.size == 0:
        return {'rate': 0.0, 'min': math.nan, 'max': math.nan, 'std_dev': math.nan,
                'window': len(stamps)}
    return {'rate': float(1.0 / gaps.mean()), 'min': float(gaps.min()), 'max': float(gaps.max()),
            'std_dev': float(gaps.std()), 'window': int(gaps.size + 1)}


def cmd_topic_hz(ns: argparse.Namespace) -> int:
    from . import dds
    start = time.monotonic()
    # --duration bounds the whole command, the wait for a publisher included
    wait = ns.timeout if ns.duration is None else min(ns.timeout, ns.duration)
    typename, qos = wait_for_type(ns.topic, ns.type and known_type(ns.type), wait)
    reader = dds.RawReader(ns.topic, typename, qos)
    stamps: list[float] = []
    last_print = time.monotonic()
    while ns.duration is None or time.monotonic() - start < ns.duration:
        for _ in reader.take(64):
            stamps.append(time.monotonic())
        stamps = stamps[-ns.window:]
        if time.monotonic() - last_print >= 1.0 and len(stamps) > 1:
            s = rate_stats(stamps)
            print(f"average rate: {s['rate']:.3f}\n\tmin: {s['min']:.3f}s max: {s['max']:.3f}s "
                  f"std dev: {s['std_dev']:.5f}s window: {s['window']}", flush=True)
            last_print = time.monotonic()
        time.sleep(0.001)
    return 0


# --- info ----------------------------------------------------------------------------------------

def _duration(ns: int | None) -> str:
    """rclpy Duration's str: 'Infinite' or 'N nanoseconds'."""
    return 'Infinite' if ns is None or ns >= INFINITE_NS else f'{ns} nanoseconds'


def qos_lines(dds_qos: Any) -> list[str]:
    """The 'QoS profile:' block of rclpy's TopicEndpointInfo.__str__ from a discovered QoS, read
    as rmw_cyclonedds_cpp reads it (a missing lifespan is infinite)."""
    from cyclonedds.qos import Policy
    reliability = durability = liveliness = 'UNKNOWN'
    history = 'UNKNOWN'
    deadline = lifespan = lease = None
    for p in dds_qos or ():
        if isinstance(p, Policy.Reliability.Reliable):
            reliability = 'RELIABLE'
        elif p == Policy.Reliability.BestEffort:
            reliability = 'BEST_EFFORT'
        elif isinstance(p, Policy.History.KeepLast):
            history = f'KEEP_LAST ({p.depth})'
        elif p == Policy.History.KeepAll:
            history = 'KEEP_ALL'
        elif p == Policy.Durability.Volatile:
            durability = 'VOLATILE'
        elif p == Policy.Durability.TransientLocal:
            durability = 'TRANSIENT_LOCAL'
        elif isinstance(p, Policy.Deadline):
            deadline = p.deadline
        elif isinstance(p, Policy.Lifespan):
            lifespan = p.lifespan
        elif isinstance(p, Policy.Liveliness.Automatic):
            liveliness, lease = 'AUTOMATIC', p.lease_duration
        elif isinstance(p, Policy.Liveliness.ManualByTopic):
            liveliness, lease = 'MANUAL_BY_TOPIC', p.lease_duration
        elif isinstance(p, Policy.Liveliness.ManualByParticipant):
            liveliness, lease = 'MANUAL_BY_NODE', p.lease_duration
    return ['QoS profile:',
            f'  Reliability: {reliability}',
            f'  History (Depth): {history}',
            f'  Durability: {durability}',
            f'  Lifespan: {_duration(lifespan)}',
            f'  Deadline: {_duration(deadline)}',
            f'  Liveliness: {liveliness}',
            f'  Liveliness lease duration: {_duration(lease)}']


def node_owners(infos: Sequence[Any]) -> dict[bytes, tuple[str, str]]:
    """Endpoint GUID -> (node name, namespace), from the nodes' ros_discovery_info."""
    owners: dict[bytes, tuple[str, str]] = {}
    for info in infos:
        for gid in (*info.reader_gids, *info.writer_gids):
            owners[gid] = (info.name, info.namespace)
    return owners


def endpoint_text(ep: Any, owners: dict[bytes, tuple[str, str]]) -> str:
    """One endpoint as rclpy's TopicEndpointInfo.__str__ prints it (`ros2 topic info -v`)."""
    name, namespace = owners.get(ep.guid, UNKNOWN_NODE)
    return '\n'.join([f'Node name: {name}',
                      f'Node namespace: {namespace}',
                      f'Topic type: {ep.typename}',
                      f'Topic type hash: {ep.type_hash or "INVALID"}',
                      f'Endpoint type: {"PUBLISHER" if ep.is_writer else "SUBSCRIPTION"}',
                      f'GID: {".".join(f"{b:02x}" for b in ep.guid)}',
                      *qos_lines(ep.dds_qos)])


def cmd_topic_info(ns: argparse.Namespace) -> int:
    from . import dds
    from .peers import discover_nodes
    disc = dds.Discovery()
    infos = discover_nodes(ns.wait) if ns.verbose else []
    if not ns.verbose:
        _listen_for_endpoints(ns.wait)
    endpoints = [ep for ep in disc.endpoints() if ep.topic == ns.topic]
    if not endpoints:
        return die(f"Unknown topic '{ns.topic}'", 1)
    types = sorted({ep.typename for ep in endpoints})
    end = '\n\n' if ns.verbose else '\n'
    print(f'Type: {types[0] if len(types) == 1 else types}', end=end)
    owners = node_owners(infos)
    for is_writer, label in ((True, 'Publisher count'), (False, 'Subscription count')):
        mine = sorted((ep for ep in endpoints if ep.is_writer == is_writer),
                      key=lambda ep: owners.get(ep.guid, UNKNOWN_NODE)[::-1] + (ep.guid,))
        print(f'{label}: {len(mine)}', end=end)
        if ns.verbose:
            for ep in mine:
                print(endpoint_text(ep, owners), end=end)
    return 0


# --- pub -----------------------------------------------------------------------------------------

QOS_PRESETS = {  # rclpy's presets as `--qos-profile` names them: (reliable, transient, depth)
    'default': (True, False, 10), 'system_default': (True, False, 10),
    'sensor_data': (False, False, 5), 'services_default': (True, False, 10),
    'parameters': (True, False, 1000), 'parameter_events': (True, False, 1000),
    'action_status_default': (True, True, 1), 'best_available': (True, False, 10),
}


def pub_qos(ns: argparse.Namespace) -> Any:
    """The QoS of `ros2 topic pub` from --qos-profile and its overrides."""
    from . import dds
    reliable, transient, depth = QOS_PRESETS[ns.qos_profile]
    if ns.qos_reliability and ns.qos_reliability != 'system_default':
        reliable = ns.qos_reliability == 'reliable'
    if ns.qos_durability and ns.qos_durability != 'system_default':
        transient = ns.qos_durability == 'transient_local'
    keep_all = ns.qos_history == 'keep_all'
    if ns.qos_depth is not None and ns.qos_depth >= 0:
        depth = ns.qos_depth
    return dds.QoS(reliable=reliable, transient_local=transient, keep_all=keep_all,
                   depth=max(depth, 1))


class _SimClock:
    """The latest /clock (rosgraph_msgs/Clock), 0 until one arrives, as an rclpy node with
    use_sim_time tells the time."""

    def __init__(self) -> None:
        from . import dds
        self._reader = dds.RawReader('/clock', 'rosgraph_msgs/msg/Clock',
                                     dds.QoS(reliable=False, depth=1))
        self.clock: Any = None

    def now(self) -> Any:
        from . import msgs
        for raw, _ in self._reader.take(16):
            self.clock = msgs.deserialize(raw, 'rosgraph_msgs/msg/Clock').clock
        return self.clock if self.clock is not None else msgs.get_message(
            'builtin_interfaces/msg/Time')()


def _wall_now() -> Any:
    from . import msgs
    ns = time.time_ns()
    return msgs.get_message('builtin_interfaces/msg/Time')(sec=ns // 10**9, nanosec=ns % 10**9)


def cmd_topic_pub(ns: argparse.Namespace) -> int:
    from . import dds, msgs
    from .msg_yaml import FieldError, parse_values, set_fields
    if not ns.topic.startswith('/'):
        ns.topic = '/' + ns.topic       # relative to the root namespace, as a CLI node's is
    typename = known_type(ns.message_type)
    times = 1 if ns.once else ns.times
    wait_subs = ns.wait_matching_subscriptions
    if wait_subs is None:
        wait_subs = int(times != 0)
    if wait_subs == 0 and ns.max_wait_time_secs is not None:
        return die('topic pub: --max-wait-time-secs option is only effective with '
                   '--wait-matching-subscriptions, --once or --times')
    msg = msgs.get_message(typename)()
    try:
        stamps = set_fields(msg, parse_values(sys.stdin.read() if ns.stdin else ns.values))
    except FieldError as err:
        return die(f'topic pub: Failed to populate field: {err}', 1)
    writer = dds.RawWriter(ns.topic, typename, pub_qos(ns))
    clock = _SimClock() if ns.use_sim_time else None
    try:
        waited = 0.0
        logged = 0
        while writer.matched_count() < wait_subs:
            if not logged:    # ros2's line, once a second while waiting
                print(f'Waiting for at least {wait_subs} matching subscription(s)...',
                      flush=True)
            if ns.max_wait_time_secs is not None and waited >= ns.max_wait_time_secs:
                return die(f'topic pub: Timed out waiting for subscribers: Expected {wait_subs} '
                           f'subcribers but only got {writer.matched_count()} subscribers', 1)
            logged = (logged + 1) % 10
            time.sleep(0.1)
            waited += 0.1
        print('publisher: beginning loop', flush=True)
        count = 0
        start = time.monotonic()
        while True:
            now = clock.now() if clock is not None else _wall_now()
            for stamp in stamps:
                stamp(now)
            count += 1
            if ns.print and count % ns.print == 0:
                print(f'publishing #{count}: {msg!r}\n', flush=True)
            writer.write(msgs.serialize(msg, typename))
            if times and count >= times:
                break
            # deadlines from the start: the rate holds whatever the time a publish took
            time.sleep(max(0.0, start + count / ns.rate - time.monotonic()))
        time.sleep(ns.keep_alive)   # give the last message time to reach the wire
    finally:
        dds.delete(writer)   # a reliable writer lingers until its readers acknowledged
    return 0


# --- parser --------------------------------------------------------------------------------------

def _add_wait(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument('--wait', type=nonnegative_seconds, default=1.0,
                   help='seconds to listen for discovery at least; then until every ROS 2 process '
                        f'seen has shown its {what} (at most 5 s more)')


def add_parser(sub: Any) -> None:
    topic = sub.add_parser('topic', help='inspect and publish topics (like ros2 topic)'
                           ).add_subparsers(dest='topic_verb', required=True)

    tl = topic.add_parser('list', help='the topics of the graph')
    tl.add_argument('-t', '--show-types', action='store_true')
    _add_wait(tl, 'readers and writers')
    tl.set_defaults(func=cmd_topic_list)

    echo = topic.add_parser('echo', help="print a topic's messages as YAML")
    echo.add_argument('topic')
    echo.add_argument('message_type', nargs='?',
                      help="type of the messages (e.g. 'std_msgs/msg/String'), if no publisher "
                           'is up yet')
    echo.add_argument('--type', help=argparse.SUPPRESS)   # the earlier spelling of message_type
    echo.add_argument('--timeout', type=positive_seconds, default=10.0,
                      help='seconds to wait for a publisher (default 10)')
    once = echo.add_mutually_exclusive_group()
    once.add_argument('--once', action='store_true',
                      help='print the first message received and exit')
    once.add_argument('-n', '--count', type=positive_int, help='exit after this many messages')
    echo.add_argument('-l', '--truncate-length', type=nonnegative_int, default=128,
                      help='the length to truncate arrays, bytes and strings to (default 128)')
    echo.add_argument('-f', '--full-length', action='store_true',
                      help="print arrays and strings whole (no '...' after --truncate-length)")
    echo.add_argument('--no-arr', action='store_true', help="don't print array fields")
    echo.add_argument('--no-str', action='store_true', help="don't print string fields")
    echo.add_argument('--flow-style', action='store_true',
                      help='print collections in YAML flow style')
    echo.set_defaults(func=cmd_topic_echo)

    hz = topic.add_parser('hz', help="a topic's publishing rate")
    hz.add_argument('topic')
    hz.add_argument('--type', help='message type, if no publisher is up yet')
    hz.add_argument('--timeout', type=positive_seconds, default=10.0,
                    help='seconds to wait for a publisher (default 10, at most --duration)')
    hz.add_argument('--window', type=positive_int, default=100)
    hz.add_argument('--duration', type=positive_seconds,
                    help='exit after this many seconds, the wait for a publisher included')
    hz.set_defaults(func=cmd_topic_hz)

    info = topic.add_parser('info', help="a topic's type and its publishers and subscriptions")
    info.add_argument('topic')
    info.add_argument('-v', '--verbose', action='store_true',
                      help='also each endpoint: node name and namespace, type, type hash, GID, '
                           'QoS profile')
    _add_wait(info, 'readers and writers (and with -v its nodes)')
    info.set_defaults(func=cmd_topic_info)

    pub = topic.add_parser('pub', help='publish a message to a topic')
    pub.add_argument('topic', help="name of the topic to publish to (e.g. '/gaze/command')")
    pub.add_argument('message_type', help="type of the message (e.g. 'std_msgs/msg/String')")
    values = pub.add_mutually_exclusive_group()
    values.add_argument('values', nargs='?', default='{}',
                        help="values to fill the message with, in YAML (e.g. 'data: hi'; "
                             "'header: auto' stamps a header, 'now' a time); default: defaults")
    values.add_argument('--stdin', action='store_true', help='read the values from stdin')
    pub.add_argument('-r', '--rate', metavar='N', type=positive_number, default=1.0,
                     help='publishing rate in Hz (default: 1)')
    pub.add_argument('-p', '--print', metavar='N', type=int, default=1,
                     help='only print every N-th published message (default: 1)')
    times = pub.add_mutually_exclusive_group()
    times.add_argument('-1', '--once', action='store_true', help='publish one message and exit')
    times.add_argument('-t', '--times', type=nonnegative_int, default=0,
                       help='publish this number of times and then exit')
    pub.add_argument('-w', '--wait-matching-subscriptions', type=nonnegative_int, default=None,
                     help='wait until this many subscriptions match (default 1 with -1/--once/'
                          '--times, else 0)')
    pub.add_argument('--max-wait-time-secs', type=positive_number, default=None,
                     help='the longest wait for those subscriptions (default: no limit)')
    pub.add_argument('--keep-alive', metavar='N', type=nonnegative_seconds, default=0.1,
                     help='keep the publisher for N seconds after the last message (default 0.1)')
    pub.add_argument('-s', '--use-sim-time', action='store_true',
                     help="stamp 'auto' headers and 'now' times from /clock (0 until it ticks)")
    pub.add_argument('--qos-profile', choices=sorted(QOS_PRESETS), default='default',
                     help='QoS preset profile to publish with (default: default)')
    pub.add_argument('--qos-depth', metavar='N', type=int, help='queue size (overrides the '
                     "profile's)")
    pub.add_argument('--qos-history', choices=['system_default', 'keep_last', 'keep_all'])
    pub.add_argument('--qos-reliability', choices=['system_default', 'reliable', 'best_effort'])
    pub.add_argument('--qos-durability', choices=['system_default', 'transient_local',
                                                  'volatile'])
    pub.set_defaults(func=cmd_topic_pub)
