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
from vizzy_runtime.testing import scaled, wait_until
from vizzy_runtime.tf import (
    ExtrapolationError,
    FramePoses,
    TransformBuffer,
    TransformListener,
    TransformRefusedError,
)
from vizzy_vision.frames import matrices_from_transforms, quaternions_to_matrices
from vizzy_vision.kinematics import (
    Transform,
    frames_in_base,
    joint_transforms,
    static_transforms,
    world_transform,
)

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


def head_stamped(t: Transform, stamp: float) -> Any:
    """A TransformStamped of one of the head's transforms at stamp [s]."""
    msg = TransformStamped(child_frame_id=t.child)
    msg.header.frame_id = t.parent
    msg.header.stamp.sec = int(stamp)
    msg.header.stamp.nanosec = int(round((stamp - int(stamp)) * 1e9))
    tr, q = msg.transform.translation, msg.transform.rotation
    tr.x, tr.y, tr.z = t.translation
    q.x, q.y, q.z, q.w = t.rotation
    return msg


def pan(deg: float, z: float = 0.5) -> np.ndarray:
    """A pose turned deg about z, z [m] up."""
    a = math.radians(deg)
    m = np.eye(4)
    m[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    m[2, 3] = z
    return m


def yaw_deg(m: np.ndarray) -> float:
    return math.degrees(math.atan2(m[1, 0], m[0, 0]))


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


def test_reparenting_replaces_and_loop_closing_edges_are_refused() -> None:
    """issue 28 item 3: one edge closing a loop used to break every lookup through it until
    restart; now it is refused, named, and the tree keeps working."""
    buffer = TransformBuffer()
    shift = np.eye(4)
    shift[0, 3] = 1.0
    buffer.set_transform('a', 'b', shift)
    buffer.set_transform('c', 'b', np.eye(4))  # b moves under c
    assert buffer.parent('b') == 'c'
    np.testing.assert_array_equal(buffer.lookup_transform('c', 'b'), np.eye(4))
    buffer.set_transform('b', 'a', shift)      # c -> b -> a
    with pytest.raises(TransformRefusedError, match=r"'a' -> 'c': would close a loop: "
                                                    r"c -> a -> b -> c") as err:
        buffer.set_transforms(['a', 'c'], ['c', 'd'], np.stack([np.eye(4), shift]))
    assert err.value.refused == [('a', 'c', 'would close a loop: c -> a -> b -> c')]
    assert buffer.parent('c') is None and buffer.parent('d') == 'c'   # the rest was stored
    np.testing.assert_array_equal(buffer.lookup_transform('c', 'a'), shift)
    np.testing.assert_array_equal(buffer.lookup_transform('a', 'd'), np.linalg.inv(shift) @ shift)
    with pytest.raises(TransformRefusedError, match='loop'):       # a root under its descendant
        buffer.set_transform('d', 'c', np.eye(4), stamp=1.0)
    assert buffer.refused == {'loop': 2}
    with pytest.raises(ValueError, match='to itself'):
        buffer.set_transform('x', 'x', np.eye(4))


def test_a_foreign_loop_on_tf_or_tf_static_leaves_the_head_tree_working() -> None:
    """The head's tree as the simulator publishes it; a foreign TFMessage puts base_link under
    the left camera (on /tf, then on /tf_static) and the real /tf goes on: ego <- left keeps
    its value (before the fix: LookupError 'loop' for good, since base_link is static)."""
    buffer = TransformBuffer()
    buffer.set_transform_messages([head_stamped(t, 0.0) for t in
                                   [world_transform(), *static_transforms()]], static=True)
    buffer.set_transform_messages([head_stamped(t, 5.0) for t in joint_transforms([0.1] * 5)])
    expected = buffer.lookup_transform('ego', 'left_camera_optical_frame')
    truth = frames_in_base([0.1] * 5)
    np.testing.assert_allclose(expected, np.linalg.inv(truth['ego'])
                               @ truth['left_camera_optical_frame'], atol=1e-12)
    loop = stamped('left_camera_optical_frame', 'base_link', np.eye(4))
    loop.header.stamp.sec = 5
    for static in (False, True):
        with pytest.raises(TransformRefusedError, match="'left_camera_optical_frame' -> "
                                                        "'base_link'"):
            buffer.set_transform_messages([loop], static=static)
        buffer.set_transform_messages([head_stamped(t, 5.01) for t in
                                       joint_transforms([0.1] * 5)])
        np.testing.assert_allclose(buffer.lookup_transform('ego', 'left_camera_optical_frame'),
                                   expected, atol=1e-12)
        assert buffer.parent('base_link') == 'world'
    # a /tf edge may not move a /tf_static frame either (it could close a loop later)
    assert buffer.refused == {'static frame': 1, 'loop': 1}


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
        assert wait_until(lambda: buffer.can_transform('head', 'camera'), scaled(10.0),
                          spin=executor)
        np.testing.assert_allclose(buffer.lookup_transform('head', 'camera'), mount, atol=1e-12)

        def neck(angle: float) -> Any:
            pose = np.eye(4)
            pose[:3, :3] = quaternions_to_matrices([[0, 0, math.sin(angle / 2),
                                                     math.cos(angle / 2)]])[0]
            pose[2, 3] = 0.4
            return stamped('base_link', 'head', pose), pose

        msg, pose = neck(0.3)
        assert wait_until(lambda: tf_pub.get_subscription_count() > 0, scaled(10.0), spin=executor)
        tf_pub.publish(TFMessage(transforms=[msg]))
        assert wait_until(lambda: buffer.can_transform('base_link', 'camera'), scaled(10.0),
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
                                              atol=1e-12), scaled(10.0), spin=executor)
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


