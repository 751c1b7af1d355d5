"""rosbag2 bags without ROS: format, interoperability with rosbags / mcap, recovery, errors."""

from __future__ import annotations

import logging
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import Reader as RosbagsReader
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as RosbagsWriter

from vizzy_runtime import msgs
from vizzy_runtime.bag import BagError, BagReader, BagWriter, Player, QosProfile, bag_info, reindex
from vizzy_runtime.bag.common import INFINITE_NS, parse_qos_profiles
from vizzy_runtime.bag.play import ensure_type, offer_qos
from vizzy_runtime.testing import scaled

SRC = str(Path(__file__).resolve().parents[1])
T0 = 1_700_000_000_000_000_000
Sample = tuple[str, str, bytes, int, int]  # topic, type, cdr, log time, publish time


def wire(msg: object, typename: str) -> bytes:
    """CDR as it arrives from DDS (padded to 4 bytes)."""
    data = bytes(msgs.serialize(msg, typename))
    return data + b'\0' * (-len(data) % 4)


def sample_messages() -> list[Sample]:
    """(topic, type, cdr, log_time, publish_time) on three topics, in log-time order."""
    String = msgs.get_message('std_msgs/msg/String')
    Pose = msgs.get_message('geometry_msgs/msg/PoseStamped')
    ours = msgs.registry().ours[0]
    Ours = msgs.get_message(ours)
    out = []
    for i in range(30):
        t = T0 + i * 10_000_000
        out.append(('/chatter', 'std_msgs/msg/String', wire(String(data=f'hello {i}'),
                                                            'std_msgs/msg/String'), t, t - 5))
        if i % 3 == 0:
            pose = Pose()
            pose.pose.position.x = float(i)
            pose.header.frame_id = 'base'
            out.append(('/pose', 'geometry_msgs/msg/PoseStamped',
                        wire(pose, 'geometry_msgs/msg/PoseStamped'), t + 1, t - 7))
        if i % 10 == 0:
            out.append(('/ours', ours, wire(Ours(), ours), t + 2, t + 2))
    return out


LATCHED = QosProfile(depth=1, durability='transient_local')


def write_bag(path: Path, messages: list[Sample], **kwargs: object) -> None:
    with BagWriter(path, **kwargs) as writer:  # type: ignore[arg-type]
        for topic, typename, *_ in messages:
            qos = [LATCHED] if topic == '/ours' else [QosProfile(reliability='best_effort')]
            writer.add_topic(topic, typename, qos)
        for topic, _typename, data, log_ns, pub_ns in messages:
            writer.write(topic, data, log_ns, pub_ns)


def by_time(messages: list[Sample]) -> list[Sample]:
    return sorted(messages, key=lambda m: m[3])


# --- our writer, read by others -------------------------------------------------------------------

