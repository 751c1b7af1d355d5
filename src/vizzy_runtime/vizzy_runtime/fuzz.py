"""Fuzzing the nodes' inputs: well-typed bad messages, malformed CDR, and a harness that runs one
node of the graph at a time and feeds every topic it subscribes to.

Messages (Mutator): start from a valid message of the topic's type (TEMPLATES, small) and
- change 1-3 fields picked at random, recursively, to values of the field's own type that a node
  must survive: 0, -1 or the extremes of integers, NaN/inf/huge floats, empty/unknown/long
  strings, empty/shortened/lengthened sequences, NaN-filled float arrays, random bytes;
- or apply a type-aware case: image or cloud sizes inconsistent with their data, zero or huge
  claimed sizes, empty or field-less PointCloud2, negative/zero/future stamps, unknown frames,
  out-of-range joint targets;
- or send malformed CDR (truncated, random or bit-flipped bytes). Cyclone DDS checks what it
  sends and receives against the type, so most of it stops at the sender ('blocked by DDS') or at
  the node's DDS reader; what still parses (a flipped bit in a value) reaches the node.

Harness (fuzz_node): start one node (graph.yaml's entry: parameters and remappings) on the caller's
ROS_DOMAIN_ID, find its inputs by DDS discovery, keep a valid /clock running, send N messages to
each input topic, then check the node: a crash is the process gone, a hang is no /diagnostics
status (InputHealth publishes one about every second) within HANG_S after a burst. Its refusals are
read from that status. Everything is on loopback, like the rest of the runtime.
"""

from __future__ import annotations

import math
import random
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from cyclonedds.core import DDSException
from rosbags.interfaces import Nodetype

from . import dds, msgs

INT_RANGES = {
    'bool': (0, 1), 'byte': (0, 255), 'char': (0, 255), 'uint8': (0, 255), 'int8': (-128, 127),
    'uint16': (0, 2**16 - 1), 'int16': (-2**15, 2**15 - 1), 'uint32': (0, 2**32 - 1),
    'int32': (-2**31, 2**31 - 1), 'uint64': (0, 2**64 - 1), 'int64': (-2**63, 2**63 - 1)}
FLOATS = ('float32', 'float64')
BAD_FLOATS = (math.nan, math.inf, -math.inf, 0.0, -0.0, 1e38, -1e38, 5e-324)
BAD_STRINGS = ('', 'unknown', 'no_such_frame', 'x' * 4096, '../../etc/passwd', '\x00',
               'yuv422_yuy2',
               'ü¿?')
MAX_SEQUENCE = 4096  # elements a lengthened sequence may reach (keeps each message small)
HANG_S = 15.0        # no /diagnostics from the node this long after a burst: a hang


# --- valid templates ---------------------------------------------------------------------------

