"""The gaze_controller node on the bundled runtime, against a fake head.

The fake head (a node in the test) publishes /tf_static, /tf and /joint_states from
core.kinematics, and moves instantly to every setpoint it receives on /vizzy/joint_commands.
Nothing here asserts on wall-clock time: the tests wait for conditions.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from vizzy_gaze.core.gaze import (
    LEFT_OPTICAL_FRAME,
    RIGHT_OPTICAL_FRAME,
    GazeSplit,
    home_posture,
    joint_limits,
    solve_fixation,
    velocity_limits,
)
from vizzy_gaze.gaze_controller_node import HOLD_RESEND_S, PARAMETERS, GazeControllerNode
from vizzy_runtime.ros import Context, Node, Parameter, message, qos_profile_latched
from vizzy_runtime.testing import publish_until, scaled, spinning, wait_until
from vizzy_runtime.tf import TF_STATIC_TOPIC, TF_TOPIC
from vizzy_vision import kinematics

pytestmark = pytest.mark.live  # also run on the real rclpy (scripts/test_ros.sh)

GazeCommand = message('active_vision_msgs/msg/GazeCommand')
GazeState = message('active_vision_msgs/msg/GazeState')
JointState = message('sensor_msgs/msg/JointState')
TFMessage = message('tf2_msgs/msg/TFMessage')
TransformStamped = message('geometry_msgs/msg/TransformStamped')

TIMEOUT = scaled(20.0)
DEFAULTS = {p.name: p.default for p in PARAMETERS}
NAMES = list(kinematics.JOINT_NAMES)
FX = 320.0 / math.tan(math.radians(85.4) / 2)


def _tf(transforms: list[Any]) -> Any:
    out = []
    for t in transforms:
        msg = TransformStamped(child_frame_id=t.child)
        msg.header.frame_id = t.parent
        tr, rot = msg.transform.translation, msg.transform.rotation
        tr.x, tr.y, tr.z = (float(v) for v in t.translation)
        rot.x, rot.y, rot.z, rot.w = (float(v) for v in t.rotation)
        out.append(msg)
    return TFMessage(transforms=out)


class FakeHead(Node):
    """Publishes the head's tf and joint states; jumps to each setpoint it is sent, and sends
    the test's gaze commands. On the controller's resolved topic names."""

    def __init__(self, context: Context, controller: Any) -> None:
        super().__init__('fake_head', context=context, start_parameter_services=False)
        self.joints = home_posture()
        self.commands: list[tuple[int, np.ndarray]] = []   # (stamp [ns], positions)
        self.states: list[Any] = []
        self.static_pub = self.create_publisher(
            TFMessage, controller.resolve_topic_name(TF_STATIC_TOPIC), qos_profile_latched)
        self.tf_pub = self.create_publisher(TFMessage, controller.resolve_topic_name(TF_TOPIC), 100)
        self.joint_pub = self.create_publisher(
            JointState, controller._joint_states_sub.topic_name, 10)
        self.command_pub = self.create_publisher(GazeCommand, controller._gaze_sub.topic_name, 10)
        self.create_subscription(JointState, controller._command_pub.topic_name,
                                 self._on_command, 100)
        self.create_subscription(GazeState, controller._state_pub.topic_name,
                                 self.states.append, 100)
        self.static_pub.publish(_tf(kinematics.static_transforms()))
        self.create_timer(0.02, self.publish_joints)  # like a robot: joint states and tf at 50 Hz

    def publish_joints(self) -> None:
        self.tf_pub.publish(_tf(kinematics.joint_transforms([float(v) for v in self.joints])))
        self.joint_pub.publish(JointState(name=NAMES, position=[float(v) for v in self.joints]))

    def _on_command(self, msg: Any) -> None:
        assert list(msg.name) == NAMES
        self.joints = np.array(msg.position, dtype=float)
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        self.commands.append((stamp, self.joints.copy()))
        self.publish_joints()

    def send(self, **fields: Any) -> None:
        frame = fields.pop('frame_id', 'base_link')
        point = fields.pop('point', None)
        cmd = GazeCommand(**fields)
        cmd.header.frame_id = frame
        if point is not None:
            cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z = point
        self.command_pub.publish(cmd)

    def state_after(self, n: int, predicate: Callable[[Any], bool]) -> Any:
        return next((s for s in self.states[n:] if predicate(s)), None)


@pytest.fixture
def head_and_controller(context):
    controller = GazeControllerNode(context=context)
    head = FakeHead(context, controller)
    with spinning(context, [head, controller],
                  lambda: head.command_pub.get_subscription_count() > 0
                  and controller.tf_buffer.can_transform('base_link', 'ego')
                  and controller.tf_buffer.can_transform('base_link', LEFT_OPTICAL_FRAME)
                  and len(head.states) > 0, TIMEOUT) as executor:
        yield head, controller, executor


def _wait_status(head: FakeHead, spin: Any, n: int, status: int, words: str = '',
                 source: str | None = None) -> Any:
    """The first state after the n-th with this status, words in its message and (if given)
    this active source. States go out periodically too, so the status alone may still be the
    previous command's."""
    def match(s: Any) -> bool:
        return (s.status == status and words in s.status_message
                and (source is None or s.active_source == source))

    assert wait_until(lambda: head.state_after(n, match) is not None, TIMEOUT, spin=spin), (
        status, words, source, [(s.status, s.status_message) for s in head.states[n:]])
    return head.state_after(n, match)


