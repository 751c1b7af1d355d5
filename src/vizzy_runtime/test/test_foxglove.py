"""The Foxglove live view (live_view.py) during a graph run: a WebSocket client speaking the
Foxglove protocol gets every topic as a ros2msg/cdr channel and decodes an Image, a PointCloud2, a
MarkerArray, /tf and robot_description; the shipped layout (config/foxglove_layout.json) is what
foxglove_layout.py writes and names only topics the graph serves.

Its memory (issue 28 item 1): a client that stops reading is held to CLIENT_BACKLOG messages, the
newest, instead of 1024 (a VGA image each: 0.9 GB per client); of the frames a reader has queued
only the newest is passed on; a reading client stays connected while many topics appear at once
(each is an advertisement, and the control outbox is as small as the data one)."""

from __future__ import annotations

import json
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from vizzy_runtime import dds, msgs
from vizzy_runtime.convert import image_to_numpy, numpy_to_image
from vizzy_runtime.foxglove_layout import LAYOUT_FILE, layout_json, topics_named
from vizzy_runtime.launcher import Launcher, default_graph_file, load_graph
from vizzy_runtime.live_view import CLIENT_BACKLOG, LiveView, to_send
from vizzy_runtime.testing import STOP_GRACE_S, wait_until

sys.path.insert(0, str(Path(__file__).resolve().parent))
from foxglove_client import RawClient, collect  # noqa: E402

DECODED = {
    '/vizzy/left/image_raw': 'sensor_msgs/msg/Image',
    '/stereo/points': 'sensor_msgs/msg/PointCloud2',
    '/sim/ground_truth/objects': 'visualization_msgs/msg/MarkerArray',
    '/tf': 'tf2_msgs/msg/TFMessage',
    '/robot_description': 'std_msgs/msg/String',
}


def test_the_layout_file_is_the_generated_one() -> None:
    assert LAYOUT_FILE.read_text() == layout_json(), \
        'config/foxglove_layout.json is stale: python -m vizzy_runtime.foxglove_layout -o it'


def test_a_bad_port_is_one_clear_error() -> None:
    view = LiveView(port=70000)
    with pytest.raises(OverflowError):  # the port does not fit 16 bits
        view.start()
    view.stop()


IMAGE = 'sensor_msgs/msg/Image'
STALLED_RCVBUF = 4096   # the stalled client's receive buffer (the kernel doubles it)


def _tcp_send_buffer_max() -> int:
    """What the kernel may hold in a server socket's send buffer (net.ipv4.tcp_wmem's maximum)."""
    try:
        return int(Path('/proc/sys/net/ipv4/tcp_wmem').read_text().split()[2])
    except (OSError, IndexError, ValueError):
        return 4 << 20   # Linux's default


def test_of_frames_only_the_newest_of_a_take_is_sent_of_other_topics_all() -> None:
    takes = [(b'old', 1), (b'mid', 2), (b'new', 3)]
    assert to_send(takes, IMAGE) == [b'new']
    assert to_send(takes, 'sensor_msgs/msg/PointCloud2') == [b'new']
    assert to_send(takes, 'tf2_msgs/msg/TFMessage') == [b'old', b'mid', b'new']  # parts of a state
    assert to_send([], IMAGE) == []


def test_a_client_that_stops_reading_is_held_to_the_newest_backlog() -> None:
    """A VGA image stream to a client that stops reading: of the images published meanwhile the
    server holds (and, once the client reads again, delivers) at most CLIENT_BACKLOG, the newest,
    plus the one being written and what the kernel's socket buffers took."""
    topic = '/live_view_test/stalled_image'
    frame = np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)
    base = bytes(msgs.serialize(numpy_to_image(frame, 'rgb8'), IMAGE))
    stalled, last = 3 * CLIENT_BACKLOG, 3 * CLIENT_BACKLOG + 1   # images 1..stalled, then a marker
    writer = dds.RawWriter(topic, IMAGE, dds.QoS(reliable=True, depth=10))
    view = LiveView(port=0)
    port = view.start()
    client = None

    def publish(seq: int) -> None:
        """Image `seq` (its stamp's seconds) through DDS, waiting until the view passed it on."""
        data = bytearray(base)
        struct.pack_into('<i', data, 4, seq)  # header.stamp.sec, after the CDR header
        before = view.sent[topic]
        writer.write(data)
        assert wait_until(lambda: view.sent[topic] > before, 30), f'image {seq} not passed on'

    try:
        assert wait_until(lambda: topic in view.channels, 60), 'the image topic was not served'
        client = RawClient(port, rcvbuf=STALLED_RCVBUF)
        client.sock.settimeout(60)
        client.subscribe(topic)
        assert wait_until(lambda: writer.matched_count() >= 1, 60), 'the view never read it'
        publish(0)
        assert struct.unpack_from('<i', client.data()[1], 4)[0] == 0  # it flows; now stop reading
        for seq in range(1, last + 1):
            publish(seq)
        got: list[int] = []          # what the server held for the client meanwhile, in order
        while True:
            _sub, payload = client.data()
            seq = struct.unpack_from('<i', payload, 4)[0]
            if seq == last:
                break
            got.append(seq)
    finally:
        if client is not None:
            client.close()
        view.stop()
        dds.delete(writer)
    held = len(got) * len(base)
    bound = (CLIENT_BACKLOG + 1) * len(base) + _tcp_send_buffer_max() + 2 * STALLED_RCVBUF
    assert held <= bound, (f'{len(got)} of {stalled} images ({held / 1e6:.0f} MB) were held for a '
                           f'client that stopped reading; bound {bound / 1e6:.0f} MB')
    # the newest win: the last CLIENT_BACKLOG - 1 images before the marker all arrive, in order
    newest = list(range(last - CLIENT_BACKLOG + 1, last))
    assert got[-len(newest):] == newest, got


