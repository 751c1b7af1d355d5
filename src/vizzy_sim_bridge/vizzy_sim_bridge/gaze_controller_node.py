"""The `gaze_controller` node: arbitrates /gaze/command and reports /gaze/state.

Placeholder until the gaze-controller issue: it validates and arbitrates commands and
publishes the accepted fixation with saccade timing, but does not move the simulated joints
and has no inverse kinematics yet: version, vergence and tilt are those of the last joint-target
command, and fixation points are checked for distance only (no tf lookup of their frame).
"""

from __future__ import annotations

import math
from typing import Any

from vizzy_runtime.node_tools import declare_parameters, main_for, replace_timer
from vizzy_runtime.ros import Node, message
from vizzy_sim_bridge.core.gaze import (
    ActiveRequest, GazeStatus, check_fixation, check_joint_targets, preempts)
from vizzy_sim_bridge.core.kinematics import (
    JOINT_LIMITS, JOINT_NAMES, fixation_from_joints, gaze_angles)

GazeCommand = message('active_vision_msgs/msg/GazeCommand')
GazeState = message('active_vision_msgs/msg/GazeState')

COMMAND_TOPIC = '/gaze/command'
STATE_TOPIC = '/gaze/state'

# (name, default, description): the node declares exactly these.
PARAMETERS: tuple[tuple[str, Any, str], ...] = (
    ('rate_hz', 30.0, 'Rate of /gaze/state [Hz], in (0, 1000].'),
    ('saccade_duration_s', 0.1, 'How long in_saccade stays true after a new command [s], >= 0.'),
    ('min_fixation_distance_m', 0.1,
     'Nearest accepted fixation point, from the origin of its frame [m], > 0.'),
    ('max_fixation_distance_m', 10.0,
     'Farthest accepted fixation point, from the origin of its frame [m]; also the distance '
     'reported when the optical axes are parallel.'),
)


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is."""
    if name == 'rate_hz' and not 0.0 < value <= 1000.0:
        return f'rate_hz must be in (0, 1000], got {value}'
    if name == 'saccade_duration_s' and not 0.0 <= value <= 10.0:
        return f'saccade_duration_s must be in [0, 10] s, got {value}'
    if name in ('min_fixation_distance_m', 'max_fixation_distance_m') and not 0.0 < value <= 1e3:
        return f'{name} must be in (0, 1000] m, got {value}'
    return None


def check_parameters(values: dict[str, Any]) -> str | None:
    """What is wrong with the parameters taken together, or None."""
    if values['min_fixation_distance_m'] >= values['max_fixation_distance_m']:
        return 'min_fixation_distance_m must be < max_fixation_distance_m'
    return None


class GazeControllerNode(Node):
    """Validates and arbitrates gaze commands; publishes the gaze state."""

    def __init__(self) -> None:
        super().__init__('gaze_controller')
        self._p = declare_parameters(self, PARAMETERS, check_parameter,
                                     check_all=check_parameters,
                                     on_change=self._on_parameters_changed)

        home = [0.0] * len(JOINT_NAMES)
        self._fixation = fixation_from_joints(home, self._p['max_fixation_distance_m'])
        self._frame_id = 'base_link'
        self._angles = gaze_angles(home)
        self._active: ActiveRequest | None = None
        self._saccade_until = -math.inf
        self._status, self._status_message = GazeStatus.IDLE, 'no command yet'

        self._state_pub = self.create_publisher(GazeState, STATE_TOPIC, 10)
        self.create_subscription(GazeCommand, COMMAND_TOPIC, self._on_command, 10)
        self._timer = self.create_timer(1.0 / self._p['rate_hz'], self._on_timer)
        self.get_logger().info(
            f'arbitrating {COMMAND_TOPIC} (priority, then hold_time), publishing {STATE_TOPIC} at '
            f'{self._p["rate_hz"]} Hz; saccades last {self._p["saccade_duration_s"]} s')

    def _seconds(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _reject(self, status: GazeStatus, problem: str, cmd: Any) -> None:
        self._status, self._status_message = status, problem
        self.get_logger().warning(
            f'{COMMAND_TOPIC}: rejected command from {cmd.source or "<no source>"!r}: '
            f'{status.name}: {problem}')

    def _on_command(self, cmd: Any) -> None:
        try:
            self._handle_command(cmd)
        except Exception as exc:  # one bad message never kills the node
            self._reject(GazeStatus.REJECTED_INVALID, f'{type(exc).__name__}: {exc}', cmd)

    def _handle_command(self, cmd: Any) -> None:
        if cmd.motion not in (GazeCommand.MOTION_SACCADE, GazeCommand.MOTION_PURSUIT):
            return self._reject(GazeStatus.REJECTED_INVALID, f'unknown motion {cmd.motion}', cmd)
        if not math.isfinite(cmd.hold_time) or cmd.hold_time < 0.0:
            return self._reject(GazeStatus.REJECTED_INVALID,
                                f'hold_time must be finite and >= 0, got {cmd.hold_time}', cmd)
        if cmd.mode == GazeCommand.MODE_FIXATION_POINT:
            point = (cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z)
            status, problem = check_fixation(point, cmd.header.frame_id,
                                             self._p['min_fixation_distance_m'],
                                             self._p['max_fixation_distance_m'])
        elif cmd.mode == GazeCommand.MODE_JOINT_TARGETS:
            names = list(cmd.joint_names)
            positions = [float(v) for v in cmd.joint_positions]
            status, problem = check_joint_targets(names, positions, JOINT_LIMITS)
        else:
            status, problem = GazeStatus.REJECTED_INVALID, f'unknown mode {cmd.mode}'
        if status != GazeStatus.OK:
            return self._reject(status, problem, cmd)

        now = self._seconds()
        if not preempts(self._active, cmd.priority, now):
            self._status = GazeStatus.PREEMPTED
            self._status_message = (f'{cmd.source!r} (priority {cmd.priority}) lost to '
                                    f'{self._active.source!r} (priority {self._active.priority})')
            self.get_logger().debug(f'{COMMAND_TOPIC}: {self._status_message}')
            return None
        if cmd.mode == GazeCommand.MODE_FIXATION_POINT:
            self._fixation, self._frame_id = point, cmd.header.frame_id
        else:
            joints = dict(zip(JOINT_NAMES, [0.0] * len(JOINT_NAMES)))
            joints.update(zip(names, positions))
            self._fixation = fixation_from_joints(joints, self._p['max_fixation_distance_m'])
            self._frame_id = 'base_link'
            self._angles = gaze_angles(joints)
        self._active = ActiveRequest(cmd.source, int(cmd.priority), now, float(cmd.hold_time))
        if cmd.motion == GazeCommand.MOTION_SACCADE:
            self._saccade_until = now + self._p['saccade_duration_s']
        self._status, self._status_message = GazeStatus.OK, ''
        return None

    def _on_timer(self) -> None:
        now = self.get_clock().now()
        state = GazeState(in_saccade=now.nanoseconds * 1e-9 < self._saccade_until,
                          status=getattr(GazeState, f'STATUS_{self._status.name}'),
                          status_message=self._status_message)
        state.header.stamp = now.to_msg()
        state.header.frame_id = self._frame_id
        state.fixation_point.x, state.fixation_point.y, state.fixation_point.z = (
            float(c) for c in self._fixation)
        if self._active is not None:
            state.active_source, state.active_priority = self._active.source, self._active.priority
        state.version, state.vergence, state.tilt = (float(a) for a in self._angles)
        self._state_pub.publish(state)

    def _on_parameters_changed(self, changed: dict[str, Any]) -> None:
        if 'rate_hz' in changed:
            self._timer = replace_timer(self, self._timer, 1.0 / changed['rate_hz'],
                                        self._on_timer)


main = main_for(GazeControllerNode)


if __name__ == '__main__':
    main()