def test_a_saccade_to_a_point_in_another_frame_reaches_the_ik_solution(head_and_controller):
    head, controller, spin = head_and_controller
    # before any command: idle, and the head is left alone (no setpoints)
    assert head.states[-1].status == GazeState.STATUS_IDLE and not head.commands
    point_ego = np.array([1.0, 0.25, -0.1])
    ego = kinematics.frames_in_base([0.0] * len(NAMES))['ego']
    point = ego[:3, :3] @ point_ego + ego[:3, 3]
    expected = solve_fixation(point, GazeSplit(DEFAULTS['eye_pan_comfort_rad'],
                                               DEFAULTS['eye_tilt_comfort_rad'],
                                               DEFAULTS['neck_share']),
                              DEFAULTS['min_fixation_distance_m'],
                              DEFAULTS['max_fixation_distance_m']).joints
    n = len(head.states)
    head.send(point=point_ego, frame_id='ego', source='test', priority=1,
              motion=GazeCommand.MOTION_SACCADE, mode=GazeCommand.MODE_FIXATION_POINT)
    started = _wait_status(head, spin, n, GazeState.STATUS_OK, source='test')
    assert started.in_saccade and started.active_source == 'test'
    assert started.active_priority == 1 and started.header.frame_id == 'base_link'
    np.testing.assert_allclose([started.fixation_point.x, started.fixation_point.y,
                                started.fixation_point.z], point, atol=1e-9)
    # the setpoints move to the IK solution, then the saccade ends
    assert wait_until(lambda: head.commands and np.allclose(head.commands[-1][1], expected,
                                                            atol=1e-12), TIMEOUT, spin=spin)
    first = head.states.index(started)
    assert wait_until(lambda: head.state_after(first, lambda s: not s.in_saccade) is not None,
                      TIMEOUT, spin=spin)
    settled = head.state_after(first, lambda s: not s.in_saccade)
    assert settled.status == GazeState.STATUS_OK and settled.active_source == 'test'
    # within settle_tolerance_rad of the target: the saccade is over
    measured = kinematics.gaze_angles([float(v) for v in expected])
    assert np.allclose((settled.version, settled.vergence, settled.tilt), measured,
                       atol=2 * DEFAULTS['settle_tolerance_rad'])
    # version, vergence and tilt follow the joint states: once there, exactly the target's
    assert wait_until(lambda: np.allclose((head.states[-1].version, head.states[-1].vergence,
                                           head.states[-1].tilt), measured, atol=1e-12),
                      TIMEOUT, spin=spin)
    # the setpoints: within the limits, monotonically closer, never faster than the limit
    lo, hi = joint_limits()
    stamps = np.array([t for t, _ in head.commands], dtype=np.int64)
    q = np.array([p for _, p in head.commands])
    assert np.all(q >= lo - 1e-12) and np.all(q <= hi + 1e-12)
    distance = np.abs(q - expected).max(axis=1)
    assert np.all(np.diff(distance) <= 1e-12)
    dt, dq = np.diff(stamps) * 1e-9, np.abs(np.diff(q, axis=0))
    moving = dt > 0
    assert np.all(dq[~moving] <= 1e-12)  # same stamp, same setpoint
    assert np.all(dq[moving] <= velocity_limits() * dt[moving, None] * (1 + 1e-6) + 1e-12)
    # and the point is at both principal points
    poses = kinematics.frames_in_base([float(v) for v in head.commands[-1][1]])
    for frame in (LEFT_OPTICAL_FRAME, RIGHT_OPTICAL_FRAME):
        x, y, z = poses[frame][:3, :3].T @ (point - poses[frame][:3, 3])
        assert z > 0 and abs(FX * x / z) < 2.0 and abs(FX * y / z) < 2.0
    # held there, the same setpoint goes out again about every HOLD_RESEND_S, not every tick
    held = len(head.commands)
    wait_until(lambda: False, 1.0, spin=spin)                # spin for a second
    resent = head.commands[held:]
    assert 1 <= len(resent) <= 1.0 / HOLD_RESEND_S + 5       # 100 at control_rate_hz
    assert all(np.array_equal(p, expected) for _, p in resent)


