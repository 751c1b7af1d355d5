"""The Foxglove live view (live_view.py) during a graph run: a WebSocket client speaking the
Foxglove protocol gets every topic as a ros2msg/cdr channel and decodes an Image, a PointCloud2, a
MarkerArray, /tf and robot_description; the shipped layout (config/foxglove_layout.json) is what
foxglove_layout.py writes and names only topics the graph serves.

Its memory (issue 28 item 1): a client that stops reading is held to CLIENT_BACKLOG messages, the
newest, instead of 1024 (a VGA image each: 0.9 GB per client); of the frames a reader has queued
only the newest is passed on; a reading client stays connected while many topics appear at once
(each is an advertisement, and the control outbox is as small as the data one).

Older viewers (issue 29 item 7): a client offering only the subprotocol's old name
foxglove.websocket.v1 (Foxglove Studio 1.x, Lichtblick before December 2025) is served through the
view's relay (ws_relay.py) instead of HTTP 400; a plain HTTP request gets a clear 426."""

from __future__ import annotations

import json
import socket
import struct
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from vizzy_runtime import dds, msgs
from vizzy_runtime.convert import image_to_numpy, numpy_to_image
from vizzy_runtime.foxglove_layout import LAYOUT_FILE, layout_json, topics_named
from vizzy_runtime.launcher import Launcher, default_graph_file, load_graph
from vizzy_runtime.live_view import CLIENT_BACKLOG, LiveView, to_send
from vizzy_runtime.testing import STOP_GRACE_S, scaled, wait_until
from vizzy_runtime.ws_relay import RELAY_CHUNK, UPSTREAM_RCVBUF, rewrite_request, rewrite_response

sys.path.insert(0, str(Path(__file__).resolve().parent))
from foxglove_client import OLD_SUBPROTOCOL, SUBPROTOCOL, RawClient, collect  # noqa: E402

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
        assert wait_until(lambda: view.sent[topic] > before, scaled(30)), (
            f'image {seq} not passed on')

    try:
        assert wait_until(lambda: topic in view.channels, scaled(60)), (
            'the image topic was not served')
        client = RawClient(port, rcvbuf=STALLED_RCVBUF)
        client.sock.settimeout(scaled(60))
        client.subscribe(topic)
        assert wait_until(lambda: writer.matched_count() >= 1, scaled(60)), 'the view never read it'
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
    # beyond the SDK's outbox: the kernel's buffers between the SDK and the client, which through
    # the view's relay are two send buffers, the relay's capped receive buffer and one chunk
    kernel = 2 * _tcp_send_buffer_max() + 2 * UPSTREAM_RCVBUF + RELAY_CHUNK + 2 * STALLED_RCVBUF
    bound = (CLIENT_BACKLOG + 1) * len(base) + kernel
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
    client.sock.settimeout(scaled(60))
    try:
        client.frame()  # serverInfo: connected before the topics appear
        endpoints.extend(dds.Endpoint(t, 'std_msgs/msg/String', dds.QoS(), t.encode(), b'peer',
                                      True) for t in topics)
        while not set(topics) <= set(client.channels):
            client.frame()  # ConnectionError if the server disconnected us
    finally:
        client.close()
        view.stop()


def test_the_relay_renames_only_a_request_offering_just_the_old_name() -> None:
    head = (b'GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\n'
            b'sec-websocket-protocol: foxglove.websocket.v1\r\nX-Other: 1')
    new, renamed = rewrite_request(head)
    assert renamed and new.endswith(b'\r\nSec-WebSocket-Protocol: foxglove.sdk.v1')
    assert b'foxglove.websocket.v1' not in new and b'X-Other: 1' in new
    both = head.replace(b'websocket.v1', b'websocket.v1, foxglove.sdk.v1')
    assert rewrite_request(both) == (both, False)                  # the SDK picks foxglove.sdk.v1
    other = head.replace(b'foxglove.websocket.v1', b'chat')
    assert rewrite_request(other) == (other, False)                # the SDK's own answer (400)
    answer = b'HTTP/1.1 101 Switching Protocols\r\nsec-websocket-protocol: foxglove.sdk.v1'
    assert rewrite_response(answer).endswith(b'\r\nsec-websocket-protocol: foxglove.websocket.v1')