def test_lookup_at_a_stamp_interpolates_each_dynamic_edge() -> None:
    """issue 28 item 3: a camera panning at 1 rad/s, /tf at 100 Hz; an image stamped between two
    samples and looked up 50 ms later gets the pose at its stamp (the latest is ~2.9 deg off);
    static edges hold at any stamp."""
    buffer = TransformBuffer()
    optical = pan(-90.0, 0.0)
    buffer.set_transform('camera', 'optical', optical)               # static
    rate = math.degrees(1.0)                                         # 1 rad/s in deg/s
    for k in range(31):                                              # 100.00 .. 100.30 s
        buffer.set_transform('base_link', 'camera', pan(rate * 0.01 * k, 0.4), 100.0 + 0.01 * k)
    image = 100.245                                                  # between two samples
    at_image = buffer.lookup_transform('base_link', 'optical', image)
    assert yaw_deg(at_image) == pytest.approx(rate * 0.245 - 90.0, abs=1e-9)
    assert yaw_deg(buffer.lookup_transform('base_link', 'optical')) \
        == pytest.approx(rate * 0.30 - 90.0)                        # latest: 3.15 deg further
    np.testing.assert_allclose(at_image[:3, 3], [0.0, 0.0, 0.4], atol=1e-12)
    # a header's stamp works as well as seconds; an exact sample is returned as it is
    time_msg = TransformStamped().header.stamp
    time_msg.sec, time_msg.nanosec = 100, 120_000_000
    np.testing.assert_allclose(buffer.lookup_transform('base_link', 'camera', time_msg),
                               pan(rate * 0.12, 0.4), atol=1e-12)
    # the static edge alone is time-independent
    np.testing.assert_array_equal(buffer.lookup_transform('camera', 'optical', 5.0), optical)
    np.testing.assert_array_equal(buffer.lookup_transform('camera', 'optical', 1e9), optical)
    # just past the newest sample (tf lags slightly): the newest, counted; further: an error
    held = buffer.lookup_transform('base_link', 'camera', 100.33)
    assert yaw_deg(held) == pytest.approx(rate * 0.30) and buffer.held_lookups == 1
    with pytest.raises(ExtrapolationError, match=r"no transform 'base_link' -> 'camera' at "
                                                 r"100\.4000 s yet") as err:
        buffer.lookup_transform('base_link', 'optical', 100.4)
    assert isinstance(err.value, LookupError) and err.value.frame == 'camera'
    assert not buffer.can_transform('base_link', 'optical', 100.4)
    with pytest.raises(ExtrapolationError, match=r"older than its history \(100\.0000 to "
                                                 r"100\.3000 s kept"):
        buffer.lookup_transform('optical', 'base_link', 99.0)
    assert buffer.latest_common_time('optical', 'base_link') == pytest.approx(100.3)
    assert buffer.latest_common_time('camera', 'optical') is None    # static only