def _stamp(now_ns: int | None = None) -> Any:
    ns = time.time_ns() if now_ns is None else now_ns
    return msgs.get_message('builtin_interfaces/msg/Time')(sec=ns // 10**9, nanosec=ns % 10**9)


def _header(frame: str) -> Any:
    return msgs.get_message('std_msgs/msg/Header')(stamp=_stamp(), frame_id=frame)


def _image(frame: str = 'l_camera_optical_frame') -> Any:
    h, w = 24, 32
    data = np.random.default_rng(0).integers(0, 255, h * w * 3, dtype=np.uint8)
    return msgs.get_message('sensor_msgs/msg/Image')(
        header=_header(frame), height=h, width=w, encoding='rgb8', is_bigendian=0, step=w * 3,
        data=data)


def _camera_info(frame: str = 'l_camera_optical_frame') -> Any:
    info = msgs.get_message('sensor_msgs/msg/CameraInfo')()
    info.header = _header(frame)
    info.height, info.width = 24, 32
    info.distortion_model = 'plumb_bob'
    info.d = np.zeros(5)
    info.k = np.array([30.0, 0, 16, 0, 30.0, 12, 0, 0, 1])
    info.r = np.eye(3).ravel()
    info.p = np.array([30.0, 0, 16, 0, 0, 30.0, 12, 0, 0, 0, 1, 0])
    return info


def _cloud(frame: str = 'rgbd_camera_optical_frame') -> Any:
    field_t = msgs.get_message('sensor_msgs/msg/PointField')
    pts = np.random.default_rng(0).uniform(-0.5, 0.5, (16, 12, 3)).astype(np.float32)
    pts[..., 2] += 1.0
    return msgs.get_message('sensor_msgs/msg/PointCloud2')(
        header=_header(frame), height=16, width=12,
        fields=[field_t(name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate('xyz')],
        is_bigendian=False, point_step=12, row_step=12 * 12,
        data=np.frombuffer(pts.tobytes(), dtype=np.uint8).copy(), is_dense=True)


def _joint_state() -> Any:
    names = ['neck_pan_joint', 'neck_tilt_joint', 'eyes_tilt_joint', 'l_eye_joint', 'r_eye_joint']
    return msgs.get_message('sensor_msgs/msg/JointState')(
        header=_header('base_link'), name=names, position=np.full(5, 0.05), velocity=np.zeros(5),
        effort=np.zeros(0))


def _gaze_command() -> Any:
    cmd = msgs.get_message('active_vision_msgs/msg/GazeCommand')()
    cmd.header = _header('base_link')
    cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z = 1.0, 0.0, 0.2
    cmd.source, cmd.priority, cmd.hold_time = 'fuzz', 1, 0.0
    return cmd


def _tf_message() -> Any:
    tf = msgs.get_message('geometry_msgs/msg/TransformStamped')()
    tf.header = _header('base_link')
    tf.child_frame_id = 'fuzz_frame'
    tf.transform.translation.x = 0.1
    tf.transform.rotation.w = 1.0
    return msgs.get_message('tf2_msgs/msg/TFMessage')(transforms=[tf])


def _clock() -> Any:
    return msgs.get_message('rosgraph_msgs/msg/Clock')(clock=_stamp())


TEMPLATES: dict[str, Callable[[], Any]] = {
    'sensor_msgs/msg/Image': _image,
    'sensor_msgs/msg/CameraInfo': _camera_info,
    'sensor_msgs/msg/PointCloud2': _cloud,
    'sensor_msgs/msg/JointState': _joint_state,
    'active_vision_msgs/msg/GazeCommand': _gaze_command,
    'tf2_msgs/msg/TFMessage': _tf_message,
    'rosgraph_msgs/msg/Clock': _clock,
}


def template(typename: str) -> Any:
    """A valid message of typename (a default-constructed one for types without a template)."""
    make = TEMPLATES.get(typename)
    return make() if make else msgs.get_message(typename)()


# --- mutations ---------------------------------------------------------------------------------

def _bad_base(kind: str, current: Any, rng: random.Random) -> Any:
    if kind in INT_RANGES:
        lo, hi = INT_RANGES[kind]
        if kind == 'bool':
            return not bool(current)
        return rng.choice([0, lo, hi, min(hi, max(lo, -1)), min(hi, 1), rng.randint(lo, hi)])
    if kind in FLOATS:
        return rng.choice(BAD_FLOATS)
    if kind in ('string', 'wstring'):
        return rng.choice(BAD_STRINGS)
    return current


def _bad_sequence(desc: Any, current: Any, rng: random.Random, fixed: int) -> Any:
    (inner_kind, inner), _bound = desc
    n = len(current)
    if inner_kind == Nodetype.BASE:
        base = inner[0]
        dtype = current.dtype if isinstance(current, np.ndarray) else None
        if fixed:   # a fixed-size array keeps its length: bad values instead
            if base in FLOATS:
                return np.array([rng.choice(BAD_FLOATS) for _ in range(n)], dtype=dtype or float)
            return current
        choice = rng.randrange(4)
        if choice == 0:
            length = 0
        elif choice == 1:
            length = rng.randrange(max(1, n))
        else:
            length = min(MAX_SEQUENCE, max(1, n) * rng.choice([2, 3, 10]))
        if base in FLOATS:
            values: list[Any] = [rng.choice(BAD_FLOATS) for _ in range(length)]
        elif base in INT_RANGES:
            lo, hi = INT_RANGES[base]
            values = [rng.randint(lo, hi) for _ in range(length)]
            if base == 'bool':
                values = [bool(v) for v in values]
        else:
            values = [rng.choice(BAD_STRINGS) for _ in range(min(length, 64))]
        return np.array(values, dtype=dtype) if dtype is not None else values
    # sequence of messages: drop, repeat or mutate one
    items = list(current)
    if not items or rng.random() < 0.3:
        return [] if rng.random() < 0.5 else items * min(8, MAX_SEQUENCE // max(1, len(items)))
    i = rng.randrange(len(items))
    items[i] = _mutate(inner, items[i], rng)
    return items


def _mutate(typename: str, msg: Any, rng: random.Random) -> Any:
    """msg with one field (picked at random, recursively) set to a bad value of its type."""
    fields = msgs.registry().fields(typename)
    if not fields:
        return msg
    name, (kind, desc) = rng.choice(fields)
    current = getattr(msg, name)
    if kind == Nodetype.BASE:
        setattr(msg, name, _bad_base(desc[0], current, rng))
    elif kind == Nodetype.NAME:
        setattr(msg, name, _mutate(desc, current, rng))
    elif kind == Nodetype.ARRAY:
        setattr(msg, name, _bad_sequence((desc[0], 0), current, rng, fixed=len(current)))
    elif kind == Nodetype.SEQUENCE:
        setattr(msg, name, _bad_sequence(desc, current, rng, fixed=0))
    return msg


def _semantic(typename: str, msg: Any, rng: random.Random) -> Any:
    """Type-aware bad content that a field-level change rarely produces."""
    if hasattr(msg, 'header') and rng.random() < 0.5:
        pick = rng.randrange(4)
        if pick == 0:
            msg.header.stamp.sec, msg.header.stamp.nanosec = -rng.randint(1, 2**31), 0
        elif pick == 1:
            msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 0
        elif pick == 2:
            msg.header.stamp.sec = 2**31 - 1
        else:
            msg.header.frame_id = rng.choice(['', 'no_such_frame', '/base_link', 'map'])
        return msg
    if typename == 'sensor_msgs/msg/Image':
        pick = rng.randrange(5)
        if pick == 0:
            msg.height = rng.choice([0, 1, 2**31, 2**32 - 1])
        elif pick == 1:
            msg.step = rng.choice([0, 1, msg.width, msg.width * 3 - 1, 2**32 - 1])
        elif pick == 2:
            msg.data = msg.data[: rng.randrange(len(msg.data))]
        elif pick == 3:
            msg.encoding = rng.choice(['mono16', '32FC1', 'bgra8', 'bayer_rggb8', '16UC3', 'nope'])
        else:
            msg.width, msg.height = msg.height, msg.width
    elif typename == 'sensor_msgs/msg/PointCloud2':
        pick = rng.randrange(5)
        if pick == 0:
            msg.fields = []
        elif pick == 1:
            msg.data = msg.data[: rng.randrange(len(msg.data))]
        elif pick == 2:
            msg.point_step = rng.choice([0, 1, 4, 2**32 - 1])
        elif pick == 3:
            pts = np.full(len(msg.data) // 4, np.nan, dtype=np.float32)
            msg.data = np.frombuffer(pts.tobytes(), dtype=np.uint8).copy()
        else:
            msg.width, msg.height = rng.choice([(0, 0), (2**31, 1), (msg.width, msg.height * 2)])
    elif typename == 'sensor_msgs/msg/JointState':
        msg.position = np.array([rng.choice([10.0, -10.0, 1e6, math.nan])] * len(msg.position))
    elif typename == 'active_vision_msgs/msg/GazeCommand':
        msg.mode = 1
        msg.joint_names = ['l_eye_joint', 'neck_pan_joint']
        msg.joint_positions = np.array([rng.choice([5.0, -5.0, math.inf]), rng.uniform(-9, 9)])
    elif typename == 'sensor_msgs/msg/CameraInfo':
        msg.k = np.array([rng.choice([0.0, -1.0, math.nan])] * 9)
    return _mutate(typename, msg, rng)


def _raw_bad(data: bytes, rng: random.Random) -> bytes:
    pick = rng.randrange(3)
    if pick == 0 and len(data) > 4:
        out = data[: rng.randrange(4, len(data))]
    elif pick == 1:
        out = data[:4] + bytes(rng.getrandbits(8) for _ in range(rng.randrange(0, 256)))
    else:
        raw = bytearray(data)
        for _ in range(rng.randint(1, 8)):
            i = rng.randrange(4, len(raw)) if len(raw) > 4 else 0
            raw[i] ^= 1 << rng.randrange(8)
        out = bytes(raw)
    return out


class Mutator:
    """Bad messages of one type, reproducible from the seed: next() -> (kind, CDR bytes)."""

    def __init__(self, typename: str, seed: int) -> None:
        self.typename = typename
        self.rng = random.Random(seed)

    def valid(self) -> bytes:
        return _serialize(template(self.typename), self.typename)

    def next(self) -> tuple[str, bytes]:
        for _ in range(20):
            roll = self.rng.random()
            msg = template(self.typename)
            try:
                if roll < 0.15:
                    return 'malformed CDR', _raw_bad(_serialize(msg, self.typename), self.rng)
                if roll < 0.5:
                    return 'type-aware', _serialize(_semantic(self.typename, msg, self.rng),
                                                    self.typename)
                for _ in range(self.rng.randint(1, 3)):
                    msg = _mutate(self.typename, msg, self.rng)
                return 'field', _serialize(msg, self.typename)
            except (ValueError, OverflowError, TypeError, KeyError, AttributeError, IndexError):
                continue  # not serializable as that type: draw again
        return 'valid', self.valid()


def _serialize(msg: Any, typename: str) -> bytes:
    return bytes(msgs.serialize(msg, typename))  # (RawWriter.write pads to 4 bytes)


# --- the harness -------------------------------------------------------------------------------

@dataclass
class TopicReport:
    topic: str
    typename: str
    sent: int = 0
    kinds: dict[str, int] = field(default_factory=dict)


@dataclass
class NodeReport:
    node: str
    topics: list[TopicReport] = field(default_factory=list)
    crashed: bool = False
    hung: bool = False
    exit_code: int | None = None
    refusals: dict[str, int] = field(default_factory=dict)   # '<topic>: <reason>' -> count
    accepted: dict[str, int] = field(default_factory=dict)   # '<topic>' -> count
    log_tail: str = ''

    def as_dict(self) -> dict[str, Any]:
        return {'sent': {t.topic: t.sent for t in self.topics},
                'kinds': {t.topic: t.kinds for t in self.topics}, 'crashed': self.crashed,
                'hung': self.hung, 'exit_code': self.exit_code, 'refusals': self.refusals,
                'accepted': self.accepted}


class _Diagnostics:
    """The latest /diagnostics status of one node (by its full name)."""

    def __init__(self, node_fqn: str) -> None:
        self.fqn = node_fqn
        self.count = 0
        self.values: dict[str, str] = {}
        self._reader = dds.RawReader('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
                                     dds.QoS(reliable=True, depth=50))

    def poll(self) -> None:
        for raw, _ in self._reader.take(64):
            try:
                array = msgs.deserialize(raw, 'diagnostic_msgs/msg/DiagnosticArray')
            except Exception:  # noqa: BLE001 - someone else's junk on /diagnostics
                continue
            for status in array.status:
                if status.name == self.fqn:
                    self.count += 1
                    self.values = {kv.key: kv.value for kv in status.values}

    def topic_total(self, topic: str) -> int:
        """Messages on `topic` the node has counted so far, refused or accepted."""
        return sum(int(v) for k, v in self.values.items()
                   if k.startswith(f'{topic}: ') and v.isdigit())

    def close(self) -> None:
        dds.delete(self._reader)


def fuzz_node(name: str, per_topic: int, seed: int, *, graph_file: str | Path | None = None,
              log_dir: Path, pace_every: int = 100, pace_s: float = 0.01,
              progress: Callable[[str], None] | None = None, grace_s: float = 5.0) -> NodeReport:
    """Run graph.yaml's node `name` alone and fuzz each of its input topics with per_topic
    messages; returns what happened. The caller's ROS_DOMAIN_ID must be free of other graphs.
    A node still running grace_s after SIGINT at the end counts as hung (the launcher's own
    default, 5 s; tests on a loaded machine give more)."""
    from .launcher import Graph, Launcher, default_graph_file, load_graph
    graph = load_graph(graph_file or default_graph_file())
    spec = next(s for s in graph.nodes if s.name == name)
    alone = Graph(nodes=[spec], use_sim_time=graph.use_sim_time, respawn=False)
    report = NodeReport(node=name)
    log_path = log_dir / f'fuzz_{name}.log'
    log = open(log_path, 'w+')  # noqa: SIM115 - the launcher's log, closed below
    launcher = Launcher(alone, output=log, grace_s=grace_s)
    diag = _Diagnostics(f'/{name}')
    disc = dds.Discovery()
    ours = dds.participant().guid.bytes
    clock = dds.RawWriter('/clock', 'rosgraph_msgs/msg/Clock', dds.QoS(reliable=True, depth=1))
    ticking = threading.Event()

    def tick() -> None:  # a valid, advancing /clock for sim-time timers (fuzzed /clock interleaves)
        while not ticking.wait(0.05):
            clock.write(_serialize(_clock(), 'rosgraph_msgs/msg/Clock'))

    ticker = threading.Thread(target=tick, daemon=True)
    writers: list[dds.RawWriter] = []
    try:
        launcher.start()
        ticker.start()
        deadline = time.monotonic() + 90
        while diag.count == 0 and time.monotonic() < deadline and launcher.poll()[name] is None:
            diag.poll()
            time.sleep(0.05)
        if diag.count == 0:
            report.crashed = launcher.poll()[name] is not None
            report.hung = not report.crashed
            return report
        time.sleep(1.0)  # its subscriptions are announced with its first status at the latest
        inputs = sorted({(ep.topic, ep.typename, ep.qos.transient_local) for ep in disc.endpoints()
                         if not ep.is_writer and ep.participant_guid != ours
                         and ep.topic not in ('/diagnostics', '/parameter_events', '/rosout')})
        for index, (topic, typename, latched) in enumerate(inputs):
            if progress:
                progress(f'{name}: {topic} [{typename}]')
            writer = dds.RawWriter(topic, typename, dds.QoS(reliable=True, transient_local=latched,
                                                            depth=1))
            writers.append(writer)
            mutator = Mutator(typename, seed * 1000 + index)
            tr = TopicReport(topic, typename)
            report.topics.append(tr)
            matched = time.monotonic() + 10
            while writer.matched_count() == 0 and time.monotonic() < matched:
                time.sleep(0.02)
            for i in range(per_topic):
                kind, data = mutator.next()
                try:
                    writer.write(data)
                except DDSException:  # Cyclone checks what it sends against the type
                    kind = 'blocked by DDS'
                tr.sent += 1
                tr.kinds[kind] = tr.kinds.get(kind, 0) + 1
                if i % pace_every == pace_every - 1:
                    time.sleep(pace_s)
                    if launcher.poll()[name] is not None:
                        break
            for _ in range(3):
                writer.write(mutator.valid())
            # alive and spinning: a fresh status after the burst
            seen = diag.count
            wait_until = time.monotonic() + HANG_S
            while time.monotonic() < wait_until and launcher.poll()[name] is None:
                diag.poll()
                if diag.count > seen + 1:
                    break
                time.sleep(0.05)
            if launcher.poll()[name] is not None:
                report.crashed = True
                break
            if diag.count <= seen + 1:
                report.hung = True
                break
            # a busy node may still be working through the burst's backlog: its counts are read
            # once two fresh statuses agree on this topic (or after HANG_S)
            settle_until = time.monotonic() + HANG_S
            last, seen = diag.topic_total(topic), diag.count
            while time.monotonic() < settle_until and launcher.poll()[name] is None:
                diag.poll()
                if diag.count > seen:
                    total = diag.topic_total(topic)
                    if total == last and total > 0:
                        break
                    last, seen = total, diag.count
                time.sleep(0.05)
    finally:
        ticking.set()
        diag.poll()
        report.refusals = {k: int(v) for k, v in diag.values.items()
                           if not k.endswith(': accepted')}
        report.accepted = {k[: -len(': accepted')]: int(v) for k, v in diag.values.items()
                           if k.endswith(': accepted')}
        codes = launcher.stop()
        report.exit_code = codes.get(name)
        if (not report.crashed and report.exit_code not in (0, None)
                and name not in launcher.escalated):
            report.crashed = True
        if name in launcher.escalated:
            report.hung = True
        for w in writers:
            dds.delete(w)
        dds.delete(clock)
        diag.close()
        log.seek(0)
        report.log_tail = log.read()[-4000:]
        log.close()
    return report
