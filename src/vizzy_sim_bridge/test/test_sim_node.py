"""The sim node on the bundled runtime: tf, the robot description, ground truth, joint
commands and their refusals, lockstep (images and camera_info: test_sim_node_images.py).

A listener node in the test process (`running`, conftest.py) subscribes to the sim's topics;
nothing asserts on wall-clock time (every test waits for a condition). Images are rendered at
reduced resolution.
"""

from __future__ import annotations

import math
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest

from vizzy_runtime.ros import (
    Context,
    Node,
    Parameter,
    SingleThreadedExecutor,
)
from vizzy_runtime.testing import no_renderer, wait_until
from vizzy_sim_bridge.core import render as render_mod
from vizzy_sim_bridge.core.urdf import head_urdf
from vizzy_sim_bridge.sim_node import SimNode, box_corners, image_box
from vizzy_vision.camera import camera_matrix
from vizzy_vision.kinematics import (
    JOINT_LIMITS,
    JOINT_NAMES,
    frames_in_base,
    static_transforms,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sim_node_support import (  # noqa: E402
    OVERRIDES,
    TIMEOUT,
    Clock,
    Image,
    JointState,
)

pytestmark = pytest.mark.live  # also run on the real rclpy (scripts/test_ros.sh)


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
        no_renderer(str(exc))
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