def test_bad_commands_are_rejected_and_reported(head_and_controller):
    head, controller, spin = head_and_controller
    base = {'source': 'test', 'priority': 0, 'motion': GazeCommand.MOTION_SACCADE}
    cases = [
        (dict(point=(math.nan, 0.0, 1.0), frame_id='ego'), GazeState.STATUS_REJECTED_NAN,
         'fixation_point.x is nan'),
        (dict(point=(1.0, 0.0, 0.0), frame_id='nowhere'), GazeState.STATUS_REJECTED_UNKNOWN_FRAME,
         "'nowhere'"),
        (dict(point=(1.0, 0.0, 0.0), frame_id=''), GazeState.STATUS_REJECTED_UNKNOWN_FRAME,
         'frame_id is empty'),
        (dict(point=(-2.0, 0.0, 0.0), frame_id='ego'), GazeState.STATUS_REJECTED_UNREACHABLE,
         'behind the head'),
        (dict(point=(1.0, 0.0, 0.0), frame_id='ego', motion=7), GazeState.STATUS_REJECTED_INVALID,
         'unknown motion 7'),
        (dict(mode=GazeCommand.MODE_JOINT_TARGETS, joint_names=['elbow'], joint_positions=[0.1]),
         GazeState.STATUS_REJECTED_INVALID, "unknown joints ['elbow']"),
        (dict(mode=GazeCommand.MODE_JOINT_TARGETS, joint_names=['l_eye_joint'],
              joint_positions=[0.1, 0.2]), GazeState.STATUS_REJECTED_INVALID, '1 joint_names'),
        (dict(point=(1.0, 0.0, 0.0), frame_id='ego', hold_time=-1.0),
         GazeState.STATUS_REJECTED_INVALID, 'hold_time must be >= 0'),
        (dict(point=(1.0, 0.0, 0.0), frame_id='ego', hold_time=math.inf),
         GazeState.STATUS_REJECTED_NAN, 'hold_time is inf'),
    ]
    for fields, status, words in cases:
        n = len(head.states)
        head.send(**{**base, **fields})
        state = _wait_status(head, spin, n, status, words)
        assert state.active_source == ''  # nothing accepted
    assert not head.commands  # the head was never moved
    # out-of-range joint targets are refused (GazeState.msg): the head does not move for them
    lo, hi = joint_limits()
    i = NAMES.index('l_eye_joint')
    n = len(head.states)
    head.send(**base, mode=GazeCommand.MODE_JOINT_TARGETS,
              joint_names=['l_eye_joint', 'neck_pan_joint'], joint_positions=[5.0, 0.1])
    state = _wait_status(head, spin, n, GazeState.STATUS_REJECTED_UNREACHABLE,
                         'l_eye_joint target 5.0000 rad outside its limits')
    assert state.active_source == '' and not head.commands
    # on the limit: accepted and driven to
    n = len(head.states)
    head.send(**base, mode=GazeCommand.MODE_JOINT_TARGETS, joint_names=['l_eye_joint'],
              joint_positions=[hi[i]])
    _wait_status(head, spin, n, GazeState.STATUS_OK, source='test')
    assert wait_until(lambda: head.commands and head.commands[-1][1][i] == hi[i], TIMEOUT,
                      spin=spin)