@pytest.fixture
def string_view() -> Iterator[tuple[LiveView, str]]:
    """A live view with one String topic published through DDS (a latched sample)."""
    topic = '/live_view_test/old_viewer'
    writer = dds.RawWriter(topic, 'std_msgs/msg/String',
                           dds.QoS(reliable=True, transient_local=True, depth=1))
    msg = msgs.get_message('std_msgs/msg/String')(data='hello old viewer')
    writer.write(bytes(msgs.serialize(msg, 'std_msgs/msg/String')))
    view = LiveView(port=0)
    view.start()
    try:
        assert wait_until(lambda: topic in view.channels, scaled(60)), 'the topic was not served'
        yield view, topic
    finally:
        view.stop()
        dds.delete(writer)


@pytest.mark.parametrize('offer, chosen', [
    ((OLD_SUBPROTOCOL,), OLD_SUBPROTOCOL),                  # Foxglove Studio 1.x, old Lichtblick
    ((OLD_SUBPROTOCOL, SUBPROTOCOL), SUBPROTOCOL),
    ((SUBPROTOCOL,), SUBPROTOCOL),                          # the Foxglove app, new Lichtblick
])
def test_a_viewer_offering_either_name_gets_server_info_channels_and_messages(
        string_view: tuple[LiveView, str], offer: tuple[str, ...], chosen: str) -> None:
    """Before the relay, foxglove-sdk answered HTTP 400 to a client offering only
    foxglove.websocket.v1. A WebSocket client library (which fails a handshake naming a protocol
    it did not offer) now gets serverInfo, the advertisement and the message."""
    view, topic = string_view
    session = collect(view.url, {topic}, timeout=scaled(60), subprotocols=offer)
    assert session.subprotocol == chosen
    assert session.server_info.get('name') == 'vizzy'
    assert session.channels[topic]['schemaName'] == 'std_msgs/msg/String'
    assert topic in session.first, f'no message on {topic}'
    assert msgs.deserialize(session.first[topic], 'std_msgs/msg/String').data == 'hello old viewer'


def test_an_old_name_client_on_a_raw_socket_reads_frames_through_the_relay(
        string_view: tuple[LiveView, str]) -> None:
    view, topic = string_view
    client = RawClient(view.port, subprotocols=(OLD_SUBPROTOCOL,))
    client.sock.settimeout(scaled(60))
    try:
        assert client.subprotocol == OLD_SUBPROTOCOL
        opcode, payload = client.frame()
        assert opcode == 1 and json.loads(payload)['op'] == 'serverInfo'
        client.subscribe(topic)
        _sub, data = client.data()
        assert msgs.deserialize(data, 'std_msgs/msg/String').data == 'hello old viewer'
    finally:
        client.close()


def test_a_plain_http_request_gets_a_clear_answer(string_view: tuple[LiveView, str]) -> None:
    """The SDK closes a non-upgrade request without a word; the view says what it is."""
    view, _topic = string_view
    with socket.create_connection(('127.0.0.1', view.port), timeout=scaled(30)) as sock:
        sock.sendall(b'GET / HTTP/1.1\r\nHost: x\r\n\r\n')
        answer = b''
        while chunk := sock.recv(4096):
            answer += chunk
    assert answer.startswith(b'HTTP/1.1 426 Upgrade Required\r\n')
    assert b'Foxglove WebSocket' in answer


# on the real tier the nodes run on the real rclpy (Fast DDS); the view on Cyclone
@pytest.mark.slow
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
        wait_until(lambda: layout_topics | set(DECODED) <= set(view.channels), scaled(120))
        session = collect(f'ws://127.0.0.1:{port}', set(DECODED), timeout=scaled(120))
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
