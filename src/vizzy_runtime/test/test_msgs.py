"""Message classes and CDR: our bytes must be exactly what ROS 2's DDS middlewares send.

Cyclone DDS's own (independent, element-by-element) XCDR1 serializer is the reference: for every
message type the graph uses, ours and the bundled vision_msgs included, random contents serialize
byte-identically.
"""

import random

import numpy as np
import pytest
from rosbags.interfaces import Nodetype

from vizzy_runtime import dds, msgs

GRAPH_TYPES = [
    'std_msgs/msg/String', 'std_msgs/msg/Header', 'builtin_interfaces/msg/Time',
    'sensor_msgs/msg/Image', 'sensor_msgs/msg/CompressedImage', 'sensor_msgs/msg/CameraInfo',
    'sensor_msgs/msg/PointCloud2', 'sensor_msgs/msg/JointState', 'sensor_msgs/msg/RegionOfInterest',
    'tf2_msgs/msg/TFMessage', 'rosgraph_msgs/msg/Clock', 'geometry_msgs/msg/PointStamped',
    'visualization_msgs/msg/MarkerArray', 'rcl_interfaces/msg/ParameterEvent',
    'rmw_dds_common/msg/ParticipantEntitiesInfo',
]
OURS = msgs.registry().ours
# vision_msgs (shipped definitions): /foveation/detections_2d, /objects and the rest of the package
BUNDLED = msgs.registry().bundled

_NP = {'bool': np.bool_, 'byte': np.int8, 'char': np.uint8, 'int8': np.int8, 'uint8': np.uint8,
       'int16': np.int16, 'uint16': np.uint16, 'int32': np.int32, 'uint32': np.uint32,
       'int64': np.int64, 'uint64': np.uint64, 'float32': np.float32, 'float64': np.float64}


def _scalar(rng: random.Random, name: str):
    if name in ('string', 'bounded_string'):
        return ''.join(rng.choice('abcxyz_/é') for _ in range(rng.randint(0, 9)))
    if name == 'bool':
        return rng.random() < 0.5
    if name.startswith('float'):
        return float(np.float32(rng.uniform(-1e3, 1e3)))
    if name == 'byte':  # octet: rosbags decodes it as int8, Cyclone wants 0..255; agree on 0..127
        return rng.randint(0, 127)
    info = np.iinfo(_NP[name])
    return rng.randint(int(info.min), int(info.max))


def random_message(typename: str, rng: random.Random):
    """Fill every field of a message with random values of the right type."""
    cls = msgs.get_message(typename)
    values = {}
    for fname, desc in msgs.registry().fields(typename):
        values[fname] = _random_field(desc, rng)
    return cls(**values)


def _random_field(desc, rng):
    kind, rest = desc
    if kind == Nodetype.BASE:
        name, bound = rest
        value = _scalar(rng, name)
        return value[:bound] if bound and isinstance(value, str) else value
    if kind == Nodetype.NAME:
        return random_message(rest, rng)
    sub, length = rest
    n = length if kind == Nodetype.ARRAY else rng.randint(0, min(length or 4, 4))
    if sub[0] == Nodetype.BASE and sub[1][0] in _NP:
        return np.array([_scalar(rng, sub[1][0]) for _ in range(n)], dtype=_NP[sub[1][0]])
    return [_random_field(sub, rng) for _ in range(n)]


def to_cyclone(msg, typename: str):
    """The same content as an instance of Cyclone's IdlStruct for the type."""
    cls = dds.idl_type(typename)
    kwargs = {}
    for fname, desc in msgs.registry().fields(typename):
        kwargs[fname] = _to_cyclone_field(getattr(msg, fname), desc)
    return cls(**kwargs)


def _to_cyclone_field(value, desc):
    kind, rest = desc
    if kind == Nodetype.NAME:
        return to_cyclone(value, rest)
    if kind == Nodetype.BASE:
        return value
    sub = rest[0]
    return [_to_cyclone_field(v.item() if isinstance(v, np.generic) else v, sub) for v in value]


@pytest.mark.parametrize('typename', GRAPH_TYPES + OURS + BUNDLED)
def test_cdr_identical_to_cyclone(typename):
    rng = random.Random(typename)
    for _ in range(5):
        msg = random_message(typename, rng)
        ours = bytes(msgs.serialize(msg, typename))
        theirs = to_cyclone(msg, typename).serialize(use_version_2=False)
        assert ours[:4] == b'\x00\x01\x00\x00'  # XCDR1 little endian, as ROS 2 sends
        assert ours == theirs
        back = msgs.deserialize(ours, typename)
        assert back == msg


