"""Bags across vendors: the bundled `vizzy bag record` records a graph running on the real rclpy
(rmw_fastrtps_cpp), and nodes on the real rclpy consume the bundled `vizzy bag play`."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vizzy_runtime import msgs
from vizzy_runtime.bag import BagReader, bag_info
from vizzy_runtime.testing import real_rclpy_python, repo_root, scaled

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mixed_support import (  # noqa: E402
    Flow,
    expect_clean_real_exit,
    graph_subset,
    real_launch,
    stop_all,
    wait_state,
)

pytestmark = pytest.mark.slow  # real-rclpy processes and a bag played in another

VIZZY = [sys.executable, '-m', 'vizzy_runtime.cli']   # the bundled runtime's CLI (.venv)
# what the sim and the gaze controller publish, each recorded and decoded
RECORDED = {
    '/clock': 'rosgraph_msgs/msg/Clock',
    '/joint_states': 'sensor_msgs/msg/JointState',
    '/tf': 'tf2_msgs/msg/TFMessage',
    '/tf_static': 'tf2_msgs/msg/TFMessage',                 # latched (transient local)
    '/gaze/state': 'active_vision_msgs/msg/GazeState',
    # reliable (REP 2003), 921,600 bytes each
    '/vizzy/left/image_raw': 'sensor_msgs/msg/Image',
    '/vizzy/right/image_raw': 'sensor_msgs/msg/Image',
    '/vizzy/left/camera_info': 'sensor_msgs/msg/CameraInfo',
}


def test_bundled_bag_record_records_a_real_rclpy_graph(tmp_path):
    real_rclpy_python()  # skips without .venv-ros
    real = real_launch(graph_subset(tmp_path / 'real.yaml', ['sim', 'gaze_controller']),
                       tmp_path / 'real.log')
    bag = tmp_path / 'bag'
    try:
        # the graph is up (the sim publishes) before recording starts
        flow = Flow(['/clock', '/gaze/state', '/vizzy/left/image_raw'])
        up = wait_state(lambda: flow.all_heard() or not real.alive(), scaled(120))
        assert up and real.alive(), f'the real graph did not come up: {flow.counts}\n{real.log()}'
        rec = subprocess.run([*VIZZY, 'bag', 'record', '-a', '-o', str(bag), '-d', '10',
                              '--exclude-topics', '/vizzy/rgbd/points'],
                             capture_output=True, text=True, timeout=scaled(120))
        assert rec.returncode == 0, rec.stderr[-3000:]
        flow.close()
    finally:
        code = real.stop()
    expect_clean_real_exit(code, real.log(100000), 'the real sim + gaze_controller')

    reader = BagReader(bag)
    topics = reader.topics
    assert '/vizzy/rgbd/points' not in topics
    seen: dict[str, int] = {}
    first: dict[str, object] = {}
    for msg in reader.messages():
        seen[msg.topic] = seen.get(msg.topic, 0) + 1
        if msg.topic in RECORDED and msg.topic not in first:
            first[msg.topic] = msgs.deserialize(msg.data, msg.typename)
    missing = {t for t in RECORDED if not seen.get(t)}
    assert not missing, f'nothing on {sorted(missing)}: {seen}\n{rec.stdout}\n{rec.stderr[-2000:]}'
    for topic, typename in RECORDED.items():
        assert topics[topic].type == typename, (topic, topics[topic].type)
    assert all(topics[t].message_count == n for t, n in seen.items()), (topics, seen)
    # decoded, with the sim's content
    image = first['/vizzy/left/image_raw']
    assert (image.width, image.height, image.encoding) == (640, 480, 'rgb8')
    assert len(image.data) == 640 * 480 * 3 and np.asarray(image.data).any()
    assert len(first['/joint_states'].name) == len(first['/joint_states'].position) > 0
    frames = {t.child_frame_id for t in first['/tf_static'].transforms}
    assert frames, 'no static transforms recorded'
    assert first['/gaze/state'].header.frame_id
    # the recording's own summary and `vizzy bag info` agree with the bag
    assert '/gaze/state:' in rec.stdout
    info = bag_info(bag)
    assert '/vizzy/left/image_raw' in info and 'sensor_msgs/msg/Image' in info


def _stamps(bag: Path, topic: str) -> set[tuple[int, int]]:
    return {(m.header.stamp.sec, m.header.stamp.nanosec)
            for m in (msgs.deserialize(r.data, r.typename)
                      for r in BagReader(bag).messages([topic]))}


def test_real_rclpy_foveation_consumes_bundled_bag_play(tmp_path):
    real_rclpy_python()
    bag = repo_root() / 'bags' / 'tabletop'
    real = real_launch(graph_subset(tmp_path / 'real.yaml', ['foveation']), tmp_path / 'real.log')
    flow = Flow(['/foveation/image'], decode=['/foveation/image'])
    player = None
    try:
        # the real foveation node subscribes to the camera before the bag plays
        def subscribed() -> bool:
            flow.poll()
            return any(not ep.is_writer and ep.topic == '/vizzy/left/image_raw'
                       for ep in flow.disc.endpoints())
        assert wait_state(lambda: subscribed() or not real.alive(),
                          scaled(120)) and real.alive(), real.log()
        player = subprocess.Popen([*VIZZY, 'bag', 'play', str(bag), '-l'],
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        flowing = wait_state(
            lambda: flow.all_heard() or not real.alive() or player.poll() is not None, scaled(120))
        heard, alive, played = flow.counts['/foveation/image'], real.alive(), player.poll()
    finally:
        def stop_player() -> None:
            if player is not None and player.poll() is None:
                player.send_signal(signal.SIGINT)
                try:
                    player.wait(scaled(20))
                except subprocess.TimeoutExpired:
                    player.kill()
        codes: list = []
        stop_all(flow.close, stop_player, lambda: codes.append(real.stop()))
    out = player.stdout.read() if player is not None else ''
    assert alive and played is None, (
        f'foveation alive {alive}, player exit {played}: {out[-2000:]}\n{real.log()}')
    assert flowing and heard, (f'no /foveation/image from the played bag\n{out[-2000:]}\n'
                               f'{real.log()}')
    # foveated from the bag's images: it keeps their headers
    foveated = {(m.header.stamp.sec, m.header.stamp.nanosec)
                for m in flow.messages['/foveation/image']}
    assert foveated <= _stamps(bag, '/vizzy/left/image_raw'), foveated
    assert player.returncode == 0, out[-2000:]
    assert '/vizzy/left/image_raw:' in out        # the player's counts
    expect_clean_real_exit(codes[0], real.log(100000), 'the real foveation')
