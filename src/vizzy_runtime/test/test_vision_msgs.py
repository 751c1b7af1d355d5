"""vision_msgs 4.1.1 (ROS 2 Jazzy) on both runtimes: the same type hashes as the released package.

The bundled runtime parses the .msg files vizzy_runtime ships (interfaces/vision_msgs/msg), and
.venv-ros builds its vision_msgs from the same files (scripts/gen_interfaces.py): a field that
differed from the release in name, type, order or bound would change the RIHS01 hash, and a ROS 2
peer with the real package would then see another type (rmw matches endpoints on the hash).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from vizzy_runtime import msgs

# The RIHS01 type hashes of the released vision_msgs 4.1.1 (the ROS 2 Jazzy release, apt
# ros-jazzy-vision-msgs). Obtained by building the upstream package itself (ros-perception/
# vision_msgs, tag 4.1.1, folder vision_msgs: `git archive 4.1.1 vision_msgs`) with cmake against
# the rosidl of the ROS 2 Jazzy wheels pinned in requirements-ros.txt (as scripts/setup_ros.sh
# builds our interface packages, into a scratch prefix) and reading `type_hashes` from the
# share/vision_msgs/msg/<Type>.json files rosidl wrote. Cross-checked: 12 of them
# (BoundingBox2D, BoundingBox2DArray, BoundingBox3D, Classification, Detection2DArray,
# Detection3D, LabelInfo, ObjectHypothesis, ObjectHypothesisWithPose, Point2D, Pose2D,
# VisionClass) equal the values in a third party's colcon build of vision_msgs published on
# GitHub (borednuna/ipm-ws, build/vision_msgs/rosidl_generator_type_description/*.json and
# detection2_d_array__description.c).
RELEASED_HASHES = {
    'vision_msgs/msg/BoundingBox2D':
        'RIHS01_008eacbb0cf8f26e83795547bed013eec3675485ef386ec056d80eaaf1c1ce2f',
    'vision_msgs/msg/BoundingBox2DArray':
        'RIHS01_2464e82838009386d371b523211c21c91d74d313fcdd6788223c531d621cf691',
    'vision_msgs/msg/BoundingBox3D':
        'RIHS01_bbb73a65c163d7f9bb29009c7bde9f7faa576bd2d23299c4511d19230dab4698',
    'vision_msgs/msg/BoundingBox3DArray':
        'RIHS01_a81938db9576b10c2eecd7c5a5da3eac496efd00221b25ed051dfbc81fb56da6',
    'vision_msgs/msg/Classification':
        'RIHS01_f74db28d0eaef3afb78f48bf2161cd709a1383a0309d3454383b25be11345143',
    'vision_msgs/msg/Detection2D':
        'RIHS01_0d12b69df5c593b3455b7346fac8205437a7d4bcb09b9e0e0b2dde787ded38ea',
    'vision_msgs/msg/Detection2DArray':
        'RIHS01_214274120007f4a683866481336b70310268cfa107aebe9d594a6acf75bda968',
    'vision_msgs/msg/Detection3D':
        'RIHS01_ddd703be132ab0b69d33121f1bb034132bfbb3b0ac5f9fb1516005ba1c8a265b',
    'vision_msgs/msg/Detection3DArray':
        'RIHS01_793f5eab9595ac1c0da07873cc859db42eae51f0ee76056db8562515d830e018',
    'vision_msgs/msg/LabelInfo':
        'RIHS01_3d37df4015cdf660cc851c51897f2acd957e1ca6205ba0a99aebffb9406b0783',
    'vision_msgs/msg/ObjectHypothesis':
        'RIHS01_51da43cec11c01957a64d1e05a24acd18aae7745ec30b74348ad5f6d634f7f90',
    'vision_msgs/msg/ObjectHypothesisWithPose':
        'RIHS01_41c12344c0396c48b81df12467c192d99b2a0eb1463c5c37194e4223251c80bc',
    'vision_msgs/msg/Point2D':
        'RIHS01_eab0e83f44ab4de92ceaf76dd7d0e7638f2bdd1d16ffbe16c7a136c48e407247',
    'vision_msgs/msg/Pose2D':
        'RIHS01_b0b5d1d7b4c20dd4fcde3ed1d4b289a919290572007d67a97043814db25d3648',
    'vision_msgs/msg/VisionClass':
        'RIHS01_1e4a11f0fed50b5623cb8ff26ca0e37952a48a9c074d16f804b44e9164c2037a',
    'vision_msgs/msg/VisionInfo':
        'RIHS01_95d3116a17484ad91c9a2686e1d54890bbfc3ff6c6a2de137738c4950d45d284',
}


# --- the bundled runtime ------------------------------------------------------------------------

def test_bundled_runtime_has_the_released_types_and_hashes() -> None:
    reg = msgs.registry()
    assert reg.bundled == sorted(RELEASED_HASHES)
    got = {name: reg.store.hash_rihs01(name) for name in RELEASED_HASHES}
    assert got == RELEASED_HASHES


def test_wire_names_and_user_data_carry_the_released_hash() -> None:
    from vizzy_runtime import dds

    name = 'vision_msgs/msg/Detection2DArray'
    assert msgs.dds_type_name(name) == 'vision_msgs::msg::dds_::Detection2DArray_'
    assert dds.type_hash_user_data(name) == f'typehash={RELEASED_HASHES[name]};'.encode()
    assert {f.name for f in dds.idl_type(name).__dataclass_fields__.values()} == \
        {'header', 'detections'}


def _detection_3d_array():
    Detection3DArray = msgs.get_message('vision_msgs/msg/Detection3DArray')
    Detection3D = msgs.get_message('vision_msgs/msg/Detection3D')
    Hypothesis = msgs.get_message('vision_msgs/msg/ObjectHypothesisWithPose')
    out = Detection3DArray()
    out.header.frame_id = 'base_link'
    out.header.stamp.sec, out.header.stamp.nanosec = 12, 345
    for i, (label, score) in enumerate([('cup', 0.875), ('box', 0.5)]):
        det = Detection3D(id=f'obj{i}')
        det.header = out.header
        hyp = Hypothesis()
        hyp.hypothesis.class_id, hyp.hypothesis.score = label, score
        hyp.pose.pose.position.x = 0.25 * (i + 1)
        hyp.pose.covariance = np.arange(36, dtype=np.float64) * (i + 1)
        det.results.append(hyp)
        det.bbox.center.position.x, det.bbox.center.position.z = 0.4, 0.8 + i
        det.bbox.center.orientation.z, det.bbox.center.orientation.w = 0.6, 0.8
        det.bbox.size.x, det.bbox.size.y, det.bbox.size.z = 0.1, 0.2, 0.3 + i
        out.detections.append(det)
    return out


def _detection_2d_array():
    Detection2DArray = msgs.get_message('vision_msgs/msg/Detection2DArray')
    Detection2D = msgs.get_message('vision_msgs/msg/Detection2D')
    Hypothesis = msgs.get_message('vision_msgs/msg/ObjectHypothesisWithPose')
    out = Detection2DArray()
    out.header.frame_id = 'left_camera_optical_frame'
    out.header.stamp.sec = 7
    det = Detection2D()
    det.header = out.header
    for label, score in [('red', 0.75), ('green', 0.125)]:
        hyp = Hypothesis()
        hyp.hypothesis.class_id, hyp.hypothesis.score = label, score
        det.results.append(hyp)
    det.bbox.center.position.x, det.bbox.center.position.y = 259.5, 60.0
    det.bbox.center.theta = 0.0
    det.bbox.size_x, det.bbox.size_y = 24.0, 25.0
    out.detections.append(det)
    return out


def test_detection_arrays_round_trip_through_cdr() -> None:
    for typename, msg in [('vision_msgs/msg/Detection3DArray', _detection_3d_array()),
                          ('vision_msgs/msg/Detection2DArray', _detection_2d_array())]:
        back = msgs.deserialize(bytes(msgs.serialize(msg, typename)), typename)
        assert back == msg
        assert back.header.frame_id == msg.header.frame_id

    back3 = msgs.deserialize(bytes(msgs.serialize(_detection_3d_array())),
                             'vision_msgs/msg/Detection3DArray')
    assert back3.header.stamp.sec == 12 and back3.header.stamp.nanosec == 345
    assert [d.id for d in back3.detections] == ['obj0', 'obj1']
    second = back3.detections[1]
    assert second.results[0].hypothesis.class_id == 'box'
    assert second.results[0].hypothesis.score == 0.5
    np.testing.assert_array_equal(second.results[0].pose.covariance, np.arange(36) * 2.0)
    assert second.results[0].pose.pose.orientation.w == 1.0     # the default quaternion
    assert (second.bbox.size.x, second.bbox.size.y, second.bbox.size.z) == (0.1, 0.2, 1.3)
    assert (second.bbox.center.orientation.z, second.bbox.center.orientation.w) == (0.6, 0.8)

    back2 = msgs.deserialize(bytes(msgs.serialize(_detection_2d_array())),
                             'vision_msgs/msg/Detection2DArray')
    det = back2.detections[0]
    assert [(r.hypothesis.class_id, r.hypothesis.score) for r in det.results] == \
        [('red', 0.75), ('green', 0.125)]
    assert (det.bbox.center.position.x, det.bbox.center.position.y) == (259.5, 60.0)
    assert (det.bbox.size_x, det.bbox.size_y) == (24.0, 25.0)
    assert det.id == '' and det.header.stamp.sec == 7


def test_a_bag_carries_the_released_hash_and_a_usable_definition(tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    from vizzy_runtime.bag import BagWriter, QosProfile

    name = 'vision_msgs/msg/Detection3DArray'
    data = bytes(msgs.serialize(_detection_3d_array()))
    with BagWriter(tmp_path / 'bag') as writer:
        writer.add_topic('/objects', name, [QosProfile()])
        writer.write('/objects', data + b'\0' * (-len(data) % 4), 1_000, 1_000)
    with Reader(tmp_path / 'bag') as reader:
        assert [c.digest for c in reader.connections] == [RELEASED_HASHES[name]]
    # a reader that has never heard of vision_msgs decodes it from the bag's own definition
    store = get_typestore(Stores.ROS2_JAZZY)
    assert name not in store.fielddefs
    with AnyReader([tmp_path / 'bag'], default_typestore=store) as reader:
        (conn, _, raw), = list(reader.messages())
        back = reader.deserialize(raw, conn.msgtype)
    assert [d.id for d in back.detections] == ['obj0', 'obj1']
    assert back.detections[0].results[0].hypothesis.class_id == 'cup'
    assert back.detections[1].bbox.size.z == 1.3


def test_bundled_definitions_and_an_unknown_package() -> None:
    texts = msgs.bundled_msg_texts('vision_msgs')
    assert sorted(texts) == sorted(RELEASED_HASHES)
    with pytest.raises(ValueError, match="no bundled interface package 'foo_msgs'"):
        msgs.bundled_msg_texts('foo_msgs')


# --- the real rclpy (the real-rclpy tier: .venv-ros, or apt ROS 2 with vision_msgs) -------------

@pytest.mark.live
def test_real_vision_msgs_have_the_released_hashes(request: pytest.FixtureRequest) -> None:
    from vizzy_runtime.ros import USING_REAL_ROS, Node, message

    if not USING_REAL_ROS:
        pytest.skip('checks the real rclpy\'s vision_msgs: runs on the real-rclpy tier '
                    '(scripts/test_ros.sh: .venv-ros, VIZZY_RUNTIME=ros); this run is on the '
                    'bundled runtime')
    # the hash rmw puts on an endpoint: the generated type support's, as a ROS 2 peer sees it
    context = request.getfixturevalue('context')
    node = Node('vision_msgs_hashes', context=context, start_parameter_services=False)
    try:
        got = {}
        for i, name in enumerate(sorted(RELEASED_HASHES)):
            node.create_publisher(message(name), f'type_{i}', 1)
            infos = node.get_publishers_info_by_topic(f'/type_{i}')
            assert [info.topic_type for info in infos] == [name]
            got[name] = str(infos[0].topic_type_hash)
    finally:
        node.destroy_node()
    assert got == RELEASED_HASHES
    # and the type descriptions rosidl installed with the imported package: <prefix>/share/
    # vision_msgs/msg/*.json beside <prefix>/lib/pythonX.Y/site-packages/vision_msgs
    import vision_msgs

    share = Path(vision_msgs.__file__).resolve().parents[4] / 'share' / 'vision_msgs' / 'msg'
    assert share.is_dir(), f'no rosidl type descriptions at {share}'
    installed = {}
    for name in RELEASED_HASHES:
        description = json.loads((share / f'{name.rsplit("/", 1)[1]}.json').read_text())
        installed[name] = next(h['hash_string'] for h in description['type_hashes']
                               if h['type_name'] == name)
    assert installed == RELEASED_HASHES
