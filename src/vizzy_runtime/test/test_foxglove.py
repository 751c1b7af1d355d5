"""The Foxglove live view (live_view.py) during a graph run: a WebSocket client speaking the
Foxglove protocol gets every topic as a ros2msg/cdr channel and decodes an Image, a PointCloud2, a
MarkerArray, /tf and robot_description; the shipped layout (config/foxglove_layout.json) is what
foxglove_layout.py writes and names only topics the graph serves."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from vizzy_runtime import msgs
from vizzy_runtime.convert import image_to_numpy
from vizzy_runtime.foxglove_layout import LAYOUT_FILE, layout_json, topics_named
from vizzy_runtime.launcher import Launcher, default_graph_file, load_graph
from vizzy_runtime.live_view import LiveView
from vizzy_runtime.testing import STOP_GRACE_S, wait_until

sys.path.insert(0, str(Path(__file__).resolve().parent))
from foxglove_client import collect  # noqa: E402

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
