"""Recording and playing over DDS (loopback, a random ROS_DOMAIN_ID per test module)."""

from __future__ import annotations

import os
import random
import signal
import statistics
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest

# Before the first dds.participant(): keep clear of other processes' domains.
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(100, 200)))

from vizzy_runtime import msgs  # noqa: E402
from vizzy_runtime.bag import BagReader, BagWriter, QosProfile, Recorder  # noqa: E402
from vizzy_runtime.testing import scaled

SRC = str(Path(__file__).resolve().parents[1])
T0 = 1_700_000_000_000_000_000
GAP_NS = 100_000_000  # 100 ms between recorded messages


def env() -> dict[str, str]:
    return {**os.environ, 'PYTHONPATH': SRC, 'ROS_DOMAIN_ID': os.environ['ROS_DOMAIN_ID']}


def bag_cli(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, '-m', 'vizzy_runtime.cli', 'bag', *args], env=env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for(condition: Callable[[], bool], timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f'timed out after {timeout} s waiting for {what}')
        time.sleep(0.02)


def wire(text: str) -> bytes:
    data = bytes(msgs.serialize(msgs.get_message('std_msgs/msg/String')(data=text),
                                'std_msgs/msg/String'))
    return data + b'\0' * (-len(data) % 4)  # as DDS delivers it


@pytest.mark.slow
def test_play_then_record_round_trip(tmp_path: Path) -> None:
    source, copy = tmp_path / 'source', tmp_path / 'copy'
    latched = QosProfile(durability='transient_local', depth=1)
    sent: dict[str, list[bytes]] = {'/talk': [], '/static': []}
    with BagWriter(source) as writer:
        writer.add_topic('/talk', 'std_msgs/msg/String', [QosProfile()])
        writer.add_topic('/static', 'std_msgs/msg/String', [latched])
        writer.write('/static', wire('static'), T0)
        sent['/static'].append(wire('static'))
        for i in range(10):
            data = wire(f'message {i} ' + 'x' * i)
            writer.write('/talk', data, T0 + (i + 1) * GAP_NS)
            sent['/talk'].append(data)

    recorder = bag_cli('record', '-o', str(copy), '/talk', '/static')
    try:
        player = bag_cli('play', str(source), '--rate', '2', '--wait-for-subscribers',
                         str(scaled(30)))
        out, err = player.communicate(timeout=scaled(90))
        assert player.returncode == 0, err
        assert 'no subscriber' not in err  # the recorder matched before the first message
        assert '/talk: 10' in out
    finally:
        recorder.send_signal(signal.SIGINT)  # Ctrl-C: the bag must be finalized
        out, err = recorder.communicate(timeout=scaled(60))
    assert recorder.returncode == 0, err
    assert (copy / 'metadata.yaml').exists()

    reader = BagReader(copy)
    got: dict[str, list[bytes]] = {'/talk': [], '/static': []}
    times: list[int] = []
    for msg in reader.messages():
        got[msg.topic].append(msg.data)
        if msg.topic == '/talk':
            times.append(msg.log_time_ns)
    assert got == sent  # byte for byte, in order
    assert reader.topics['/static'].offered_qos_profiles[0].durability == 'transient_local'
    assert reader.topics['/talk'].offered_qos_profiles[0].reliability == 'reliable'
    gaps = [(b - a) / 1e9 for a, b in zip(times, times[1:], strict=False)]
    # rate 2: 100 ms gaps become ~50 ms; generous bounds, but far from rate 1 (100 ms)
    assert 0.03 < statistics.median(gaps) < 0.075, gaps
    assert 0.3 < (times[-1] - times[0]) / 1e9 < 0.7, gaps


LATCHED_PUBLISHER = textwrap.dedent('''
    import sys
    from vizzy_runtime import dds, msgs
    String = msgs.get_message('std_msgs/msg/String')
    writer = dds.RawWriter('/latched', 'std_msgs/msg/String',
                           dds.QoS(reliable=True, transient_local=True, depth=1))
    writer.write(msgs.serialize(String(data='published before the recorder started')))
    print('published', flush=True)
    sys.stdin.read()  # keep the writer (and its latched sample) alive until stdin closes
''')


