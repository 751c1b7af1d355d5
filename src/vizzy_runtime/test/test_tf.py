"""vizzy_runtime.tf: composing transforms, clear errors, and the /tf + /tf_static listener."""

from __future__ import annotations

import math
import uuid
from typing import Any

import numpy as np
import pytest

from vizzy_runtime.rclpy_compat.executors import SingleThreadedExecutor
from vizzy_runtime.rclpy_compat.node import Node
from vizzy_runtime.ros import message, qos_profile_latched
from vizzy_runtime.testing import wait_until
from vizzy_runtime.tf import TransformBuffer, TransformListener
from vizzy_vision.frames import matrices_from_transforms, quaternions_to_matrices

TFMessage = message('tf2_msgs/msg/TFMessage')
TransformStamped = message('geometry_msgs/msg/TransformStamped')


def random_pose(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return matrices_from_transforms(rng.normal(size=3), q)[0]


def stamped(parent: str, child: str, pose: np.ndarray) -> Any:
    """A TransformStamped for a 4x4 pose (quaternion from the rotation matrix)."""
    r = pose[:3, :3]
    w = math.sqrt(max(0.0, 1.0 + np.trace(r))) / 2.0
    if w > 1e-6:
        x, y, z = (r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w), \
            (r[1, 0] - r[0, 1]) / (4 * w)
    else:  # a half turn: not needed by these tests
        raise ValueError('rotation too close to a half turn for this helper')
    msg = TransformStamped(child_frame_id=child)
    msg.header.frame_id = parent
    t = msg.transform
    t.translation.x, t.translation.y, t.translation.z = (float(v) for v in pose[:3, 3])
    t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w = float(x), float(y), float(z), float(w)
    return msg


def test_quaternions_become_rotation_matrices() -> None:
    half = math.sqrt(0.5)
    r = quaternions_to_matrices(np.array([[0, 0, 0, 1], [0, 0, half, half], [2, 0, 0, 0]]))
    np.testing.assert_allclose(r[0], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(r[1], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)  # z +90 deg
    np.testing.assert_allclose(r[2], np.diag([1, -1, -1]), atol=1e-15)  # normalized first
    rng = np.random.default_rng(1)
    rs = quaternions_to_matrices(rng.normal(size=(100, 4)))
    np.testing.assert_allclose(rs @ rs.transpose(0, 2, 1), np.broadcast_to(np.eye(3), rs.shape),
                               atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(rs), 1.0)
    with pytest.raises(ValueError, match='invalid rotation'):
        quaternions_to_matrices(np.zeros((1, 4)))
    with pytest.raises(ValueError, match='non-finite translation'):
        matrices_from_transforms([[0.0, math.nan, 0.0]], [[0, 0, 0, 1]])


def test_lookup_composes_chains_and_branches() -> None:
    rng = np.random.default_rng(7)
    # base -> a -> b -> c and base -> d -> e (two branches)
    edges = {'a': 'base', 'b': 'a', 'c': 'b', 'd': 'base', 'e': 'd'}
    local = {child: random_pose(rng) for child in edges}
    buffer = TransformBuffer()
    buffer.set_transforms(list(edges.values()), list(edges), np.stack(list(local.values())))

    def in_base(frame: str) -> np.ndarray:
        pose = np.eye(4)
        while frame != 'base':
            pose = local[frame] @ pose
            frame = edges[frame]
        return pose

    frames = ['base', *edges]
    for target in frames:
        for source in frames:
            expected = np.linalg.inv(in_base(target)) @ in_base(source)
            np.testing.assert_allclose(buffer.lookup_transform(target, source), expected,
                                       atol=1e-12, err_msg=f'{source} in {target}')
    assert buffer.all_frames() == set(frames)
    assert buffer.parent('c') == 'b' and buffer.parent('base') is None
    # points: (N, 3) in source -> target, and a single point
    pts = rng.normal(size=(50, 3))
    m = buffer.lookup_transform('e', 'c')
    np.testing.assert_allclose(buffer.transform_points('e', 'c', pts),
                               (m[:3, :3] @ pts.T).T + m[:3, 3], atol=1e-12)
    np.testing.assert_allclose(buffer.transform_points('e', 'c', pts[0]),
                               buffer.transform_points('e', 'c', pts)[0])
    # tf2 ignores a leading slash
    np.testing.assert_allclose(buffer.lookup_transform('/base', 'c'),
                               buffer.lookup_transform('base', 'c'))


def test_unknown_and_disconnected_frames_raise_naming_them() -> None:
    buffer = TransformBuffer()
    with pytest.raises(LookupError, match="frames 'camera' and 'base_link' are not in the tf "
                                          "tree.*known frames: none yet"):
        buffer.lookup_transform('base_link', 'camera')
    buffer.set_transform('base_link', 'head', np.eye(4))
    with pytest.raises(LookupError, match="frame 'camera' is not in the tf tree") as err:
        buffer.lookup_transform('base_link', 'camera')
    assert 'base_link' in str(err.value) and 'head' in str(err.value)  # the known frames
    with pytest.raises(LookupError, match="frames 'nowhere' and 'camera' are not"):
        buffer.lookup_transform('camera', 'nowhere')
    buffer.set_transform('world', 'table', np.eye(4))
    with pytest.raises(LookupError, match="not connected.*'head' is under 'base_link'"):
        buffer.lookup_transform('table', 'head')
    with pytest.raises(LookupError, match='empty frame id'):
        buffer.lookup_transform('', 'head')
    assert not buffer.can_transform('table', 'head')
    assert buffer.can_transform('head', 'base_link')
    np.testing.assert_array_equal(buffer.lookup_transform('unknown', 'unknown'), np.eye(4))


def test_reparenting_replaces_and_loops_are_reported() -> None:
    buffer = TransformBuffer()
    shift = np.eye(4)
    shift[0, 3] = 1.0
    buffer.set_transform('a', 'b', shift)
    buffer.set_transform('c', 'b', np.eye(4))  # b moves under c
    assert buffer.parent('b') == 'c'
    np.testing.assert_array_equal(buffer.lookup_transform('c', 'b'), np.eye(4))
    buffer.set_transform('b', 'a', np.eye(4))  # a -> b -> ... -> a: a loop
    buffer.set_transform('a', 'c', np.eye(4))
    with pytest.raises(LookupError, match='loop'):
        buffer.lookup_transform('a', 'b')
    with pytest.raises(ValueError, match='to itself'):
        buffer.set_transform('x', 'x', np.eye(4))


def test_messages_are_added_all_or_nothing() -> None:
    rng = np.random.default_rng(3)
    pose = random_pose(rng)
    while np.trace(pose[:3, :3]) < -0.5:
        pose = random_pose(rng)
    buffer = TransformBuffer()
    buffer.set_transform_messages([stamped('base', 'cam', pose)])
    np.testing.assert_allclose(buffer.lookup_transform('base', 'cam'), pose, atol=1e-12)
    bad = stamped('base', 'arm', np.eye(4))
    bad.transform.translation.y = math.nan
    with pytest.raises(ValueError, match=r"base->arm"):
        buffer.set_transform_messages([stamped('base', 'hand', np.eye(4)), bad])
    assert 'hand' not in buffer.all_frames() and 'arm' not in buffer.all_frames()
    zero = stamped('base', 'leg', np.eye(4))
    zero.transform.rotation.w = 0.0
    with pytest.raises(ValueError, match='base->leg'):
        buffer.set_transform_messages([zero])


def test_listener_fills_the_buffer_from_tf_and_latched_tf_static(context) -> None:
    suffix = uuid.uuid4().hex[:8]
    tf_topic, static_topic = f'/tf_test_{suffix}', f'/tf_static_test_{suffix}'
    broadcaster = Node(f'broadcaster_{suffix}', context=context, start_parameter_services=False)
    static_pub = broadcaster.create_publisher(TFMessage, static_topic, qos_profile_latched)
    tf_pub = broadcaster.create_publisher(TFMessage, tf_topic, 100)
    rng = np.random.default_rng(11)
    mount = random_pose(rng)
    while np.trace(mount[:3, :3]) < -0.5:
        mount = random_pose(rng)
    # published before the listener exists: a late joiner still gets it (transient local)
    static_pub.publish(TFMessage(transforms=[stamped('head', 'camera', mount)]))

    listener_node = Node(f'tf_listener_{suffix}', context=context, start_parameter_services=False)
    buffer = TransformBuffer()
    TransformListener(buffer, listener_node, tf_topic=tf_topic, tf_static_topic=static_topic)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(broadcaster)
    executor.add_node(listener_node)
    try:
        assert wait_until(lambda: buffer.can_transform('head', 'camera'), 10.0, spin=executor)
        np.testing.assert_allclose(buffer.lookup_transform('head', 'camera'), mount, atol=1e-12)

        def neck(angle: float) -> Any:
            pose = np.eye(4)
            pose[:3, :3] = quaternions_to_matrices([[0, 0, math.sin(angle / 2),
                                                     math.cos(angle / 2)]])[0]
            pose[2, 3] = 0.4
            return stamped('base_link', 'head', pose), pose

        msg, pose = neck(0.3)
        assert wait_until(lambda: tf_pub.get_subscription_count() > 0, 10.0, spin=executor)
        tf_pub.publish(TFMessage(transforms=[msg]))
        assert wait_until(lambda: buffer.can_transform('base_link', 'camera'), 10.0,
                          spin=executor)
        np.testing.assert_allclose(buffer.lookup_transform('base_link', 'camera'), pose @ mount,
                                   atol=1e-12)
        # a bad message is skipped (logged), the next good one still arrives
        bad, _ = neck(0.5)
        bad.transform.rotation.w = math.nan
        tf_pub.publish(TFMessage(transforms=[bad]))
        msg, pose = neck(-0.2)
        tf_pub.publish(TFMessage(transforms=[msg]))
        assert wait_until(lambda: np.allclose(buffer.lookup_transform('base_link', 'head'), pose,
                                              atol=1e-12), 10.0, spin=executor)
    finally:
        executor.remove_node(broadcaster)
        executor.remove_node(listener_node)
        broadcaster.destroy_node()
        listener_node.destroy_node()


def test_frame_poses_answer_at_a_past_stamp_while_the_head_moves() -> None:
    """The camera pans 1 deg per /tf message (10 ms): a pose asked at a past stamp is the one
    the chain had then (interpolated), not the latest; a static chain gets the latest one."""
    from vizzy_runtime.tf import FramePoses

    buffer = TransformBuffer()
    poses = FramePoses(buffer, 'base_link', max_age_s=1.0)
    assert poses.pose_at('camera', 0.0) is None          # no chain yet
    assert poses.newest('camera') is None

    def pan(deg: float) -> np.ndarray:
        a = math.radians(deg)
        m = np.eye(4)
        m[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
        m[:3, 3] = (0.0, 0.0, 0.5)
        return m

    for i in range(10):
        msg = stamped('base_link', 'camera', pan(float(i)))
        msg.header.stamp.sec, msg.header.stamp.nanosec = 100, i * 10_000_000
        tf = TFMessage(transforms=[msg])
        buffer.set_transform_messages(tf.transforms)
        poses.on_tf(tf)
    assert poses.newest('camera') == pytest.approx(100.09)
    past = poses.pose_at('camera', 100.035)               # between 3 and 4 deg
    assert past is not None
    assert math.degrees(math.atan2(past[1, 0], past[0, 0])) == pytest.approx(3.5)
    assert poses.latest_answers == 0
    # outside the records: the latest transform, counted
    old = poses.pose_at('camera', 50.0)
    assert old is not None and math.degrees(math.atan2(old[1, 0], old[0, 0])) == pytest.approx(9)
    assert poses.latest_answers == 1
    poses.set_fixed_frame('world')                        # another frame: records forgotten
    assert poses.newest('camera') is None