def test_a_reading_client_stays_connected_while_many_topics_appear(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Three backlogs' worth of topics appearing in one discovery pass: each is an advertisement to
    every client, and the control outbox (CLIENT_BACKLOG) disconnects a client when full."""
    endpoints: list[dds.Endpoint] = []

    class Discovery:
        def endpoints(self) -> list[dds.Endpoint]:
            return list(endpoints)

    monkeypatch.setattr(dds, 'Discovery', Discovery)
    topics = [f'/live_view_test/many_{i:02d}' for i in range(3 * CLIENT_BACKLOG)]
    view = LiveView(port=0)
    port = view.start()
    client = RawClient(port)
    client.sock.settimeout(60)
    try:
        client.frame()  # serverInfo: connected before the topics appear
        endpoints.extend(dds.Endpoint(t, 'std_msgs/msg/String', dds.QoS(), t.encode(), b'peer',
                                      True) for t in topics)
        while not set(topics) <= set(client.channels):
            client.frame()  # ConnectionError if the server disconnected us
    finally:
        client.close()
        view.stop()


# on the real tier the nodes run on the real rclpy (Fast DDS); the view on Cyclone
@pytest.mark.live
def test_foxglove_client_decodes_the_graph(tmp_path: Path) -> None:
    log = open(tmp_path / 'launch.log', 'w+')  # noqa: SIM115 - the launcher's log
    launcher = Launcher(load_graph(default_graph_file()), output=log,
                        grace_s=STOP_GRACE_S)
    view = LiveView(port=0)
    port = view.start()
    try:
        launcher.start()
        layout_topics = topics_named(json.loads(LAYOUT_FILE.read_text()))
        wait_until(lambda: layout_topics | set(DECODED) <= set(view.channels), 120)
        session = collect(f'ws://127.0.0.1:{port}', set(DECODED), timeout=120)
    finally:
        launcher.stop()
        view.stop()
        log.seek(0)
        text = log.read()
    missing = set(DECODED) - set(session.first)
    assert not missing, (f'no message on {missing}; channels {sorted(session.channels)}; '
                         f'log:\n{text[-2000:]}')
    for topic, typename in DECODED.items():
        ch = session.channels[topic]
        assert ((ch['schemaName'], ch['schemaEncoding'], ch['encoding'])
                == (typename, 'ros2msg', 'cdr'))
        assert ch['schema'] == msgs.message_definition(typename)
    # what the Foxglove app would decode, decoded here from the bytes the client received
    image = msgs.deserialize(session.first['/vizzy/left/image_raw'],
                             DECODED['/vizzy/left/image_raw'])
    pixels = image_to_numpy(image)
    assert pixels.shape[:2] == (image.height, image.width) and pixels.std() > 0
    cloud = msgs.deserialize(session.first['/stereo/points'], DECODED['/stereo/points'])
    assert {'x', 'y', 'z', 'information'} <= {f.name for f in cloud.fields}
    markers = msgs.deserialize(session.first['/sim/ground_truth/objects'],
                               DECODED['/sim/ground_truth/objects'])
    assert markers.markers and all(np.isfinite(m.pose.position.x) for m in markers.markers)
    tf = msgs.deserialize(session.first['/tf'], DECODED['/tf'])
    assert tf.transforms and all(t.header.frame_id and t.child_frame_id for t in tf.transforms)
    urdf = msgs.deserialize(session.first['/robot_description'], DECODED['/robot_description'])
    assert urdf.data.lstrip().startswith('<') and '<robot' in urdf.data
    # the shipped layout names only topics the graph serves
    assert layout_topics <= set(view.channels), layout_topics - set(view.channels)
