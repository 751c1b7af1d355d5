"""Issue 29 item 2: `vizzy bag play --clock [HZ] --remap FROM:=TO --start-offset S` and the
progress line, as ros2 bag play has them (loopback, a random ROS_DOMAIN_ID unless one is set)."""

from __future__ import annotations

import io
import os
import random
import re
import threading
from pathlib import Path

import pytest

os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(100, 200)))

from vizzy_runtime import cli, dds, msgs  # noqa: E402
from vizzy_runtime.bag import BagWriter, Player, QosProfile  # noqa: E402
from vizzy_runtime.bag.play import DEFAULT_CLOCK_HZ, parse_remaps  # noqa: E402
from vizzy_runtime.testing import scaled, wait_until  # noqa: E402

T0 = 1_700_000_000_000_000_000
GAP_NS = 100_000_000       # 10 messages, 100 ms apart
BAG_CLOCK_SEC = 42         # the bag's own /clock says this: never played with --clock


def wire(msg: object, typename: str) -> bytes:
    data = bytes(msgs.serialize(msg, typename))
    return data + b'\0' * (-len(data) % 4)


def make_bag(path: Path) -> list[bytes]:
    String = msgs.get_message('std_msgs/msg/String')
    Clock = msgs.get_message('rosgraph_msgs/msg/Clock')
    sent = []
    with BagWriter(path) as writer:
        writer.add_topic('/chatter', 'std_msgs/msg/String', [QosProfile()])
        writer.add_topic('/clock', 'rosgraph_msgs/msg/Clock',
                         [QosProfile(reliability='best_effort', depth=1)])
        for i in range(10):
            data = wire(String(data=f'message {i}'), 'std_msgs/msg/String')
            writer.write('/chatter', data, T0 + i * GAP_NS)
            sent.append(data)
            clock = Clock()
            clock.clock.sec = BAG_CLOCK_SEC
            writer.write('/clock', wire(clock, 'rosgraph_msgs/msg/Clock'), T0 + i * GAP_NS + 1)
    return sent


def test_clock_remap_and_start_offset(tmp_path: Path) -> None:
    sent = make_bag(tmp_path / 'bag')
    replayed = dds.RawReader('/replayed', 'std_msgs/msg/String', dds.QoS(depth=100))
    chatter = dds.RawReader('/chatter', 'std_msgs/msg/String', dds.QoS(depth=100))
    clock = dds.RawReader('/clock', 'rosgraph_msgs/msg/Clock', dds.QoS(reliable=False, depth=1000))
    player = Player(tmp_path / 'bag', remap={'/chatter': '/replayed'}, start_offset=0.45,
                    clock_hz=100.0, wait_for_subscribers=60.0)
    assert [t.name for t in player.topics] == ['/chatter']   # the bag's /clock is left out
    counts: dict[str, int] = {}
    thread = threading.Thread(target=lambda: counts.update(player.run(handle_signals=False)))
    try:
        thread.start()
        thread.join(scaled(120))
        assert not thread.is_alive()
        got: list[bytes] = []
        ticks: list[int] = []

        def all_in() -> bool:
            got.extend(bytes(d) for d, _ in replayed.take(100))
            for raw, _ in clock.take(1000):
                c = msgs.deserialize(raw, 'rosgraph_msgs/msg/Clock').clock
                ticks.append(c.sec * 10**9 + c.nanosec)
            return len(got) >= 5
        assert wait_until(all_in, scaled(30)), got
        assert counts == {'/replayed': 5}
        assert got == sent[5:]          # the messages from 0.45 s on, under the new name
        assert chatter.take(100) == []  # nothing on the old name
        # /clock: the bag's time as played, from start + offset, never going back; not the
        # bag's own /clock (sec 42)
        assert len(ticks) >= 2, ticks
        assert ticks == sorted(ticks)
        assert all(T0 + 450_000_000 <= t <= T0 + 9 * GAP_NS for t in ticks), ticks
    finally:
        player.stop()
        for reader in (replayed, chatter, clock):
            dds.delete(reader)


def test_progress_line_is_rosbag2_s_on_one_line(tmp_path: Path) -> None:
    make_bag(tmp_path / 'bag')
    stream = io.StringIO()
    counts = Player(tmp_path / 'bag', topics=['/chatter'], rate=50.0, progress_hz=-1,
                    progress_stream=stream).run(handle_signals=False)
    assert counts == {'/chatter': 10}
    text = stream.getvalue()
    assert text.endswith('\n') and text.count('\n') == 1   # one line, redrawn with \r
    updates = [u.rstrip() for u in text.strip('\n').split('\r') if u]
    assert all(re.fullmatch(r'\[\d{10}\.\d{9}\] Duration \d+\.\d\d/0\.90 \[R\]', u)
               for u in updates), updates
    assert updates[-1] == '[1700000000.900000001] Duration 0.90/0.90 [R]'   # the bag's end
    assert len(updates) >= 10        # every message, with a negative rate
    quiet = io.StringIO()
    Player(tmp_path / 'bag', rate=50.0, progress_hz=0, progress_stream=quiet).run(
        handle_signals=False)
    assert quiet.getvalue() == ''


def test_play_flags_parse_as_ros2_bag_play() -> None:
    parse = cli.build_parser().parse_args
    ns = parse(['bag', 'play', 'b', '--clock'])
    assert ns.clock == DEFAULT_CLOCK_HZ == 40.0 and ns.start_offset == 0.0
    ns = parse(['bag', 'play', 'b', '--clock', '100', '-m', '/a:=/b', 'c:=d',
                '--start-offset', '2.5'])
    assert ns.clock == 100.0 and ns.start_offset == 2.5
    assert parse_remaps(ns.remap) == {'/a': '/b', '/c': '/d'}
    assert parse(['bag', 'play', 'b']).clock == 0.0       # no /clock unless asked
    for bad in (['x'], ['/a:='], ['__node:=x']):
        with pytest.raises(ValueError, match='--remap'):
            parse_remaps(bad)