def test_our_interfaces_are_loaded():
    expected = {'GazeCommand', 'GazeState', 'FoveatedDetection', 'FoveatedDetectionArray',
                'Cylinder', 'CylinderArray', 'Track', 'TrackArray', 'AttentionRegions',
                'MapObject', 'MapObjectArray'}
    assert {t.split('/')[-1] for t in OURS} >= expected


def test_classes_behave_like_rclpy_messages():
    Image = msgs.get_message('sensor_msgs/msg/Image')
    img = Image(width=4, encoding='rgb8')
    assert img.height == 0 and img.header.frame_id == '' and img.data.dtype == np.uint8
    assert img.data.size == 0
    CameraInfo = msgs.get_message('sensor_msgs/msg/CameraInfo')
    assert CameraInfo().k.shape == (9,)
    with pytest.raises(TypeError, match='no field'):
        Image(nonsense=1)
    with pytest.raises(AttributeError):
        img.nonsense = 1  # slots: a typo is an error, as in rclpy


def test_deserialized_arrays_are_views_not_copies():
    Image = msgs.get_message('sensor_msgs/msg/Image')
    raw = msgs.serialize(Image(height=1, width=3, encoding='mono8', step=3,
                               data=np.arange(3, dtype=np.uint8)))
    back = msgs.deserialize(raw, 'sensor_msgs/msg/Image')
    assert back.data.base is not None and list(back.data) == [0, 1, 2]


def test_names():
    assert msgs.dds_type_name('sensor_msgs/msg/Image') == 'sensor_msgs::msg::dds_::Image_'
    assert (msgs.ros_type_from_dds('active_vision_msgs::msg::dds_::GazeState_')
            == 'active_vision_msgs/msg/GazeState')
    assert msgs.normalize_type_name('std_msgs/String') == 'std_msgs/msg/String'
    with pytest.raises(ValueError):
        msgs.normalize_type_name('nonsense')
    with pytest.raises(KeyError, match='unknown message type'):
        msgs.get_message('nope_msgs/msg/Nope')


def test_malformed_cdr_is_a_clear_error():
    from rosbags.serde import SerdeError
    with pytest.raises(SerdeError):
        msgs.deserialize(b'\x00\x01\x00\x00\xff\xff', 'sensor_msgs/msg/Image')


def test_array_fields_accept_what_rclpy_accepts():
    JointState = msgs.get_message('sensor_msgs/msg/JointState')
    js = JointState(name=['neck_pan_joint'], position=[0.5])
    assert js.position.dtype == np.float64 and js.position[0] == 0.5
    Image = msgs.get_message('sensor_msgs/msg/Image')
    assert list(Image(data=b'\x01\x02').data) == [1, 2]
    CameraInfo = msgs.get_message('sensor_msgs/msg/CameraInfo')
    with pytest.raises(ValueError, match='exactly 9 elements'):
        CameraInfo(k=[1.0, 2.0])
    assert msgs.get_message('geometry_msgs/msg/Quaternion')().w == 1.0  # upstream default
    raw = msgs.serialize(js)
    assert msgs.deserialize(raw, 'sensor_msgs/msg/JointState') == js


def test_constructors_are_generated_with_a_parameter_per_field():
    """rosbags' deserializer builds every (nested) message through the constructor (a TFMessage
    of 5 transforms: 31 of them), so each type gets its own (issue 27): the fields by name."""
    import inspect
    Vector3 = msgs.get_message('geometry_msgs/msg/Vector3')
    assert list(inspect.signature(Vector3).parameters)[:3] == ['x', 'y', 'z']
    assert Vector3(1.0, z=3.0) == Vector3(x=1.0, y=0.0, z=3.0)
    assert Vector3(1.0, None, 3.0).y == 0.0       # None: the default, by position or by name
    with pytest.raises(TypeError, match='at most 3 positional'):
        Vector3(1.0, 2.0, 3.0, 4.0)
    with pytest.raises(TypeError, match=r"no field\(s\) \['w'\]"):
        Vector3(w=1.0)
    JointState = msgs.get_message('sensor_msgs/msg/JointState')
    js = JointState(name=['a'], position=[1.5])
    assert js.position.dtype == np.float64 and js.velocity.size == 0 and js.header.frame_id == ''
    assert JointState() is not JointState() and JointState().name is not JointState().name