def test_arbitration_priority_hold_and_recency(head_and_controller):
    head, controller, spin = head_and_controller
    ahead = (1.5, 0.0, 0.0)
    n = len(head.states)
    head.send(point=ahead, frame_id='ego', source='mot_planner', priority=5, hold_time=60.0)
    accepted = _wait_status(head, spin, n, GazeState.STATUS_OK, source='mot_planner')
    # lower priority: refused while mot_planner holds (its saccade, then 60 s)
    n = len(head.states)
    head.send(point=(1.5, 0.3, 0.0), frame_id='ego', source='foveation', priority=1)
    lost = _wait_status(head, spin, n, GazeState.STATUS_PREEMPTED,
                        "'foveation' (priority 1) lost to 'mot_planner' (priority 5)")
    assert lost.active_source == 'mot_planner' and lost.active_priority == 5
    assert lost.fixation_point.y == accepted.fixation_point.y  # still the accepted fixation
    # equal priority: the newest wins, and says whom it preempted
    n = len(head.states)
    head.send(point=(1.5, -0.3, 0.0), frame_id='ego', source='stereo_ses', priority=5)
    _wait_status(head, spin, n, GazeState.STATUS_OK, "preempted 'mot_planner' (priority 5)",
                 source='stereo_ses')
    # higher priority: takes over at once
    n = len(head.states)
    head.send(point=ahead, frame_id='ego', source='user', priority=9,
              motion=GazeCommand.MOTION_PURSUIT)
    won = _wait_status(head, spin, n, GazeState.STATUS_OK, source='user')
    assert won.active_priority == 9 and not won.in_saccade


def test_pursuit_moves_smoothly_without_a_saccade(head_and_controller):
    head, controller, spin = head_and_controller
    vmax = DEFAULTS['pursuit_max_velocity_rad_s']
    n = len(head.states)
    head.send(point=(1.2, 0.3, 0.1), frame_id='ego', source='tracker', priority=0,
              motion=GazeCommand.MOTION_PURSUIT)
    _wait_status(head, spin, n, GazeState.STATUS_OK, source='tracker')
    assert wait_until(lambda: len(head.commands) > 20, TIMEOUT, spin=spin)
    assert not any(s.in_saccade for s in head.states[n:])
    stamps = np.array([t for t, _ in head.commands], dtype=np.int64)
    q = np.array([p for _, p in head.commands])
    dt, dq = np.diff(stamps) * 1e-9, np.abs(np.diff(q, axis=0))
    assert np.all(dq <= vmax * np.minimum(dt, 0.1)[:, None] * (1 + 1e-6) + 1e-12)
    assert np.abs(q[-1] - q[0]).max() > 0.0


def test_rates_can_be_changed_at_run_time(head_and_controller):
    head, controller, spin = head_and_controller
    result = controller.set_parameters([Parameter('state_rate_hz', value=50.0)])[0]
    assert result.successful
    n = len(head.states)
    assert wait_until(lambda: len(head.states) > n + 3, TIMEOUT, spin=spin)
    too_fast = controller.set_parameters([Parameter('max_velocity_rad_s', value=50.0)])[0]
    assert not too_fast.successful and 'max_velocity_rad_s' in too_fast.reason


