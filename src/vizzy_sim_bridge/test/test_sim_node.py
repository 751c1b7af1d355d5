"""The sim node on the bundled runtime: what it publishes and how it takes joint commands.

A listener node in the test process subscribes to the sim's topics; nothing asserts on
wall-clock time (every test waits for a condition). Images are rendered at reduced resolution.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import replace
from typing import Any

import cv2
import numpy as np
import pytest

from vizzy_runtime.convert import image_to_numpy, pointcloud2_to_array
from vizzy_runtime.ros import (
    Context,
    Node,
    Parameter,
    SingleThreadedExecutor,
    message,
    qos_profile_latched,
    qos_profile_sensor_data,
)
from vizzy_runtime.testing import wait_until
from vizzy_sim_bridge.camera_calibration import Calibration, to_yaml
from vizzy_sim_bridge.compressed import encode_jpeg
from vizzy_sim_bridge.core import render as render_mod
from vizzy_sim_bridge.core.urdf import head_urdf
from vizzy_sim_bridge.sim_node import SimNode, box_corners, image_box
from vizzy_vision.camera import camera_matrix
from vizzy_vision.kinematics import (
    BASELINE,
    JOINT_LIMITS,
    JOINT_NAMES,
    frames_in_base,
    static_transforms,
)

pytestmark = pytest.mark.live  # also run on the real rclpy (scripts/test_ros.sh)

CameraInfo = message('sensor_msgs/msg/CameraInfo')
CompressedImage = message('sensor_msgs/msg/CompressedImage')
Image = message('sensor_msgs/msg/Image')
JointState = message('sensor_msgs/msg/JointState')
MarkerArray = message('visualization_msgs/msg/MarkerArray')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')
TFMessage = message('tf2_msgs/msg/TFMessage')
Clock = message('rosgraph_msgs/msg/Clock')
String = message('std_msgs/msg/String')

TIMEOUT = 30.0
W, H = 160, 120
OVERRIDES = [Parameter('width', value=W), Parameter('height', value=H),
             Parameter('rgbd_width', value=W), Parameter('rgbd_height', value=H),
             Parameter('rate_hz', value=20.0), Parameter('rgbd_rate_hz', value=10.0),
             Parameter('joint_state_rate_hz', value=100.0)]


class Listener(Node):
    """Keeps the last message of each sim topic and sends joint commands."""

    TOPICS = {
        '/vizzy/left/image_raw': (Image, qos_profile_sensor_data),
        '/vizzy/right/image_raw': (Image, qos_profile_sensor_data),
        '/vizzy/left/camera_info': (CameraInfo, qos_profile_sensor_data),
        '/vizzy/right/camera_info': (CameraInfo, qos_profile_sensor_data),
        '/vizzy/rgbd/image_raw': (Image, qos_profile_sensor_data),
        '/vizzy/rgbd/depth/image_raw': (Image, qos_profile_sensor_data),
        '/vizzy/rgbd/points': (PointCloud2, qos_profile_sensor_data),
        '/vizzy/rgbd/camera_info': (CameraInfo, qos_profile_sensor_data),
        '/joint_states': (JointState, 10),
        '/tf': (TFMessage, 100),
        '/tf_static': (TFMessage, qos_profile_latched),
        '/clock': (Clock, 10),
        '/sim/ground_truth/objects': (MarkerArray, qos_profile_latched),
        # reliable + transient local, depth 1: what RViz's RobotModel asks for
        '/robot_description': (String, qos_profile_latched),
    }

    def __init__(self, context: Context) -> None:
        super().__init__('sim_listener', context=context, start_parameter_services=False)
        self.last: dict[str, Any] = {}
        self.stamps: dict[str, list[int]] = {}
        for topic, (kind, qos) in self.TOPICS.items():
            self.create_subscription(kind, topic, self._keep(topic), qos)
        self.commands = self.create_publisher(JointState, '/vizzy/joint_commands', 10)

    def _keep(self, topic: str) -> Any:
        def keep(msg: Any) -> None:
            self.last[topic] = msg
            stamp = getattr(getattr(msg, 'header', None), 'stamp', None)
            if stamp is not None:
                self.stamps.setdefault(topic, []).append(stamp.sec * 10 ** 9 + stamp.nanosec)
        return keep

    def command(self, **targets: float) -> None:
        self.commands.publish(JointState(name=list(targets),
                                         position=[float(v) for v in targets.values()]))

    def joint(self, name: str) -> float:
        js = self.last['/joint_states']
        return float(js.position[list(js.name).index(name)])


@pytest.fixture(scope='module')
def running():
    try:
        render_mod.select_backend()
    except render_mod.RendererUnavailable as exc:
        pytest.skip(str(exc))
    ctx = Context()
    ctx.init(['test'])
    sim = SimNode(context=ctx, parameter_overrides=OVERRIDES)
    listener = Listener(ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(sim)
    executor.add_node(listener)
    assert wait_until(lambda: set(Listener.TOPICS) <= set(listener.last), TIMEOUT, spin=executor), (
        f'never received {set(Listener.TOPICS) - set(listener.last)}')
    try:
        yield sim, listener, executor
    finally:
        executor.remove_node(listener)
        executor.remove_node(sim)
        listener.destroy_node()
        sim.destroy_node()
        ctx.try_shutdown()


def test_images_and_camera_info(running) -> None:
    sim, listener, _ = running
    k = camera_matrix(W, H, 85.4)
    for side in ('left', 'right'):
        img = listener.last[f'/vizzy/{side}/image_raw']
        assert (img.width, img.height, img.encoding) == (W, H, 'rgb8')
        assert img.header.frame_id == f'{side}_camera_optical_frame'
        assert image_to_numpy(img).std() > 5.0
        info = listener.last[f'/vizzy/{side}/camera_info']
        assert info.header.frame_id == img.header.frame_id
        assert (info.width, info.height, info.distortion_model) == (W, H, 'plumb_bob')
        np.testing.assert_allclose(np.reshape(info.k, (3, 3)), k)
        np.testing.assert_array_equal(info.d, np.zeros(5))
        np.testing.assert_array_equal(np.reshape(info.r, (3, 3)), np.eye(3))
        p = np.reshape(info.p, (3, 4))
        np.testing.assert_allclose(p[:, :3], k)
        tx = -k[0, 0] * BASELINE if side == 'right' else 0.0
        assert p[0, 3] == pytest.approx(tx)
    # each stereo pair shares one stamp
    left = set(listener.stamps['/vizzy/left/image_raw'])
    assert left & set(listener.stamps['/vizzy/right/image_raw'])


def test_rgbd_cloud_depth_and_info(running) -> None:
    _, listener, _ = running
    cloud = listener.last['/vizzy/rgbd/points']
    assert cloud.header.frame_id == 'rgbd_camera_optical_frame'
    assert (cloud.height, cloud.width) == (H, W) and not cloud.is_dense
    assert [f.name for f in cloud.fields] == ['x', 'y', 'z', 'rgb']
    pts = pointcloud2_to_array(cloud)
    valid = np.isfinite(pts['z'])
    assert valid.mean() > 0.5
    assert np.nanmin(pts['z']) >= 0.5 and np.nanmax(pts['z']) <= 3.5
    depth = listener.last['/vizzy/rgbd/depth/image_raw']
    assert depth.encoding == '32FC1' and depth.header.frame_id == cloud.header.frame_id
    info = listener.last['/vizzy/rgbd/camera_info']
    np.testing.assert_allclose(np.reshape(info.k, (3, 3)), camera_matrix(W, H, 58.0))
    assert listener.last['/vizzy/rgbd/image_raw'].encoding == 'rgb8'


def _ns(msg: Any) -> int:
    return msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec


def test_compressed_images_are_encoded_only_while_read(running) -> None:
    """<image>/compressed beside each raw image (image_transport's compressed transport): a JPEG
    at jpeg_quality with compressed_image_transport's format string and the raw image's header,
    encoded only while something subscribes (issue 29 item 3)."""
    sim, listener, spin = running
    stamps = listener.stamps['/vizzy/left/image_raw']
    encodes, n = sim.jpeg_encodes, len(stamps)
    assert wait_until(lambda: len(stamps) >= n + 4, TIMEOUT, spin=spin)
    assert sim.jpeg_encodes == encodes          # four stereo pairs, RGB-D images: no JPEG

    reader = Node('compressed_reader', context=sim.context, start_parameter_services=False)
    got: dict[str, list[Any]] = {t: [] for t in ('left', 'right', 'rgbd')}
    raw: dict[int, Any] = {}
    for t in got:
        reader.create_subscription(CompressedImage, f'/vizzy/{t}/image_raw/compressed',
                                   got[t].append, qos_profile_sensor_data)
    reader.create_subscription(Image, '/vizzy/left/image_raw',
                               lambda m: raw.__setitem__(_ns(m), m), qos_profile_sensor_data)
    spin.add_node(reader)
    try:
        assert wait_until(lambda: all(len(v) >= 2 for v in got.values())
                          and any(_ns(m) in raw for m in got['left']), TIMEOUT, spin=spin)
        assert sim.jpeg_encodes > encodes
        frames = {'left': 'left_camera_optical_frame', 'right': 'right_camera_optical_frame',
                  'rgbd': 'rgbd_camera_optical_frame'}
        for t, msgs in got.items():
            assert msgs[-1].format == 'rgb8; jpeg compressed bgr8'
            assert msgs[-1].header.frame_id == frames[t]
            bgr = cv2.imdecode(np.asarray(msgs[-1].data, np.uint8), cv2.IMREAD_COLOR)
            assert bgr is not None and bgr.shape == (H, W, 3)
        jpeg = next(m for m in reversed(got['left']) if _ns(m) in raw)   # same stamp as a raw
        # exactly the JPEG of the raw image at quality 95 (true colours: test_compressed.py)
        assert bytes(jpeg.data) == encode_jpeg(image_to_numpy(raw[_ns(jpeg)]), 'rgb8', 95)
        # jpeg_quality applies from the next frame
        size = len(jpeg.data)
        assert sim.set_parameters([Parameter('jpeg_quality', value=20)])[0].successful
        k = len(got['left'])
        assert wait_until(lambda: len(got['left']) > k + 1, TIMEOUT, spin=spin)
        assert len(got['left'][-1].data) < 0.6 * size
    finally:
        spin.remove_node(reader)
        reader.destroy_node()
        sim.set_parameters([Parameter('jpeg_quality', value=95)])
    pubs = [*sim._compressed_pubs.values(), sim._rgbd_compressed_pub]
    assert wait_until(lambda: all(p.get_subscription_count() == 0 for p in pubs), TIMEOUT,
                      spin=spin)
    # a frame rendered from now on is not encoded: once one is out, the one in flight is done
    now = int(round(sim._sim.time * 1e9))
    assert wait_until(lambda: stamps[-1] > now, TIMEOUT, spin=spin)
    encodes, n = sim.jpeg_encodes, len(stamps)
    assert wait_until(lambda: len(stamps) >= n + 4, TIMEOUT, spin=spin)
    assert sim.jpeg_encodes == encodes


def test_camera_info_url_replaces_the_computed_calibration(tmp_path, capfd) -> None:
    """A camera's <camera>_camera_info_url (camera_info_manager's URL, ${NAME} substituted)
    naming a usable camera_calibration_parsers YAML is published as its camera_info; a file for
    another image size and a missing file each give one error line and the computed calibration
    (issue 29 item 4)."""
    try:
        render_mod.select_backend()
    except render_mod.RendererUnavailable as exc:
        pytest.skip(str(exc))
    left = Calibration('vizzy_left', W, H, (200.0, 0.0, 81.0, 0.0, 201.0, 59.0, 0.0, 0.0, 1.0),
                       'plumb_bob', (-0.1, 0.02, 0.001, -0.002, 0.0),
                       (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
                       (199.0, 0.0, 80.0, 0.0, 0.0, 199.5, 60.0, 0.0, 0.0, 0.0, 1.0, 0.0))
    (tmp_path / 'vizzy_left.yaml').write_text(to_yaml(left))
    (tmp_path / 'right.yaml').write_text(to_yaml(replace(left, camera_name='vizzy_right',
                                                         width=2 * W, height=2 * H)))
    urls = {'left': f'file://{tmp_path}/${{NAME}}.yaml', 'right': f'file://{tmp_path}/right.yaml',
            'rgbd': f'file://{tmp_path}/missing.yaml'}
    ctx = Context()
    ctx.init(['test'])
    # in a namespace of its own: the module's sim may still run in this domain
    sim = SimNode(context=ctx, cli_args=['--ros-args', '-r', '__ns:=/calib'],
                  parameter_overrides=[*OVERRIDES, *(Parameter(f'{c}_camera_info_url', value=u)
                                                     for c, u in urls.items())])
    peer = Node('info_reader', context=ctx, start_parameter_services=False)
    infos: dict[str, Any] = {}
    for c in urls:
        peer.create_subscription(CameraInfo, f'/calib/vizzy/{c}/camera_info',
                                 lambda m, c=c: infos.__setitem__(c, m), qos_profile_sensor_data)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(sim)
    executor.add_node(peer)
    try:
        assert wait_until(lambda: len(infos) == 3, TIMEOUT, spin=executor)
    finally:
        executor.remove_node(peer)
        executor.remove_node(sim)
        peer.destroy_node()
        sim.destroy_node()
        ctx.try_shutdown()
    info = infos['left']
    assert (info.width, info.height, info.distortion_model) == (W, H, 'plumb_bob')
    np.testing.assert_array_equal(info.k, left.k)
    np.testing.assert_array_equal(info.d, left.d)
    np.testing.assert_array_equal(info.p, left.p)
    assert info.header.frame_id == 'left_camera_optical_frame'
    k = camera_matrix(W, H, 85.4)
    np.testing.assert_allclose(np.reshape(infos['right'].k, (3, 3)), k)
    assert infos['right'].p[3] == pytest.approx(-k[0, 0] * BASELINE)
    np.testing.assert_allclose(np.reshape(infos['rgbd'].k, (3, 3)), camera_matrix(W, H, 58.0))
    assert sim.calibration_sources == {'left': urls['left'], 'right': 'computed',
                                       'rgbd': 'computed'}
    errors = [line for line in capfd.readouterr().err.splitlines()
              if 'publishing the calibration computed from MuJoCo' in line]
    assert len(errors) == 2, errors
    assert (f'right_camera_info_url: {tmp_path}/right.yaml is for {2 * W}x{2 * H} images, '
            f'the camera gives {W}x{H}') in errors[0]
    assert f'rgbd_camera_info_url: cannot read {tmp_path}/missing.yaml' in errors[1]


def test_tf_static_and_tf_cover_the_whole_head(running) -> None:
    _, listener, spin = running
    static = {t.child_frame_id: t for t in listener.last['/tf_static'].transforms}
    assert {t.child for t in static_transforms()} | {'base_link'} == set(static)
    ego = static['ego'].transform.translation
    assert (ego.x, ego.y, ego.z) == pytest.approx((0.0, 0.0, 0.370))
    assert static['base_link'].header.frame_id == 'world'
    assert wait_until(lambda: {t.child_frame_id for t in listener.last['/tf'].transforms} == {
        'neck_pan_link', 'neck_tilt_link', 'eyes_tilt_link', 'left_eye_link', 'right_eye_link'},
        TIMEOUT, spin=spin)
    js = listener.last['/joint_states']
    assert list(js.name) == list(JOINT_NAMES) and len(js.position) == 5
    clock = listener.last['/clock'].clock
    assert clock.sec * 10 ** 9 + clock.nanosec > 0


def test_robot_description_reaches_a_late_joiner_and_names_the_tf_frames(running) -> None:
    _, listener, spin = running   # the listener subscribed after the sim had published it
    urdf = listener.last['/robot_description'].data
    assert urdf == head_urdf()
    links = {link.get('name') for link in ET.fromstring(urdf).findall('link')}
    assert wait_until(lambda: len(listener.last['/tf'].transforms) == 5, TIMEOUT, spin=spin)
    published = {t.child_frame_id for t in listener.last['/tf_static'].transforms} | {
        t.child_frame_id for t in listener.last['/tf'].transforms}
    assert links == published   # every frame below world, and no other


def test_ground_truth_objects_have_dimensions_and_axes(running) -> None:
    sim, listener, _ = running
    markers = listener.last['/sim/ground_truth/objects'].markers
    shapes = [m for m in markers if m.ns == 'objects']
    axes = [m for m in markers if m.ns == 'cylinder_axes']
    assert len(shapes) == len(sim._scene.objects)
    assert len(axes) == sum(o.is_cylinder for o in sim._scene.objects) >= 5
    for m in shapes:
        assert m.header.frame_id == 'base_link' and min(m.scale.x, m.scale.y, m.scale.z) > 0


def _wait_joint(listener: Any, spin: Any, name: str, value: float) -> bool:
    return wait_until(lambda: abs(listener.joint(name) - value) < 1e-3, TIMEOUT, spin=spin)


def test_joint_commands_move_the_joints_and_are_clamped(running) -> None:
    sim, listener, spin = running
    listener.command(l_eye_joint=0.2, neck_pan_joint=-0.1)
    assert _wait_joint(listener, spin, 'l_eye_joint', 0.2)
    assert _wait_joint(listener, spin, 'neck_pan_joint', -0.1)
    # the tf of the moved joint follows MuJoCo's joint position
    tf = {t.child_frame_id: t for t in listener.last['/tf'].transforms}
    q = tf['left_eye_link'].transform.rotation
    assert 2 * math.atan2(q.z, q.w) == pytest.approx(0.2, abs=2e-3)
    # beyond the limit: clamped to it
    listener.command(r_eye_joint=5.0)
    assert _wait_joint(listener, spin, 'r_eye_joint', JOINT_LIMITS['r_eye_joint'][1])
    assert sim._sim.targets()['r_eye_joint'] == JOINT_LIMITS['r_eye_joint'][1]


def test_bad_commands_are_rejected_and_the_node_keeps_going(running) -> None:
    sim, listener, spin = running
    before = sim._sim.targets()
    listener.command(elbow_joint=0.3, l_eye_joint=-0.2)          # unknown name: whole message
    listener.commands.publish(JointState(name=['l_eye_joint'], position=[math.nan]))
    listener.commands.publish(JointState(name=['l_eye_joint', 'r_eye_joint'], position=[0.1]))
    listener.command(neck_tilt_joint=0.1)                         # a good one after the bad
    assert wait_until(lambda: sim._sim.targets()['neck_tilt_joint'] == 0.1, TIMEOUT, spin=spin)
    after = sim._sim.targets()
    assert after['l_eye_joint'] == before['l_eye_joint']
    n = len(listener.stamps['/vizzy/left/image_raw'])
    assert wait_until(lambda: len(listener.stamps['/vizzy/left/image_raw']) > n + 2, TIMEOUT,
                      spin=spin)


def _changes(before: dict[Any, int], after: dict[Any, int]) -> dict[Any, int]:
    """How much each count grew from before to after (counts that did not are left out)."""
    return {k: v - before.get(k, 0) for k, v in after.items() if v != before.get(k, 0)}


def test_refused_commands_are_counted_per_reason(running) -> None:
    """Each command rejected whole is counted by InputHealth on the resolved command topic with
    its reason; a clamped target is no refusal; the valid command right after is processed; no
    exception escapes (one would be counted as 'failed on a command: <ExcType>')."""
    sim, listener, spin = running
    topic = sim._command_sub.topic_name
    health = sim.input_health
    refused, accepted = health.refused(), health.accepted()   # the module's earlier tests' too
    targets = sim._sim.targets()
    pub = listener.commands
    # reliable, depth 10: all eight arrive, in order
    pub.publish(JointState(name=['elbow_joint'], position=[0.3]))
    pub.publish(JointState(name=['l_eye_joint', 'l_eye_joint'], position=[0.1, 0.2]))
    pub.publish(JointState(name=['l_eye_joint'], position=[math.nan]))
    pub.publish(JointState(name=['neck_pan_joint', 'l_eye_joint'], position=[0.1, -math.inf]))
    pub.publish(JointState(name=['l_eye_joint', 'r_eye_joint'], position=[0.1]))
    pub.publish(JointState(name=[], position=[]))
    listener.command(r_eye_joint=-5.0)          # beyond the limit: clamped, not refused
    listener.command(neck_tilt_joint=-0.05)     # valid, right after
    assert wait_until(lambda: sim._sim.targets()['neck_tilt_joint'] == -0.05, TIMEOUT, spin=spin)
    assert _changes(refused, health.refused()) == {
        (topic, 'unknown joint'): 1, (topic, 'repeated joint'): 1,
        (topic, 'non-finite target'): 2, (topic, 'length mismatch'): 1,
        (topic, 'no joint names'): 1}
    assert _changes(accepted, health.accepted()) == {topic: 2}
    after = sim._sim.targets()
    assert after['r_eye_joint'] == JOINT_LIMITS['r_eye_joint'][0]
    assert {k: after[k] for k in ('l_eye_joint', 'neck_pan_joint')} == {
        k: targets[k] for k in ('l_eye_joint', 'neck_pan_joint')}
    assert topic == '/vizzy/joint_commands'


def test_a_command_the_handler_fails_on_is_counted(running, monkeypatch) -> None:
    """An exception in the command callback is swallowed by guarded() and counted as a refusal of
    the command topic (reason 'failed on a command: <ExcType>'); the next command is processed."""
    sim, listener, spin = running
    topic = sim._command_sub.topic_name
    health = sim.input_health
    refused, accepted = health.refused(), health.accepted()
    set_targets = sim._sim.set_targets

    def failing(targets: Any, speeds: Any = None) -> Any:
        if 'eyes_tilt_joint' in targets:
            raise RuntimeError('simulated failure')
        return set_targets(targets, speeds)

    monkeypatch.setattr(sim._sim, 'set_targets', failing)
    listener.command(eyes_tilt_joint=0.1)
    listener.command(neck_tilt_joint=-0.04)
    assert wait_until(lambda: sim._sim.targets()['neck_tilt_joint'] == -0.04, TIMEOUT, spin=spin)
    assert _changes(refused, health.refused()) == {
        (topic, 'failed on a command: RuntimeError'): 1}
    assert _changes(accepted, health.accepted()) == {topic: 1}


def test_image_box_projects_and_clips() -> None:
    k = camera_matrix(640, 480, 85.4)
    cam = frames_in_base([0.0] * 5)['left_camera_optical_frame']
    ahead = cam[:3, 3] + 3.0 * cam[:3, 2]
    box = image_box(k, cam, box_corners(ahead, (0.5, 0.5, 1.7), (0, 0, 0, 1)), 640, 480)
    u0, v0, u1, v1 = box
    assert u0 < 319.5 < u1 and v0 < 239.5 < v1
    assert (v1 - v0) == pytest.approx(k[1, 1] * 1.7 / 2.75, rel=0.15)
    behind = cam[:3, 3] - 3.0 * cam[:3, 2]
    assert image_box(k, cam, box_corners(behind, (0.5, 0.5, 1.7), (0, 0, 0, 1)), 640, 480) is None


def test_lockstep_advances_only_as_asked_and_keeps_each_output_on_its_schedule() -> None:
    """In lockstep the sim stands still until asked on sim/step, then publishes every /clock
    tick up to the time asked, the images on their sim-time schedule, and sim/stepped."""
    try:
        render_mod.select_backend()
    except render_mod.RendererUnavailable as exc:
        pytest.skip(str(exc))
    ctx = Context()
    ctx.init(['test'])
    # in a namespace of its own: the module's real-time sim may still run in this domain
    sim = SimNode(context=ctx, cli_args=['--ros-args', '-r', '__ns:=/lockstep'],
                  parameter_overrides=[*OVERRIDES, Parameter('rate_hz', value=10.0),
                                       Parameter('rgbd_rate_hz', value=0.0),
                                       Parameter('lockstep', value=True)])
    peer = Node('stepper', context=ctx, start_parameter_services=False)
    clocks: list[float] = []
    stepped: list[float] = []
    images: list[float] = []
    peer.create_subscription(Clock, '/lockstep/clock',
                             lambda m: clocks.append(m.clock.sec + 1e-9 * m.clock.nanosec), 100)
    peer.create_subscription(Clock, '/lockstep/sim/stepped',
                             lambda m: stepped.append(m.clock.sec + 1e-9 * m.clock.nanosec), 10)
    peer.create_subscription(Image, '/lockstep/vizzy/left/image_raw',
                             lambda m: images.append(m.header.stamp.sec
                                                     + 1e-9 * m.header.stamp.nanosec), 10)
    step = peer.create_publisher(Clock, '/lockstep/sim/step', 10)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(sim)
    executor.add_node(peer)
    try:
        assert wait_until(lambda: step.get_subscription_count() > 0
                          and sim._stepped_pub.get_subscription_count() > 0, TIMEOUT,
                          spin=executor)
        for _ in range(50):                     # nothing asked: time stands still
            executor.spin_once(0.01)
        assert clocks == [] and images == [] and sim.ticks == 0

        def ask(t: float) -> None:
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = int(t), int(round((t - int(t)) * 1e9))
            step.publish(msg)
            assert wait_until(lambda: stepped and stepped[-1] >= t - 1e-9, TIMEOUT,
                              spin=executor)

        ask(0.05)
        # /clock and sim/stepped are two topics: no order between them on the wire
        assert wait_until(lambda: len(clocks) >= 5, TIMEOUT, spin=executor)
        assert clocks == pytest.approx([0.01, 0.02, 0.03, 0.04, 0.05])
        assert wait_until(lambda: len(images) == 1, TIMEOUT, spin=executor)
        ask(0.25)
        assert wait_until(lambda: len(clocks) == 25 and len(images) == 3, TIMEOUT, spin=executor)
        assert images == pytest.approx([0.01, 0.1, 0.2])        # 10 Hz of sim time
        assert stepped[-1] == pytest.approx(0.25) and sim.ticks == 25
        ask(0.1)                                # the past: answered at once, nothing moves
        assert sim.ticks == 25
    finally:
        executor.remove_node(peer)
        executor.remove_node(sim)
        peer.destroy_node()
        sim.destroy_node()
        ctx.try_shutdown()