@pytest.mark.slow
def test_recorder_gets_latched_and_late_topics(tmp_path: Path) -> None:
    publisher = subprocess.Popen([sys.executable, '-c', LATCHED_PUBLISHER], env=env(),
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    recorder = Recorder(tmp_path / 'bag', discovery_interval=0.1)
    thread = threading.Thread(target=recorder.run, name='recorder')
    try:
        assert publisher.stdout is not None and publisher.stdout.readline() == 'published\n'
        thread.start()
        wait_for(lambda: recorder.counts.get('/latched', 0) == 1, 30, 'the latched message')
    finally:
        recorder.stop()
        thread.join(timeout=scaled(60))
        publisher.communicate(timeout=scaled(30))
    assert not thread.is_alive()
    reader = BagReader(tmp_path / 'bag')
    (msg,) = list(reader.messages(topics=['/latched']))
    assert msgs.deserialize(msg.data, 'std_msgs/msg/String').data == \
        'published before the recorder started'
    qos = reader.topics['/latched'].offered_qos_profiles[0]
    assert (qos.durability, qos.reliability, qos.depth) == ('transient_local', 'reliable', 1)


@pytest.mark.slow
@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_recorder_finalizes_on_signal_without_data(tmp_path: Path, sig: int) -> None:
    recorder = bag_cli('record', '-o', str(tmp_path / 'bag'), '/nothing_here')
    wait_for(lambda: (tmp_path / 'bag' / 'bag_0.mcap').exists(), 30, 'the recorder to start')
    recorder.send_signal(sig)
    _out, err = recorder.communicate(timeout=scaled(60))
    assert recorder.returncode == 0, err
    reader = BagReader(tmp_path / 'bag')
    assert reader.message_count == 0 and reader.topics == {}


def test_recorder_skips_excluded_topics(tmp_path):
    from vizzy_runtime import dds, msgs
    from vizzy_runtime.bag import BagReader, Recorder
    String = msgs.get_message('std_msgs/msg/String')
    keep = dds.RawWriter('/keep_me', 'std_msgs/msg/String', dds.QoS(transient_local=True, depth=1))
    drop = dds.RawWriter('/drop_me', 'std_msgs/msg/String', dds.QoS(transient_local=True, depth=1))
    keep.write(msgs.serialize(String(data='k')))
    drop.write(msgs.serialize(String(data='d')))
    recorder = Recorder(tmp_path / 'bag', ['/keep_me', '/drop_me'], exclude=['/drop_me'])
    import threading
    thread = threading.Thread(target=recorder.run, kwargs={'handle_signals': False})
    thread.start()
    wait_for(lambda: recorder.counts.get('/keep_me', 0) == 1, 20, 'the kept topic')
    recorder.stop()
    thread.join(scaled(20))
    assert set(BagReader(tmp_path / 'bag').topics) == {'/keep_me'}


FULL_DISK_RECORDER = textwrap.dedent('''
    import resource, signal, sys
    # past the limit, writes fail (EFBIG) as on a full disk; the limit leaves room for whole
    # chunks (1 MiB of the test's text compresses to about 0.6 MB: with a 600 KB limit only a
    # chunk flushed early by the 1 s flush interval fitted, so a fast machine kept nothing)
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (2_000_000, 2_000_000))
    from vizzy_runtime.cli import main
    sys.exit(main(sys.argv[1:]))
''')


@pytest.mark.slow
def test_a_full_disk_ends_recording_with_one_line_and_a_readable_bag(tmp_path: Path) -> None:
    from vizzy_runtime import dds
    writer = dds.RawWriter('/filler', 'std_msgs/msg/String', dds.QoS(reliable=True, depth=50))
    bag = tmp_path / 'bag'
    recorder = subprocess.Popen([sys.executable, '-c', FULL_DISK_RECORDER, 'bag', 'record', '-o',
                                 str(bag),
                                 '/filler'], env=env(), stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE,
                                text=True)
    try:
        wait_for(lambda: writer.matched_count() > 0 or recorder.poll() is not None, 30,
                 'the recorder')
        rng = random.Random(1)
        deadline = time.monotonic() + scaled(60)
        i = 0
        while recorder.poll() is None and time.monotonic() < deadline:  # incompressible text
            writer.write(wire(f'{i} '
                              + ''.join(rng.choice('abcdefghij0123456789') for _ in range(20_000))))
            i += 1
            time.sleep(0.002)
        _out, err = recorder.communicate(timeout=scaled(60))
    finally:
        if recorder.poll() is None:
            recorder.kill()
        writer = None     # its DDS writer goes now, not with a failure's traceback (later tests)
    lines = err.strip().splitlines()
    assert recorder.returncode == 2, err
    assert ('Traceback' not in err and lines[-1].startswith('vizzy: ')
            and 'File too large' in lines[-1]), err
    assert 'vizzy bag reindex' in lines[-1], err
    reader = BagReader(bag, repair=False)  # readable as it is, up to its last complete chunk
    got = [m.data for m in reader.messages()]
    assert got and all(d[8:].split(b' ', 1)[0].isdigit() for d in got)