def test_ours_read_by_rosbags_and_mcap(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    expected = sample_messages()
    write_bag(bag, expected, chunk_size=2048)

    with AnyReader([bag], default_typestore=msgs.registry().store) as reader:
        got = [(c.topic, c.msgtype, bytes(raw), t) for c, t, raw in reader.messages()]
        for conn, _t, raw in reader.messages(connections=reader.connections[:1]):
            reader.deserialize(raw, conn.msgtype)  # definitions in the bag are usable
    assert got == [(m[0], m[1], m[2], m[3]) for m in by_time(expected)]

    with RosbagsReader(bag) as reader:
        conns = {c.topic: c for c in reader.connections}
        assert reader.message_count == len(expected)
        assert conns['/pose'].digest == msgs.registry().store.hash_rihs01(
            'geometry_msgs/msg/PoseStamped')
        qos = conns['/ours'].ext.offered_qos_profiles[0]
        assert qos.durability == QosDurability.TRANSIENT_LOCAL and qos.depth == 1

    with open(bag / 'bag_0.mcap', 'rb') as f:
        mcap = make_reader(f, validate_crcs=True)
        assert mcap.get_header().profile == 'ros2'
        summary = mcap.get_summary()
        assert summary is not None and summary.statistics is not None
        assert summary.statistics.message_count == len(expected)
        assert len(summary.chunk_indexes) > 1
        assert {ci.compression for ci in summary.chunk_indexes} == {'zstd'}
        schemas = {s.name: s for s in summary.schemas.values()}
        assert {s.encoding for s in schemas.values()} == {'ros2msg'}
        assert schemas['geometry_msgs/msg/PoseStamped'].data.decode() == \
            msgs.message_definition('geometry_msgs/msg/PoseStamped')
        for channel in summary.channels.values():
            assert channel.message_encoding == 'cdr'
            assert channel.metadata['topic_type_hash'].startswith('RIHS01_')
            assert yaml.safe_load(channel.metadata['offered_qos_profiles'])[0]['history'] \
                == 'keep_last'
        datas = [(ch.topic, m.data, m.log_time, m.publish_time)
                 for _s, ch, m in mcap.iter_messages(log_time_order=True)]
        assert datas == [(m[0], m[2], m[3], m[4]) for m in by_time(expected)]
        rosbag2_meta = [m for m in mcap.iter_metadata() if m.name == 'rosbag2']
        assert yaml.safe_load(rosbag2_meta[0].metadata['serialized_metadata'])['version'] == 9


ROSBAG2_TOP_KEYS = ['version', 'storage_identifier', 'duration', 'starting_time', 'message_count',
                    'topics_with_message_count', 'compression_format', 'compression_mode',
                    'relative_file_paths', 'files', 'custom_data', 'ros_distro']
ROSBAG2_QOS_KEYS = ['history', 'depth', 'reliability', 'durability', 'deadline', 'lifespan',
                    'liveliness', 'liveliness_lease_duration', 'avoid_ros_namespace_conventions']


def test_metadata_yaml_is_rosbag2_v9(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    expected = sample_messages()
    write_bag(bag, expected)
    text = (bag / 'metadata.yaml').read_text()
    info = yaml.safe_load(text)['rosbag2_bagfile_information']
    assert list(info) == ROSBAG2_TOP_KEYS
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    assert info['ros_distro'] == 'jazzy'
    assert info['compression_format'] == '' and info['compression_mode'] == ''
    assert info['custom_data'] is None
    assert info['relative_file_paths'] == ['bag_0.mcap']
    assert info['message_count'] == len(expected)
    assert info['starting_time'] == {'nanoseconds_since_epoch': T0}
    assert info['duration'] == {'nanoseconds': max(m[3] for m in expected) - T0}
    assert list(info['files'][0]) == ['path', 'starting_time', 'duration', 'message_count']
    topics = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    assert list(topics['/pose']) == ['topic_metadata', 'message_count']
    meta = topics['/pose']['topic_metadata']
    assert list(meta) == ['name', 'type', 'serialization_format', 'offered_qos_profiles',
                          'type_description_hash']
    assert meta['serialization_format'] == 'cdr'
    assert topics['/pose']['message_count'] == sum(m[0] == '/pose' for m in expected)
    qos = meta['offered_qos_profiles'][0]
    assert list(qos) == ROSBAG2_QOS_KEYS
    assert qos['reliability'] == 'best_effort' and qos['history'] == 'keep_last'
    assert qos['deadline'] == {'sec': 9223372036, 'nsec': 854775807}
    # yaml-cpp's emission style, as in rosbag2's own test resources
    assert 'compression_format: ""' in text and 'custom_data: ~' in text
    assert '\n    - topic_metadata:\n' in text


def test_qos_profiles_parse_all_versions() -> None:
    v8 = ('- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n'
          '    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 10\n    nsec: 0\n'
          '  liveliness: 1\n  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n'
          '  avoid_ros_namespace_conventions: false')
    (p,) = parse_qos_profiles(v8)
    assert (p.history, p.reliability, p.durability, p.liveliness) == \
        ('unknown', 'reliable', 'volatile', 'automatic')
    assert p.deadline_ns == INFINITE_NS and p.lifespan_ns == 10_000_000_000
    assert p.to_dds().lifespan_ns == 10_000_000_000 and p.to_dds().deadline_ns is None
    assert parse_qos_profiles('') == [] and parse_qos_profiles([]) == []
    assert parse_qos_profiles([LATCHED.to_dict()]) == [LATCHED]
    assert QosProfile.from_dds(LATCHED.to_dds()) == LATCHED
    assert offer_qos([LATCHED]).durability == 'transient_local'
    assert offer_qos([LATCHED]).depth == 10
    assert offer_qos([LATCHED, QosProfile()]) == QosProfile()  # mixed offers -> defaults


# --- others' bags, read by us ---------------------------------------------------------------------

@pytest.mark.parametrize('plugin', [StoragePlugin.MCAP, StoragePlugin.SQLITE3])
def test_read_rosbags_written_bag(tmp_path: Path, plugin: StoragePlugin) -> None:
    bag = tmp_path / 'theirs'
    expected = sample_messages()
    qos = Qos(QosHistory.KEEP_LAST, 5, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
              QosTime(0, 0), QosTime(0, 0), QosLiveliness.AUTOMATIC, QosTime(0, 0), False)
    with RosbagsWriter(bag, version=9, storage_plugin=plugin) as writer:
        conns = {}
        for topic, typename, *_ in expected:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, typename,
                                                     typestore=msgs.registry().store,
                                                     offered_qos_profiles=[qos])
        for topic, _typename, data, log_ns, _pub in expected:
            writer.write(conns[topic], log_ns, data)

    reader = BagReader(bag)
    assert reader.storage_identifier == plugin.name.lower()
    assert reader.message_count == len(expected)
    pose = reader.topics['/pose']
    assert pose.type == 'geometry_msgs/msg/PoseStamped'
    assert pose.message_count == sum(m[0] == '/pose' for m in expected)
    assert pose.offered_qos_profiles[0].durability == 'transient_local'
    assert pose.offered_qos_profiles[0].depth == 5
    got = [(m.topic, m.typename, m.data, m.log_time_ns) for m in reader.messages()]
    assert got == [(m[0], m[1], m[2], m[3]) for m in by_time(expected)]
    only = list(reader.messages(topics=['/ours']))
    assert [m.data for m in only] == [m[2] for m in expected if m[0] == '/ours']
    assert 'ros2msg' in {enc for enc, _text in reader.definitions().values()}
    assert 'Topic: /pose | Type: geometry_msgs/msg/PoseStamped' in bag_info(bag)


def test_time_order_filter_and_range(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    with BagWriter(bag, chunk_size=256) as writer:  # many chunks, overlapping in time
        writer.add_topic('/a', 'std_msgs/msg/String')
        writer.add_topic('/b', 'std_msgs/msg/String')
        for i in range(50):
            writer.write('/a', b'\0\1\0\0' + bytes(8), T0 + (49 - i) * 2)
            writer.write('/b', b'\0\1\0\0' + bytes(8), T0 + i * 2 + 1)
    reader = BagReader(bag)
    times = [m.log_time_ns for m in reader.messages()]
    assert times == sorted(times) and len(times) == 100
    assert {m.topic for m in reader.messages(topics=['/b'])} == {'/b'}
    window = [m.log_time_ns for m in reader.messages(start_ns=T0 + 10, stop_ns=T0 + 20)]
    assert window == list(range(T0 + 10, T0 + 20))
    assert reader.end_time_ns == T0 + 99 and reader.start_time_ns == T0


def test_bag_info_text(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_bag(bag, sample_messages())
    lines = bag_info(bag).splitlines()
    assert lines[0] == 'Files:             bag_0.mcap'
    assert lines[2] == 'Storage id:        mcap'
    assert lines[3] == 'ROS Distro:        jazzy'
    assert lines[4] == 'Duration:          0.290000000s'
    assert lines[7] == f'Messages:          {len(sample_messages())}'
    assert lines[8] == ('Topic information: Topic: /chatter | Type: std_msgs/msg/String | '
                        'Count: 30 | Serialization Format: cdr')
    assert lines[9].startswith(' ' * 19 + 'Topic: /ours | Type: active_vision_msgs/msg/')


# --- killed recordings ----------------------------------------------------------------------------

KILLED_WRITER = textwrap.dedent('''
    import sys, time
    from vizzy_runtime.bag import BagWriter
    writer = BagWriter(sys.argv[1], flush_interval=1e9)   # chunks only when told
    writer.add_topic('/count', 'std_msgs/msg/UInt32')
    n = 0
    for chunk in range(int(sys.argv[2])):
        for _ in range(7):
            writer.write('/count', b'\\0\\1\\0\\0' + n.to_bytes(4, 'little'), 1000 + n, 500 + n)
            n += 1
        writer.flush()
        print(n, flush=True)
    writer.write('/count', b'\\0\\1\\0\\0' + n.to_bytes(4, 'little'), 1000 + n)  # never flushed
    print('waiting', flush=True)
    time.sleep(600)
''')


@pytest.mark.slow
def test_sigkilled_writer_is_recovered(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    bag = tmp_path / 'killed'
    proc = subprocess.Popen([sys.executable, '-c', KILLED_WRITER, str(bag), '4'],
                            stdout=subprocess.PIPE, text=True,
                            env={**os.environ, 'PYTHONPATH': SRC})
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline().strip() for _ in range(5)]
        assert lines == ['7', '14', '21', '28', 'waiting']
    finally:
        proc.kill()  # SIGKILL: no summary, no footer, no metadata.yaml
        proc.wait(timeout=scaled(30))
    assert not (bag / 'metadata.yaml').exists()

    with caplog.at_level(logging.WARNING, logger='vizzy_runtime.bag'):
        reader = BagReader(bag)
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and str(bag / 'killed_0.mcap') in warnings[0]
    assert 'recovered 28 messages from 4 complete chunks' in warnings[0]
    got = list(reader.messages())
    assert [int.from_bytes(m.data[4:], 'little') for m in got] == list(range(28))
    assert [(m.log_time_ns, m.publish_time_ns) for m in got[:2]] == [(1000, 500), (1001, 501)]
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['message_count'] == 28 and info['version'] == 9
    assert info['topics_with_message_count'][0]['topic_metadata']['type'] == 'std_msgs/msg/UInt32'
    with RosbagsReader(bag) as theirs:  # the file was finished, so others read it too
        assert [t for _c, t, _d in theirs.messages()] == [1000 + i for i in range(28)]
    caplog.clear()
    BagReader(bag)  # repaired once: no warning the second time
    assert not caplog.records


def test_file_cut_inside_a_chunk(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    bag = tmp_path / 'cut'
    expected = sample_messages()
    write_bag(bag, expected, chunk_size=1024)
    file = bag / 'cut_0.mcap'
    with open(file, 'rb') as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) >= 3
    third = chunks[2]
    with open(file, 'r+b') as f:  # as if killed while writing the third chunk
        f.truncate(third.chunk_start_offset + third.chunk_length // 2)
    (bag / 'metadata.yaml').unlink()
    before = [m for m in by_time(expected) if m[3] <= chunks[1].message_end_time]
    with caplog.at_level(logging.WARNING, logger='vizzy_runtime.bag'):
        got = list(BagReader(bag).messages())
    assert [(m.topic, m.data) for m in got] == [(m[0], m[2]) for m in before]
    assert 'incomplete chunk record' in caplog.records[0].getMessage()
    assert reindex(bag).message_count == len(before)


def test_bag_info_never_writes(tmp_path: Path) -> None:
    """`bag info` on a killed recording reports it unfinished and leaves every byte as it was;
    only `bag reindex` repairs."""
    bag = tmp_path / 'cut'
    write_bag(bag, sample_messages(), chunk_size=1024)
    file = bag / 'cut_0.mcap'
    with open(file, 'rb') as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    with open(file, 'r+b') as f:
        f.truncate(chunks[2].chunk_start_offset + chunks[2].chunk_length // 2)
    (bag / 'metadata.yaml').unlink()
    before = {p.name: p.read_bytes() for p in bag.iterdir()}
    text = bag_info(bag)
    assert {p.name: p.read_bytes() for p in bag.iterdir()} == before
    assert 'Unfinished:        cut_0.mcap' in text and 'vizzy bag reindex' in text, text
    counted = int(re.search(r'Messages: +(\d+)', text).group(1))
    assert counted == reindex(bag).message_count > 0
    assert 'Unfinished' not in bag_info(bag)


def test_bag_being_recorded_is_read_not_repaired(tmp_path: Path) -> None:
    bag = tmp_path / 'live'
    writer = BagWriter(bag, flush_interval=1e9)
    writer.add_topic('/a', 'std_msgs/msg/String')
    for i in range(5):
        writer.write('/a', b'\0\1\0\0' + bytes(8), T0 + i)
    writer.flush()
    writer.write('/a', b'\0\1\0\0' + bytes(8), T0 + 99)  # not flushed yet
    size = (bag / 'live_0.mcap').stat().st_size
    reader = BagReader(bag)
    assert [m.log_time_ns for m in reader.messages()] == [T0 + i for i in range(5)]
    assert (bag / 'live_0.mcap').stat().st_size == size and not (bag / 'metadata.yaml').exists()
    writer.close()
    assert BagReader(bag).message_count == 6


# --- errors ---------------------------------------------------------------------------------------

def test_bad_inputs_raise_bag_error(tmp_path: Path) -> None:
    def error(fn: object, *args: object, **kwargs: object) -> str:
        with pytest.raises(BagError) as info:
            fn(*args, **kwargs)  # type: ignore[operator]
        message = str(info.value)
        assert '\n' not in message
        return message

    assert 'no such bag directory' in error(BagReader, tmp_path / 'missing')
    (tmp_path / 'file.txt').write_text('x')
    assert 'not a bag directory' in error(BagReader, tmp_path / 'file.txt')
    (tmp_path / 'empty').mkdir()
    assert 'not a rosbag2 bag' in error(BagReader, tmp_path / 'empty')
    assert 'not a rosbag2 bag' in error(bag_info, tmp_path / 'empty')

    junk = tmp_path / 'junk'
    junk.mkdir()
    (junk / 'junk_0.mcap').write_bytes(b'this is not an mcap file at all')
    assert 'not an MCAP file' in error(BagReader, junk)
    (junk / 'metadata.yaml').write_text('rosbag2_bagfile_information: [1, 2')
    assert 'metadata.yaml: not a valid rosbag2 metadata file' in error(BagReader, junk)

    bag = tmp_path / 'bag'
    write_bag(bag, sample_messages())
    assert 'already exists' in error(BagWriter, bag)
    assert "no topic(s) /nope in the bag" in error(Player, bag, topics=['/nope'])
    data = bytearray((bag / 'bag_0.mcap').read_bytes())
    with open(bag / 'bag_0.mcap', 'rb') as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunk = summary.chunk_indexes[0]
    middle = chunk.chunk_start_offset + chunk.chunk_length // 2
    data[middle:middle + 16] = bytes(16)  # damage compressed data inside a finished file
    (bag / 'bag_0.mcap').write_bytes(bytes(data))
    damaged = BagReader(bag)  # not an error: that chunk is skipped (test_bag_corrupt.py)
    assert list(damaged.messages()) == [] and len(damaged.corrupt_chunks) == 1

    with BagWriter(tmp_path / 'new') as writer:
        assert "unknown message type 'foo_msgs/msg/Nope'" in error(
            writer.add_topic, '/x', 'foo_msgs/msg/Nope')
        writer.add_topic('/x', 'std_msgs/msg/String')
        assert 'already recorded as std_msgs/msg/String' in error(
            writer.add_topic, '/x', 'std_msgs/msg/Bool')
        assert 'before add_topic' in error(writer.write, '/y', b'', 0)
    assert 'unknown message type' in error(ensure_type, 'foo_msgs/msg/Nope', {})
    missing_file = tmp_path / 'nofile'
    missing_file.mkdir()
    (missing_file / 'metadata.yaml').write_text((bag / 'metadata.yaml').read_text())
    assert 'missing storage file' in error(BagReader, missing_file)


def test_unknown_type_is_taken_from_the_bag(tmp_path: Path) -> None:
    text = ('int32 answer\nstd_msgs/Header header\n' + '=' * 80 + '\nMSG: std_msgs/Header\n'
            + msgs.message_definition('std_msgs/msg/Header'))
    typename = 'bagonly_msgs/msg/Answer'
    ensure_type(typename, {typename: ('ros2msg', text)})
    Answer = msgs.get_message(typename)
    assert Answer(answer=42).answer == 42