def test_refused_inputs_are_counted_per_topic_and_reason(head_and_controller, capfd):
    """Bad joint states and bad commands are counted by InputHealth per (topic, reason), and the
    valid input right after them is processed; nothing escapes a callback (an escaped exception
    would be counted as '<what>: <ExcType>' on its topic, or end the spin)."""
    head, controller, spin = head_and_controller
    health = controller.input_health
    commands = controller._gaze_sub.topic_name
    joint_states = controller._joint_states_sub.topic_name

    # /joint_states (before any command: the head stays where the test puts it). Best effort: each
    # bad message is sent again until counted, since a sample may be dropped.
    bad_states = {
        'length mismatch': JointState(name=NAMES, position=[0.0, 0.1]),
        'non-finite position': JointState(name=NAMES,
                                          position=[math.nan] + [0.0] * (len(NAMES) - 1)),
    }
    sent = dict.fromkeys(bad_states, 0)
    for reason, msg in bad_states.items():
        def publish(reason: str = reason, msg: Any = msg) -> None:
            sent[reason] += 1
            head.joint_pub.publish(msg)
        assert publish_until(publish, lambda reason=reason: (joint_states, reason)
                             in health.refused(), spin, TIMEOUT), reason
    refused = health.refused()
    assert set(refused) == {(joint_states, reason) for reason in bad_states}, refused
    for reason, count in sent.items():
        assert 1 <= refused[(joint_states, reason)] <= count
    # the head's valid joint states right after are used: move it, the controller measures it
    accepted = health.accepted().get(joint_states, 0)
    moved = home_posture() + 0.05
    head.joints = moved.copy()
    assert wait_until(lambda: controller._measured is not None
                      and np.allclose(controller._measured, moved, atol=1e-12), TIMEOUT, spin=spin)
    assert health.accepted().get(joint_states, 0) > accepted
    assert health.refused() == refused

    # /gaze/command: reliable, depth 10, so every one arrives, in order; the reason is the status
    base = {'source': 'test', 'priority': 0, 'motion': GazeCommand.MOTION_SACCADE}
    bad = [
        (dict(point=(math.nan, 0.0, 1.0), frame_id='ego'), 'REJECTED_NAN'),
        (dict(point=(1.0, 0.0, 0.0), frame_id='ego', hold_time=math.inf), 'REJECTED_NAN'),
        (dict(point=(1.0, 0.0, 0.0), frame_id='nowhere'), 'REJECTED_UNKNOWN_FRAME'),
        (dict(point=(-2.0, 0.0, 0.0), frame_id='ego'), 'REJECTED_UNREACHABLE'),
        (dict(mode=GazeCommand.MODE_JOINT_TARGETS, joint_names=['l_eye_joint'],
              joint_positions=[5.0]), 'REJECTED_UNREACHABLE'),
        (dict(point=(1.0, 0.0, 0.0), frame_id='ego', motion=7), 'REJECTED_INVALID'),
        (dict(mode=GazeCommand.MODE_JOINT_TARGETS, joint_names=['elbow'],
              joint_positions=[0.1]), 'REJECTED_INVALID'),
    ]
    expected = dict(refused)
    for fields, reason in bad:
        head.send(**{**base, **fields})
        expected[(commands, reason)] = expected.get((commands, reason), 0) + 1
    # a valid command right after: accepted and driven to
    n = len(head.states)
    head.send(point=(1.5, 0.2, 0.0), frame_id='ego', source='good', priority=5, hold_time=60.0)
    _wait_status(head, spin, n, GazeState.STATUS_OK, source='good')
    assert wait_until(lambda: len(head.commands) > 0, TIMEOUT, spin=spin)
    assert health.refused() == expected
    assert health.accepted().get(commands) == 1
    # losing arbitration is no refusal of bad input: it counts as accepted
    n = len(head.states)
    head.send(point=(1.5, -0.2, 0.0), frame_id='ego', source='low', priority=1)
    _wait_status(head, spin, n, GazeState.STATUS_PREEMPTED, "'low' (priority 1) lost to 'good'")
    assert health.refused() == expected and health.accepted().get(commands) == 2

    # each reason logged (its first occurrence, then throttled), never as a traceback
    err = capfd.readouterr().err
    for reason in [r for _, r in bad] + list(bad_states):
        assert f': refused: {reason}' in err, (reason, err)
    assert 'Traceback' not in err, err