def test_a_lookup_waits_up_to_its_timeout_for_the_tf_that_covers_its_stamp() -> None:
    import threading

    buffer = TransformBuffer()
    buffer.set_transform('base_link', 'camera', pan(0.0), 10.0)
    with pytest.raises(ExtrapolationError, match='yet'):
        buffer.lookup_transform('base_link', 'camera', 10.5, timeout_s=0.05)
    got: list[Any] = []
    waiter = threading.Thread(target=lambda: got.append(buffer.lookup_transform(
        'base_link', 'camera', 10.5, timeout_s=scaled(30.0))))
    waiter.start()
    buffer.set_transform('base_link', 'camera', pan(10.0), 11.0)   # /tf that covers 10.5 s
    waiter.join(scaled(30.0))
    assert len(got) == 1 and yaw_deg(got[0]) == pytest.approx(5.0)


def test_history_is_bounded_by_time_and_count() -> None:
    buffer = TransformBuffer(cache_time_s=1.0, max_samples=50)
    for k in range(300):                                             # 3 s at 100 Hz
        buffer.set_transform('base_link', 'camera', pan(k), 0.01 * k)
    assert buffer.stats()['samples'] == 50                           # the count bound
    with pytest.raises(ExtrapolationError, match='older than its history'):
        buffer.lookup_transform('base_link', 'camera', 2.4)
    assert yaw_deg(buffer.lookup_transform('base_link', 'camera', 2.505)) == pytest.approx(250.5
                                                                                          - 360)
    buffer = TransformBuffer(cache_time_s=1.0)
    for k in range(300):
        buffer.set_transform('base_link', 'camera', pan(k / 10), 0.01 * k)
    kept = buffer.stats()['samples']
    assert kept in (100, 101)                                        # 1 s: the time bound
    buffer.set_transform('base_link', 'camera', pan(0.0), 0.5)       # older than kept: ignored
    assert buffer.old_samples_ignored == 1 and buffer.stats()['samples'] == kept


@pytest.mark.slow
def test_a_stream_of_new_frame_names_keeps_the_frames_bounded() -> None:
    """issue 28 item 3: 321,500 new names on /tf in 60 s grew each node by 27-150 MB and made a
    lookup 138 ms. Here 60,000 names over 60 s of the buffer's clock, while the head's /tf goes
    on at 100 Hz: names not updated for cache_time_s are forgotten, at most max_frames are held
    (the rest refused, one error per message), and the head's chain still looks up."""
    now = [0.0]
    buffer = TransformBuffer(max_frames=2000, clock=lambda: now[0])
    buffer.set_transform_messages([head_stamped(t, 0.0) for t in
                                   [world_transform(), *static_transforms()]], static=True)
    refused = 0
    for i0 in range(0, 60_000, 10):
        now[0] = i0 / 1000.0
        buffer.set_transform_messages([head_stamped(t, now[0]) for t in
                                       joint_transforms([0.1] * 5)])
        foreign = [stamped('foreign_map', f'foreign_{i}', np.eye(4)) for i in range(i0, i0 + 10)]
        try:
            buffer.set_transform_messages(foreign)
        except TransformRefusedError as exc:
            assert 'max_frames 2000' in str(exc)
            refused += 1
    stats = buffer.stats()
    assert stats['edges'] <= 2000 and stats['frames_expired'] > 8000
    assert refused > 0 and stats['refused frame limit'] > 0
    assert stats['samples'] < 2000 + 5 * 1001                        # head: 10 s at 100 Hz
    truth = frames_in_base([0.1] * 5)
    np.testing.assert_allclose(buffer.lookup_transform('ego', 'left_camera_optical_frame', 59.99),
                               np.linalg.inv(truth['ego']) @ truth['left_camera_optical_frame'],
                               atol=1e-12)
    # a paused head is not forgotten while no new names come (nothing sweeps)
    now[0] += 100.0
    assert buffer.can_transform('ego', 'left_camera_optical_frame')


def test_frame_poses_ask_the_buffer_for_their_history() -> None:
    buffer = TransformBuffer(cache_time_s=1.0)
    poses = FramePoses(buffer, 'base_link', max_age_s=5.0)
    assert buffer.cache_time_s == 5.0
    poses.max_age_s = 8.0                                            # a node's parameter change
    assert buffer.cache_time_s == 8.0
