"""The `gaze_controller` node: arbitrates /gaze/command, moves the head, reports /gaze/state.

Topics (relative names; the resolved ones at the root namespace)
  in   /gaze/command          active_vision_msgs/GazeCommand   (reliable, depth 10)
  in   /joint_states          sensor_msgs/JointState           (best effort: any publisher QoS)
  in   /tf, /tf_static        tf2_msgs/TFMessage               (vizzy_runtime.tf, latched static)
  out  /vizzy/joint_commands  sensor_msgs/JointState (name + position setpoints, control_rate_hz
                              while they move; held still, every HOLD_RESEND_S)
  out  /gaze/state            active_vision_msgs/GazeState     (state_rate_hz, and per command)
  out  /diagnostics           diagnostic_msgs/DiagnosticArray  (about 1 Hz: input health)

What it does with a command (the ROS-free parts are in core/gaze.py):
1. Validation. NaN/inf (point, targets, hold_time) -> STATUS_REJECTED_NAN; a frame_id not in
   the tf tree -> REJECTED_UNKNOWN_FRAME; a point behind the head, too near or far, or beyond the
   joint limits -> REJECTED_UNREACHABLE; unknown mode/motion/joint or mismatched lengths ->
   REJECTED_INVALID. Joint targets beyond a joint's limits -> REJECTED_UNREACHABLE too (the head
   does not move for them). Joints a joint-target command does not name keep their target.
2. A fixation point is transformed into base_link (latest tf) and solved by inverse kinematics
   (core.gaze.solve_fixation: neck/eye split, then both eyes exactly on the point).
3. Arbitration (core.gaze.arbitrate): a higher priority always takes over, at once, even
   mid-saccade; at equal priority the newest command wins; a lower priority takes over only when
   the active command's saccade is over (trajectory done and settled) and its hold_time has passed
   since then. A losing command is not queued: senders re-send.
4. Motion. Saccade: a minimum-jerk trajectory from the current setpoint, its duration following
   the main sequence and stretched so no joint exceeds max_velocity_rad_s (capped by the
   kinematics' velocity limit). Pursuit: velocity-limited first-order tracking
   (pursuit_gain, pursuit_max_velocity_rad_s). The setpoints are streamed on
   /vizzy/joint_commands from the first accepted command on (before that the head is left alone):
   every control tick while they move; a setpoint that stays put (a fixation held) is sent again
   only every HOLD_RESEND_S, since a position-controlled joint holds its last target (the re-send
   covers a lost sample) and 100 setpoints a second of the same posture cost CPU in every reader.

How /gaze/state tells who won. status and status_message describe the most recent command:
- the command was accepted: STATUS_OK; active_source/active_priority are its own. If it took the
  eyes from another source, status_message says "preempted '<source>' (priority N)": that source
  (the loser) sees active_source is no longer itself.
- the command lost arbitration: STATUS_PREEMPTED, status_message
  "'<loser>' (priority N) lost to '<winner>' (priority M), which holds the gaze ...", and
  active_source stays the winner. A state is published right after every command, so each
  outcome is on the wire even when commands come faster than state_rate_hz.
So a sender knows it is being served while active_source equals its own source.

Refused inputs (vizzy_runtime.input_health.InputHealth, self.input_health) are counted per
(resolved topic, reason), the first of each logged in one line, then at most every 5 s per reason
with the count so far, and published on /diagnostics (WARN while refusals happen):
- /gaze/command: every command answered with a REJECTED_* status, the reason being the status
  name ('REJECTED_NAN', 'REJECTED_UNKNOWN_FRAME', 'REJECTED_UNREACHABLE', 'REJECTED_INVALID';
  a command the handler fails on is REJECTED_INVALID), the detail its status_message and source.
  A command that lost arbitration (PREEMPTED) was valid input: it counts as accepted, as does
  every STATUS_OK one. GazeState still reports each command's status as above.
- /joint_states: 'length mismatch' (name and position lengths differ: the message is dropped);
  'non-finite position' (a NaN/inf position of a head joint: those values are skipped, the
  message's finite ones still used). Other messages count as accepted; names of joints that are
  not the head's are ignored, not refused.
- on either topic, '<what>: <ExcType>' for an exception escaping the callback (guarded(topic=)).
/tf and /tf_static are taken by vizzy_runtime.tf's listener, which counts nothing here.

in_saccade is true from the start of a saccade until the trajectory has ended and the measured
/joint_states are within settle_tolerance_rad of the target (or settle_timeout_s after the end,
or at once without joint states). fixation_point is the accepted fixation (for joint targets,
where their optical axes meet), in base_link. version/vergence/tilt come from /joint_states
(kinematics.gaze_angles), or from the setpoint until joint states arrive.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from vizzy_gaze.core.gaze import (
    BASE_FRAME,
    Claim,
    GazeError,
    GazeSplit,
    GazeStatus,
    MinimumJerk,
    arbitrate,
    check_finite_point,
    fixation_point,
    home_posture,
    joint_targets,
    pursuit_step,
    saccade_duration,
    solve_fixation,
    velocity_limits,
)
from vizzy_runtime.input_health import InputHealth
from vizzy_runtime.node_tools import Param, declare_parameters, guarded, main_for, replace_timer
from vizzy_runtime.ros import Node, message, qos_profile_sensor_data
from vizzy_runtime.tf import TransformBuffer, TransformListener
from vizzy_vision import kinematics

GazeCommand = message('active_vision_msgs/msg/GazeCommand')
GazeState = message('active_vision_msgs/msg/GazeState')
JointState = message('sensor_msgs/msg/JointState')

# Relative names: the node's namespace (or remapping) places them; logs print the resolved ones.
COMMAND_TOPIC = 'gaze/command'
STATE_TOPIC = 'gaze/state'
JOINT_STATES_TOPIC = 'joint_states'
JOINT_COMMANDS_TOPIC = 'vizzy/joint_commands'

_VMAX = float(np.max(velocity_limits()))
# A step of the clock between control ticks beyond this [s] (or backwards) is a jump, not a delay.
_CLOCK_JUMP_S = 1.0
# a setpoint that moved less than this since it was last sent [rad] is the same posture, sent
# again only every HOLD_RESEND_S [s]
HOLD_TOLERANCE_RAD = 1e-6
HOLD_RESEND_S = 0.1

# The node declares exactly these; each range is the descriptor's, enforced by the middleware.
PARAMETERS: tuple[Param, ...] = (
    Param('control_rate_hz', 100.0,
          f'Rate of joint position setpoints on {JOINT_COMMANDS_TOPIC} [Hz], in [1, 1000] '
          '(slower, a saccade would take minutes to settle).', '[1, 1000]'),
    Param('state_rate_hz', 30.0,
          f'Rate of {STATE_TOPIC} [Hz], in [0.1, 1000]; a state also goes out after every '
          'command.', '[0.1, 1000]'),
    Param('eye_pan_comfort_rad', 0.35,
          'Neck/eye split: the eyes take a pan (version) up to this on their own, the neck pan '
          'the rest [rad], in [0, 1.6].', '[0, 1.6]'),
    Param('eye_tilt_comfort_rad', 0.25,
          'Neck/eye split: the eyes tilt up to this on their own, the neck tilt the rest '
          '[rad], in [0, 1.6].', '[0, 1.6]'),
    Param('neck_share', 0.0,
          'Neck/eye split: fraction of the comfortable part the neck takes as well, in [0, 1].',
          '[0, 1]'),
    Param('min_fixation_distance_m', 0.15,
          'Nearest accepted fixation point, from the midpoint of the camera centres [m], in '
          '(0, 1000].', '(0, 1000]', constraints='below max_fixation_distance_m'),
    Param('max_fixation_distance_m', 10.0,
          'Farthest accepted fixation point, from the midpoint of the camera centres [m], in '
          '(0, 1000]; also where a joint-target gaze with parallel axes is said to fixate.',
          '(0, 1000]', constraints='above min_fixation_distance_m'),
    Param('saccade_min_duration_s', 0.05,
          'Main sequence: duration of the smallest saccade [s], in [0, 2].', '[0, 2]'),
    Param('saccade_s_per_rad', 0.15,
          'Main sequence: added duration per radian of the largest joint displacement '
          '[s/rad], in [0, 10].', '[0, 10]'),
    Param('max_velocity_rad_s', _VMAX,
          f'Peak joint velocity of a saccade [rad/s], in (0, {_VMAX:g}] (the kinematics '
          'velocity limit).', f'(0, {_VMAX!r}]'),
    Param('pursuit_gain', 8.0,
          'Smooth pursuit: velocity per radian of error [1/s], in (0, 1000].', '(0, 1000]'),
    Param('pursuit_max_velocity_rad_s', 1.0,
          f'Smooth pursuit: peak joint velocity [rad/s], in (0, {_VMAX:g}].', f'(0, {_VMAX!r}]'),
    Param('settle_tolerance_rad', 0.01,
          'A saccade ends when every measured joint is this close to its target [rad], in '
          '(0, 1].', '(0, 1]'),
    Param('settle_timeout_s', 0.3,
          'A saccade ends at the latest this long after its trajectory [s], in [0, 10].',
          '[0, 10]'),
)


def check_parameters(values: dict[str, Any]) -> str | None:
    """What is wrong with the parameters taken together, or None."""
    if values['min_fixation_distance_m'] >= values['max_fixation_distance_m']:
        return 'min_fixation_distance_m must be < max_fixation_distance_m'
    return None


class GazeControllerNode(Node):
    """Arbitrates gaze commands, solves the head/eye IK, streams setpoints, reports the gaze."""

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__('gaze_controller', **node_kwargs)
        self._p = declare_parameters(self, PARAMETERS, check_all=check_parameters,
                                     on_change=self._on_parameters_changed)
        # Times are seconds since this epoch: floats near 1.8e9 s (the Unix time) resolve only
        # 0.24 us, enough to blur the velocity of a 10 ms step by 1e-5.
        self._epoch_ns = self.get_clock().now().nanoseconds
        self._names = list(kinematics.JOINT_NAMES)
        self._vlimit = velocity_limits()

        self._setpoint: np.ndarray | None = None     # None: no command yet, head left alone
        self._target = home_posture()
        self._trajectory: MinimumJerk | None = None
        self._pursuit = False
        self._in_saccade = False
        self._settle_deadline = math.inf
        self._last_tick: float | None = None
        self._last_sent: tuple[np.ndarray, float] | None = None   # setpoint and time last sent
        self._measured: np.ndarray | None = None
        self._measured_mask = np.zeros(len(self._names), dtype=bool)
        self._claim: Claim | None = None
        self._fixation = fixation_point(self._target, self._p['max_fixation_distance_m'])
        self._status, self._status_message = GazeStatus.IDLE, 'no command yet'
        # refused inputs, per topic and reason, on /diagnostics; before any subscription
        self.input_health = InputHealth(self)

        self.tf_buffer = TransformBuffer()
        self._tf_listener = TransformListener(self.tf_buffer, self)
        self._state_pub = self.create_publisher(GazeState, STATE_TOPIC, 10)
        self._command_pub = self.create_publisher(JointState, JOINT_COMMANDS_TOPIC, 10)
        self._gaze_topic = self.resolve_topic_name(COMMAND_TOPIC)   # for logs and counters
        self._joint_states_topic = self.resolve_topic_name(JOINT_STATES_TOPIC)
        self._gaze_sub = self.create_subscription(GazeCommand, COMMAND_TOPIC, guarded(
            self, 'failed on a command', self._on_command, topic=self._gaze_topic), 10)
        self._joint_states_sub = self.create_subscription(JointState, JOINT_STATES_TOPIC, guarded(
            self, 'skipped a message', self._on_joint_states, topic=self._joint_states_topic),
            qos_profile_sensor_data)
        self._control_timer = self.create_timer(
            1.0 / self._p['control_rate_hz'],
            guarded(self, 'control step failed', self._on_control))
        self._state_timer = self.create_timer(
            1.0 / self._p['state_rate_hz'], guarded(self, 'state failed', self._publish_state))
        self.get_logger().info(
            f'gaze controller: {self._gaze_sub.topic_name} -> {self._command_pub.topic_name} at '
            f'{self._p["control_rate_hz"]:g} Hz, {self._state_pub.topic_name} at '
            f'{self._p["state_rate_hz"]:g} Hz (joint states from '
            f'{self._joint_states_sub.topic_name}); '
            f'saccades up to {self._p["max_velocity_rad_s"]:g} rad/s')

    # --- inputs -----------------------------------------------------------------------------------

    def _seconds(self, nanoseconds: int) -> float:
        return (nanoseconds - self._epoch_ns) * 1e-9

    def _now(self) -> float:
        return self._seconds(self.get_clock().now().nanoseconds)

    def _on_joint_states(self, msg: Any) -> None:
        topic = self._joint_states_topic
        names, positions = list(msg.name), list(msg.position)
        if len(names) != len(positions):
            self.input_health.refuse(topic, 'length mismatch',
                                     f'{len(names)} names but {len(positions)} positions')
            return
        measured = (self._measured.copy() if self._measured is not None
                    else (self._setpoint.copy() if self._setpoint is not None else home_posture()))
        skipped = []
        for name, value in zip(names, positions, strict=True):
            if name not in self._names:
                continue   # another joint of the robot
            if not math.isfinite(value):
                skipped.append(f'{name}={value}')
                continue
            i = self._names.index(name)
            measured[i] = float(value)
            self._measured_mask[i] = True
        if self._measured_mask.any():
            self._measured = measured
        if skipped:   # the message's finite positions are still used
            self.input_health.refuse(topic, 'non-finite position', ', '.join(skipped))
        else:
            self.input_health.accept(topic)

    def _current(self) -> np.ndarray:
        """Where the head is commanded to be (or measured, or home, before the first command)."""
        if self._setpoint is not None:
            return self._setpoint.copy()
        if self._measured is not None:
            return self._measured.copy()
        return home_posture()

    def _reject(self, cmd: Any, error: GazeError) -> None:
        """Report the refusal on /gaze/state (status) and count it (logged, then throttled)."""
        self._status, self._status_message = error.status, str(error)
        self.input_health.refuse(self._gaze_topic, error.status.name,
                                 f'{error} (source {str(cmd.source) or "<none>"!r})')

    def _on_command(self, cmd: Any) -> None:
        try:
            self._handle_command(cmd)
        except GazeError as error:
            self._reject(cmd, error)
        except Exception as exc:  # malformed message: report it, keep running
            self._reject(cmd, GazeError(GazeStatus.REJECTED_INVALID,
                                        f'{type(exc).__name__}: {exc}'))
        else:   # STATUS_OK or PREEMPTED: valid input either way
            self.input_health.accept(self._gaze_topic)
        self._publish_state()

    def _handle_command(self, cmd: Any) -> None:
        if cmd.motion not in (GazeCommand.MOTION_SACCADE, GazeCommand.MOTION_PURSUIT):
            raise GazeError(GazeStatus.REJECTED_INVALID,
                            f'unknown motion {cmd.motion} (MOTION_SACCADE=0, MOTION_PURSUIT=1)')
        hold = float(cmd.hold_time)
        if not math.isfinite(hold):
            raise GazeError(GazeStatus.REJECTED_NAN, f'hold_time is {hold}')
        if hold < 0.0:
            raise GazeError(GazeStatus.REJECTED_INVALID, f'hold_time must be >= 0, got {hold}')
        if cmd.mode == GazeCommand.MODE_FIXATION_POINT:
            point = check_finite_point((cmd.fixation_point.x, cmd.fixation_point.y,
                                        cmd.fixation_point.z))
            frame = cmd.header.frame_id
            if not frame:
                raise GazeError(GazeStatus.REJECTED_UNKNOWN_FRAME, 'header.frame_id is empty')
            try:
                point = self.tf_buffer.transform_points(BASE_FRAME, frame, point)
            except LookupError as exc:
                raise GazeError(GazeStatus.REJECTED_UNKNOWN_FRAME, str(exc)) from None
            solution = solve_fixation(
                point, GazeSplit(self._p['eye_pan_comfort_rad'], self._p['eye_tilt_comfort_rad'],
                                 self._p['neck_share']),
                self._p['min_fixation_distance_m'], self._p['max_fixation_distance_m'])
            target, fixation = solution.joints, solution.point
        elif cmd.mode == GazeCommand.MODE_JOINT_TARGETS:
            reference = self._target if self._setpoint is not None else self._current()
            target = joint_targets(list(cmd.joint_names), list(cmd.joint_positions), reference)
            fixation = fixation_point(target, self._p['max_fixation_distance_m'])
        else:
            raise GazeError(GazeStatus.REJECTED_INVALID,
                            f'unknown mode {cmd.mode} (MODE_FIXATION_POINT=0, '
                            'MODE_JOINT_TARGETS=1)')

        now = self._now()
        source, priority = str(cmd.source), int(cmd.priority)
        lost = arbitrate(self._claim, source, priority, now)
        if lost is not None:
            self._status, self._status_message = GazeStatus.PREEMPTED, lost
            self.get_logger().debug(f'{self._gaze_topic}: {lost}')
            return
        previous = self._claim
        self._start_motion(target, cmd.motion == GazeCommand.MOTION_SACCADE, now)
        self._claim = Claim(source, priority, now, hold,
                            reached=None if self._in_saccade else now)
        self._fixation = fixation
        notes = []
        if previous is not None and previous.source != source and previous.held(now):
            notes.append(f'preempted {previous.source!r} (priority {previous.priority})')
        self._status, self._status_message = GazeStatus.OK, '; '.join(notes)

    # --- motion -----------------------------------------------------------------------------------

    def _start_motion(self, target: np.ndarray, saccade: bool, now: float) -> None:
        # from where the running trajectory is now (not where it was at the last tick)
        start = (self._trajectory.position(now) if self._trajectory is not None
                 else self._current())
        self._target = target.copy()
        self._last_tick = now
        vmax = np.minimum(self._vlimit, self._p['max_velocity_rad_s'])
        if saccade:
            self._pursuit = False
            duration = saccade_duration(start, target, vmax, self._p['saccade_min_duration_s'],
                                        self._p['saccade_s_per_rad'])
            self._trajectory = MinimumJerk(start, target.copy(), now, duration)
            self._in_saccade = duration > 0.0
            self._settle_deadline = math.inf
        else:
            self._trajectory = None
            self._pursuit = True
            self._in_saccade = False
        self._setpoint = start

    def _on_control(self) -> None:
        if self._setpoint is None:
            return
        clock_now = self.get_clock().now()
        now = self._seconds(clock_now.nanoseconds)  # the setpoint's time is also its stamp
        if self._last_tick is not None and not 0.0 <= now - self._last_tick <= _CLOCK_JUMP_S:
            self._on_clock_jump(now, self._last_tick)
        if self._trajectory is not None:
            self._setpoint = self._trajectory.position(now)
            if self._trajectory.done(now):
                self._setpoint = self._trajectory.q1.copy()
                self._trajectory = None
                self._settle_deadline = now + self._p['settle_timeout_s']
        elif self._pursuit and self._last_tick is not None:
            self._setpoint = pursuit_step(
                self._setpoint, self._target, min(now - self._last_tick, 0.1),
                self._p['pursuit_gain'],
                np.minimum(self._vlimit, self._p['pursuit_max_velocity_rad_s']))
        self._last_tick = now
        sent = self._last_sent
        if (sent is None or not 0.0 <= now - sent[1] < HOLD_RESEND_S
                or np.max(np.abs(self._setpoint - sent[0])) > HOLD_TOLERANCE_RAD):
            msg = JointState(name=list(self._names), position=[float(v) for v in self._setpoint])
            msg.header.stamp = clock_now.to_msg()
            self._command_pub.publish(msg)
            self._last_sent = (self._setpoint.copy(), now)
        if self._in_saccade and self._trajectory is None and self._settled(now):
            self._in_saccade = False
            if self._claim is not None and self._claim.reached is None:
                self._claim = dataclasses.replace(self._claim, reached=now)
            self._publish_state()

    def _on_clock_jump(self, now: float, last_tick: float) -> None:
        """The clock jumped (sim time reset, bag looped, use_sim_time changed): carry on from
        where the motion was, rather than jump the head to wherever the new time would say."""
        shift = now - last_tick - 1.0 / self._p['control_rate_hz']
        self.get_logger().info(f'the clock jumped by {shift:+.3f} s; motion continues from '
                               'where it was', throttle_duration_sec=5.0)
        if self._trajectory is not None:
            self._trajectory = dataclasses.replace(self._trajectory,
                                                   t0=self._trajectory.t0 + shift)
        self._settle_deadline += shift
        if self._claim is not None:
            self._claim = dataclasses.replace(
                self._claim, accepted=self._claim.accepted + shift,
                reached=None if self._claim.reached is None else self._claim.reached + shift)
        self._last_tick = now - 1.0 / self._p['control_rate_hz']

    def _settled(self, now: float) -> bool:
        if self._measured is None or now >= self._settle_deadline:
            return True
        error = np.abs(self._measured - self._target)[self._measured_mask]
        return bool(np.all(error <= self._p['settle_tolerance_rad']))

    # --- output -----------------------------------------------------------------------------------

    def _publish_state(self) -> None:
        state = GazeState(in_saccade=bool(self._in_saccade),
                          status=getattr(GazeState, f'STATUS_{self._status.name}'),
                          status_message=self._status_message)
        state.header.stamp = self.get_clock().now().to_msg()
        state.header.frame_id = BASE_FRAME
        state.fixation_point.x, state.fixation_point.y, state.fixation_point.z = (
            float(c) for c in self._fixation)
        if self._claim is not None:
            state.active_source, state.active_priority = self._claim.source, self._claim.priority
        joints = self._measured if self._measured is not None else self._current()
        state.version, state.vergence, state.tilt = (
            float(a) for a in kinematics.gaze_angles([float(v) for v in joints]))
        self._state_pub.publish(state)

    def _on_parameters_changed(self, changed: dict[str, Any]) -> None:
        if 'control_rate_hz' in changed:
            self._control_timer = replace_timer(
                self, self._control_timer, 1.0 / changed['control_rate_hz'],
                guarded(self, 'control step failed', self._on_control))
        if 'state_rate_hz' in changed:
            self._state_timer = replace_timer(
                self, self._state_timer, 1.0 / changed['state_rate_hz'],
                guarded(self, 'state failed', self._publish_state))


main = main_for(GazeControllerNode)


if __name__ == '__main__':
    main()
