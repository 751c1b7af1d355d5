"""The gaze controller without ROS: validation, arbitration, inverse kinematics, trajectories.

Everything about the head's geometry comes from core.kinematics (JOINT_NAMES, JOINT_LIMITS,
frames_in_base and, when it defines it, VELOCITY_LIMIT); nothing here hard-codes an offset, an axis
or a sign, so the numbers there can change without touching this module. The only names assumed
are the five joints of the Vizzy head (as in active_vision_msgs/GazeCommand) and the two camera
optical frames (REP 103/105: z forward, x right, y down).

Thesis: the observer's oculocephalic state is head pan and tilt plus eye vergence (section 3.3.1,
Fig. 3.1); during saccades perception is suppressed (section 3.4.2, ref. [11]), which is what
GazeState.in_saccade is for.

Inverse kinematics (solve_fixation)
-----------------------------------
Goal: both optical axes pass through the fixation point P, i.e. P projects onto the principal point
of both cameras (vergence follows from distance). The head has five joints for four conditions
(P's horizontal and vertical angle off each optical axis), so the redundancy (neck versus eyes)
is resolved by a split rule, then the eyes are solved exactly:

1. Head direction. With the eyes centred (eye joints 0), Newton iterations on (neck_pan, neck_tilt)
   point the cyclopean axis (from the midpoint of the two camera centres along the mean optical
   axis) at P. This gives the pan a_p and tilt a_t, in neck-joint units, that the neck alone would
   need, and the distance of P from the eyes.
2. Neck/eye split (GazeSplit). Like a person, the eyes take a gaze shift on their own up to a
   comfortable range (eye_pan_comfort, eye_tilt_comfort) and the neck takes the part beyond it,
   plus an optional fixed fraction neck_share of the part within it:
       neck = (a - clip(a, -c, c)) + neck_share * clip(a, -c, c),   clipped to the neck's limits.
   (c = 0: the head turns fully and the eyes only verge; c = eye limit: the eyes do all they can.)
3. Eyes. With the neck fixed, Gauss-Newton (Levenberg-Marquardt damped) iterations on
   (eyes_tilt, l_eye, r_eye) drive the four angular errors atan2(x, z), atan2(y, z) of P in the
   left and right optical frames (from kinematics.frames_in_base, Jacobian by forward differences)
   to below 1e-10 rad. With the Vizzy geometry (eye axes on a common tilt axis) this system is
   exactly solvable; should a model make it over-determined (e.g. vertically offset cameras), the
   neck joints are freed as well and the minimum-norm steps keep them near the split.
4. If an eye joint ends beyond its limit while the neck still has range, the neck takes the
   overflow (its sensitivity measured numerically) and step 3 runs again (at most a few times).

A point is rejected (GazeError, STATUS_REJECTED_UNREACHABLE) when it is behind the head (not in
front of the cyclopean plane at the home posture), nearer or farther than the configured distance
range, out of reach of the joint limits after step 4, or not in front of both cameras.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from vizzy_vision import kinematics

NECK_PAN, NECK_TILT, EYES_TILT, LEFT_EYE, RIGHT_EYE = (
    'neck_pan_joint', 'neck_tilt_joint', 'eyes_tilt_joint', 'l_eye_joint', 'r_eye_joint')
LEFT_OPTICAL_FRAME = 'left_camera_optical_frame'
RIGHT_OPTICAL_FRAME = 'right_camera_optical_frame'
BASE_FRAME = 'base_link'

# Fallback when kinematics does not define VELOCITY_LIMIT: Vizzy's 5 rad/s.
DEFAULT_VELOCITY_LIMIT = 5.0
# Peak velocity of a minimum-jerk profile = MIN_JERK_PEAK * amplitude / duration.
MIN_JERK_PEAK = 1.875

_IK_TOLERANCE = 1e-10     # rad, angular error of P off each optical axis to stop iterating
_IK_ACCEPT = 1e-6         # rad, largest error accepted as a solution (0.0003 px at fx = 350)
_LIMIT_SLACK = 1e-9       # rad, rounding allowance on joint limits


class GazeStatus(Enum):
    """Outcome of a gaze request; names match active_vision_msgs/GazeState's STATUS_* constants."""

    OK = 'OK'
    IDLE = 'IDLE'
    REJECTED_NAN = 'REJECTED_NAN'
    REJECTED_UNKNOWN_FRAME = 'REJECTED_UNKNOWN_FRAME'
    REJECTED_UNREACHABLE = 'REJECTED_UNREACHABLE'
    REJECTED_INVALID = 'REJECTED_INVALID'
    PREEMPTED = 'PREEMPTED'


class GazeError(ValueError):
    """A gaze request that cannot be carried out: status says why (GazeStatus), str() in words."""

    def __init__(self, status: GazeStatus, message: str) -> None:
        super().__init__(message)
        self.status = status


# --- the head, from core.kinematics ---------------------------------------------------------------

def _index(name: str) -> int:
    try:
        return kinematics.JOINT_NAMES.index(name)
    except ValueError:
        raise RuntimeError(f'core.kinematics.JOINT_NAMES {kinematics.JOINT_NAMES} lacks {name!r}, '
                           'which the gaze controller drives') from None


def joint_limits() -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) joint limits [rad] in kinematics.JOINT_NAMES order."""
    lo = np.array([kinematics.JOINT_LIMITS[n][0] for n in kinematics.JOINT_NAMES], dtype=float)
    hi = np.array([kinematics.JOINT_LIMITS[n][1] for n in kinematics.JOINT_NAMES], dtype=float)
    return lo, hi


def velocity_limits() -> np.ndarray:
    """Velocity limit of each joint [rad/s] in kinematics.JOINT_NAMES order.

    kinematics.VELOCITY_LIMIT may be one number or a {joint: limit} mapping; without it, 5 rad/s.
    """
    limit = getattr(kinematics, 'VELOCITY_LIMIT', DEFAULT_VELOCITY_LIMIT)
    if isinstance(limit, Mapping):
        return np.array([float(limit[n]) for n in kinematics.JOINT_NAMES])
    return np.full(len(kinematics.JOINT_NAMES), float(limit))


def home_posture() -> np.ndarray:
    """All joints at 0 (clipped into the limits), in kinematics.JOINT_NAMES order."""
    lo, hi = joint_limits()
    return np.clip(np.zeros(len(kinematics.JOINT_NAMES)), lo, hi)


def as_joint_array(positions: Mapping[str, float] | Sequence[float] | np.ndarray,
                   default: np.ndarray | None = None) -> np.ndarray:
    """Joint positions as an array in JOINT_NAMES order (missing names from default, else 0)."""
    if isinstance(positions, Mapping):
        base = np.zeros(len(kinematics.JOINT_NAMES)) if default is None else default.copy()
        for i, name in enumerate(kinematics.JOINT_NAMES):
            if name in positions:
                base[i] = float(positions[name])
        return base
    q = np.asarray(positions, dtype=float).reshape(-1)
    if len(q) != len(kinematics.JOINT_NAMES):
        raise ValueError(f'expected {len(kinematics.JOINT_NAMES)} joint positions, got {len(q)}')
    return q


def _poses(q: np.ndarray) -> dict[str, np.ndarray]:
    return kinematics.frames_in_base([float(v) for v in q])


def _in_frame(pose: np.ndarray, point: np.ndarray) -> np.ndarray:
    """point (base) expressed in the frame whose pose in base is pose."""
    return pose[:3, :3].T @ (point - pose[:3, 3])


def optical_errors(q: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Angles [rad] of point off each optical axis: (left x, left y, right x, right y).

    atan2(x, z) and atan2(y, z) of the point in each optical frame; all four are 0 when both
    optical axes pass through the point (it projects onto both principal points).
    """
    poses = _poses(q)
    pl = _in_frame(poses[LEFT_OPTICAL_FRAME], point)
    pr = _in_frame(poses[RIGHT_OPTICAL_FRAME], point)
    return np.array([math.atan2(pl[0], pl[2]), math.atan2(pl[1], pl[2]),
                     math.atan2(pr[0], pr[2]), math.atan2(pr[1], pr[2])])


def cyclopean_ray(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(origin, rotation): the camera centres' midpoint and axes (x right, y down, z forward) of
    the mean optical frame, in base_link."""
    poses = _poses(q)
    left, right = poses[LEFT_OPTICAL_FRAME], poses[RIGHT_OPTICAL_FRAME]
    forward = left[:3, 2] + right[:3, 2]
    forward /= np.linalg.norm(forward)
    x = left[:3, 0] + right[:3, 0]
    x -= (x @ forward) * forward
    x /= np.linalg.norm(x)
    return 0.5 * (left[:3, 3] + right[:3, 3]), np.column_stack([x, np.cross(forward, x), forward])


def _cyclopean_errors(q: np.ndarray, point: np.ndarray) -> np.ndarray:
    origin, rot = cyclopean_ray(q)
    d = rot.T @ (point - origin)
    return np.array([math.atan2(d[0], d[2]), math.atan2(d[1], d[2])])


def fixation_point(positions: Mapping[str, float] | Sequence[float] | np.ndarray,
                   max_distance: float = 10.0) -> np.ndarray:
    """The point both optical axes look at, in base_link [m].

    The midpoint of the shortest segment between the two optical axes; when they do not meet in
    front of both cameras within max_distance (parallel or diverging), the point max_distance
    ahead of the cameras' midpoint along the mean optical axis.
    """
    q = as_joint_array(positions)
    return kinematics.fixation_from_joints(
        dict(zip(kinematics.JOINT_NAMES, q.tolist(), strict=True)), max_distance)


# --- validation -----------------------------------------------------------------------------------

def check_finite_point(point: Sequence[float] | np.ndarray) -> np.ndarray:
    """The point as an array; GazeError(REJECTED_NAN) naming the bad coordinate if not finite."""
    p = np.asarray([float(c) for c in point], dtype=float)
    if p.shape != (3,):
        raise GazeError(GazeStatus.REJECTED_INVALID, f'a fixation point has 3 coordinates, '
                                                     f'got {len(p)}')
    for axis, value in zip('xyz', p, strict=True):
        if not math.isfinite(value):
            raise GazeError(GazeStatus.REJECTED_NAN, f'fixation_point.{axis} is {value}')
    return p


# Targets this far beyond a limit [rad] still count as on it (float round trips of the limit).
JOINT_LIMIT_TOLERANCE_RAD = 1e-9


def joint_targets(names: Sequence[str], positions: Sequence[float],
                  current: np.ndarray) -> np.ndarray:
    """Joint targets in JOINT_NAMES order; joints not named keep current.

    Raises GazeError, as GazeState.msg defines: REJECTED_INVALID for no joints, a length
    mismatch, an unknown or repeated joint; REJECTED_NAN for a non-finite target;
    REJECTED_UNREACHABLE for a target outside its joint's limits (the head is not moved).
    """
    names = list(names)
    values = [float(v) for v in positions]
    if len(names) != len(values):
        raise GazeError(GazeStatus.REJECTED_INVALID,
                        f'{len(names)} joint_names but {len(values)} joint_positions')
    if not names:
        raise GazeError(GazeStatus.REJECTED_INVALID, 'no joint_names given')
    if len(set(names)) != len(names):
        raise GazeError(GazeStatus.REJECTED_INVALID, f'repeated joint names in {names}')
    unknown = [n for n in names if n not in kinematics.JOINT_LIMITS]
    if unknown:
        raise GazeError(GazeStatus.REJECTED_INVALID,
                        f'unknown joints {unknown}; known: {list(kinematics.JOINT_NAMES)}')
    for name, value in zip(names, values, strict=True):
        if not math.isfinite(value):
            raise GazeError(GazeStatus.REJECTED_NAN, f'{name} target is {value}')
    outside = []
    for name, value in zip(names, values, strict=True):
        lo, hi = kinematics.JOINT_LIMITS[name]
        if not lo - JOINT_LIMIT_TOLERANCE_RAD <= value <= hi + JOINT_LIMIT_TOLERANCE_RAD:
            outside.append(f'{name} target {value:.4f} rad outside its limits [{lo:.4f}, {hi:.4f}]')
    if outside:
        raise GazeError(GazeStatus.REJECTED_UNREACHABLE, '; '.join(outside))
    target = np.array(current, dtype=float)
    for name, value in zip(names, values, strict=True):
        lo, hi = kinematics.JOINT_LIMITS[name]
        target[_index(name)] = min(max(value, lo), hi)  # within the tolerance: onto the limit
    return target


# --- inverse kinematics ---------------------------------------------------------------------------

@dataclass(frozen=True)
class GazeSplit:
    """How a gaze shift is shared between neck and eyes (see the module docstring).

    eye_pan_comfort, eye_tilt_comfort [rad]: the part of the pan/tilt the eyes take on their own;
    the neck takes the rest. neck_share in [0, 1]: the fraction of that comfortable part the neck
    takes as well.
    """

    eye_pan_comfort: float = 0.35
    eye_tilt_comfort: float = 0.25
    neck_share: float = 0.0

    def neck_angle(self, total: float, comfort: float) -> float:
        within = min(max(total, -comfort), comfort)
        return (total - within) + self.neck_share * within


@dataclass(frozen=True)
class FixationSolution:
    """Joint positions (JOINT_NAMES order) fixating point; error [rad] and distance [m]."""

    joints: np.ndarray
    point: np.ndarray        # the fixation point, base_link [m]
    error: float             # largest angle of the point off an optical axis [rad]
    distance: float          # from the midpoint of the camera centres [m]


def _least_squares(residual: Callable[[np.ndarray], np.ndarray], q0: np.ndarray,
                   free: Sequence[int], iterations: int = 40,
                   step_limit: float = 0.5) -> tuple[np.ndarray, float]:
    """Damped Gauss-Newton (Levenberg-Marquardt) on the joints free; returns (q, max |residual|)."""
    q = q0.copy()
    free = list(free)
    r = residual(q)
    cost = float(r @ r)
    damping = 1e-9
    h = 1e-7  # forward differences: a Jacobian good to ~1e-7 keeps Newton's convergence fast
    for _ in range(iterations):
        if np.max(np.abs(r)) < _IK_TOLERANCE:
            break
        jac = np.empty((len(r), len(free)))
        for k, j in enumerate(free):
            dq = np.zeros_like(q)
            dq[j] = h
            jac[:, k] = (residual(q + dq) - r) / h
        jtj, jtr = jac.T @ jac, jac.T @ r
        improved = False
        for _ in range(12):
            try:
                step = -np.linalg.solve(jtj + damping * np.eye(len(free)), jtr)
            except np.linalg.LinAlgError:
                damping *= 100.0
                continue
            biggest = float(np.max(np.abs(step)))
            if biggest > step_limit:
                step *= step_limit / biggest
            candidate = q.copy()
            candidate[free] += step
            r_new = residual(candidate)
            cost_new = float(r_new @ r_new)
            if np.isfinite(cost_new) and cost_new < cost:
                q, r, cost = candidate, r_new, cost_new
                damping = max(damping * 0.1, 1e-12)
                improved = True
                break
            damping *= 10.0
        if not improved:
            break
    return q, float(np.max(np.abs(r)))


def _eye_overflow(q: np.ndarray, lo: np.ndarray, hi: np.ndarray, joints: Sequence[int]) -> float:
    """How far (signed, rad) the joints go beyond their limits: > 0 above, < 0 below, 0 inside
    (with joints above and below, the difference)."""
    above = max(0.0, max(q[j] - hi[j] for j in joints))
    below = max(0.0, max(lo[j] - q[j] for j in joints))
    return above - below


def _describe(point: np.ndarray) -> str:
    return '(' + ', '.join(f'{c:.3f}' for c in point) + ') m in ' + BASE_FRAME


def solve_fixation(point: Sequence[float] | np.ndarray, split: GazeSplit = GazeSplit(),
                   min_distance: float = 0.15, max_distance: float = 10.0) -> FixationSolution:
    """Joint positions whose two optical axes both pass through point (base_link, metres).

    Raises GazeError: REJECTED_NAN for a non-finite point, REJECTED_UNREACHABLE (with the reason)
    for a point behind the head, outside [min_distance, max_distance] from the eyes, or beyond
    the joint limits. The method is in the module docstring.
    """
    p = check_finite_point(point)
    lo, hi = joint_limits()
    i_pan, i_tilt, i_etilt, i_l, i_r = (_index(n) for n in
                                        (NECK_PAN, NECK_TILT, EYES_TILT, LEFT_EYE, RIGHT_EYE))
    home = home_posture()

    # 1. head direction: the neck alone turns the cyclopean axis onto the point.
    origin, rot = cyclopean_ray(home)
    ahead = float(rot[:, 2] @ (p - origin))
    if ahead <= 0.0:
        raise GazeError(GazeStatus.REJECTED_UNREACHABLE,
                        f'fixation point {_describe(p)} is behind the head ({ahead:.3f} m along '
                        'its forward axis at the home posture)')
    head, err = _least_squares(lambda q: _cyclopean_errors(q, p), home, [i_pan, i_tilt])
    origin, _ = cyclopean_ray(head)
    distance = float(np.linalg.norm(p - origin))
    if distance < min_distance:
        raise GazeError(GazeStatus.REJECTED_UNREACHABLE,
                        f'fixation point {_describe(p)} is too close: {distance:.3f} m from the '
                        f'eyes, nearest allowed {min_distance} m')
    if distance > max_distance:
        raise GazeError(GazeStatus.REJECTED_UNREACHABLE,
                        f'fixation point {_describe(p)} is too far: {distance:.3f} m from the '
                        f'eyes, farthest allowed {max_distance} m')
    if err > 1e-6:  # the neck cannot point the head at it even without limits (e.g. straight up)
        raise GazeError(GazeStatus.REJECTED_UNREACHABLE,
                        f'fixation point {_describe(p)}: no head direction looks at it')

    # 2. split: the neck takes what is beyond the eyes' comfortable range.
    q = home.copy()
    q[i_pan] = np.clip(split.neck_angle(head[i_pan], split.eye_pan_comfort), lo[i_pan], hi[i_pan])
    q[i_tilt] = np.clip(split.neck_angle(head[i_tilt], split.eye_tilt_comfort),
                        lo[i_tilt], hi[i_tilt])

    def residual(x: np.ndarray) -> np.ndarray:
        return optical_errors(x, p)

    def solve_eyes(neck: np.ndarray) -> tuple[np.ndarray, float]:
        x, e = _least_squares(residual, neck, [i_etilt, i_l, i_r])
        if e > _IK_ACCEPT:  # over-determined for this model: let the neck help
            x, e = _least_squares(residual, x, [i_pan, i_tilt, i_etilt, i_l, i_r])
        return x, e

    # 3. eyes; 4. the neck takes any overflow of the eye joints while it has range.
    sol, err = solve_eyes(q)
    for _ in range(8):
        moved = False
        for neck_j, eye_js in ((i_pan, (i_l, i_r)), (i_tilt, (i_etilt,))):
            overflows = [_eye_overflow(sol, lo, hi, (j,)) for j in eye_js]
            worst = int(np.argmax(np.abs(overflows)))
            over = overflows[worst]
            if over == 0.0 or err > _IK_ACCEPT:
                continue
            if min(overflows) < 0.0 < max(overflows):
                continue  # one eye above its range, the other below: too close to converge on
            # how the overflowing eye joint moves per radian of neck, fixation held (about +-1)
            step = 0.01 if q[neck_j] + 0.01 <= hi[neck_j] else -0.01
            probe = q.copy()
            probe[neck_j] += step
            probed, _ = solve_eyes(probe)
            sensitivity = (probed[eye_js[worst]] - sol[eye_js[worst]]) / step
            if abs(sensitivity) < 0.1:
                continue
            # aim 1 mrad inside the range
            new_neck = np.clip(q[neck_j] - (over + math.copysign(1e-3, over)) / sensitivity,
                               lo[neck_j], hi[neck_j])
            if abs(new_neck - q[neck_j]) > 1e-9:
                q[neck_j] = new_neck
                moved = True
        if not moved:
            break
        sol, err = solve_eyes(q)

    if err > _IK_ACCEPT:
        raise GazeError(GazeStatus.REJECTED_UNREACHABLE,
                        f'fixation point {_describe(p)}: no joint solution puts it on both '
                        f'optical axes (best: {math.degrees(err):.2f} deg off an axis)')
    poses = _poses(sol)
    for frame in (LEFT_OPTICAL_FRAME, RIGHT_OPTICAL_FRAME):
        if _in_frame(poses[frame], p)[2] <= 0.0:
            raise GazeError(GazeStatus.REJECTED_UNREACHABLE,
                            f'fixation point {_describe(p)} would be behind {frame}')
    outside = [(n, sol[i], lo[i], hi[i]) for i, n in enumerate(kinematics.JOINT_NAMES)
               if not lo[i] - _LIMIT_SLACK <= sol[i] <= hi[i] + _LIMIT_SLACK]
    if outside:
        why = '; '.join(f'{n} would need {v:.3f} rad, limits [{a:.3f}, {b:.3f}]'
                        for n, v, a, b in outside)
        hint = ''
        if _eye_overflow(sol, lo, hi, (i_l,)) * _eye_overflow(sol, lo, hi, (i_r,)) < 0:
            hint = f' (too close to converge on: {distance:.3f} m from the eyes)'
        raise GazeError(GazeStatus.REJECTED_UNREACHABLE,
                        f'fixation point {_describe(p)} is beyond the joint limits{hint}: {why}')
    sol = np.clip(sol, lo, hi)
    return FixationSolution(joints=sol, point=p, error=err, distance=distance)


# --- trajectories ---------------------------------------------------------------------------------

def saccade_duration(q0: np.ndarray, q1: np.ndarray, max_velocity: np.ndarray | float,
                     min_duration: float, seconds_per_rad: float) -> float:
    """Duration [s] of a saccade from q0 to q1: the main sequence, stretched to the velocity limit.

    Main sequence (human saccades: duration grows linearly with amplitude, about 2.2-2.7 ms/deg,
    e.g. Bahill et al. 1975): min_duration + seconds_per_rad * A, with A the largest joint
    displacement. A minimum-jerk profile peaks at 1.875 * A / duration, so the duration is at
    least 1.875 * |dq_j| / max_velocity_j for every joint. 0 when q0 == q1.
    """
    dq = np.abs(np.asarray(q1, dtype=float) - np.asarray(q0, dtype=float))
    amplitude = float(dq.max(initial=0.0))
    if amplitude == 0.0:
        return 0.0
    by_velocity = MIN_JERK_PEAK * float(np.max(dq / np.asarray(max_velocity, dtype=float)))
    return max(min_duration + seconds_per_rad * amplitude, by_velocity)


@dataclass(frozen=True)
class MinimumJerk:
    """Minimum-jerk move from q0 at t0 to q1 at t0 + duration, all joints in step (Flash & Hogan).

    q(t) = q0 + (q1 - q0) s(tau), s = 10 tau^3 - 15 tau^4 + 6 tau^5, tau = (t - t0) / duration:
    zero velocity and acceleration at both ends, monotonic between (so it stays within limits
    that hold q0 and q1), peak velocity 1.875 |q1 - q0| / duration at the midpoint.
    """

    q0: np.ndarray
    q1: np.ndarray
    t0: float
    duration: float

    @property
    def t_end(self) -> float:
        return self.t0 + self.duration

    def _tau(self, t: float | np.ndarray) -> np.ndarray:
        if self.duration <= 0.0:
            return np.ones_like(np.asarray(t, dtype=float))
        return np.clip((np.asarray(t, dtype=float) - self.t0) / self.duration, 0.0, 1.0)

    def position(self, t: float | np.ndarray) -> np.ndarray:
        """q at time(s) t: shape (n_joints,) for a scalar t, (len(t), n_joints) for an array."""
        tau = self._tau(t)
        s = tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
        return self.q0 + np.multiply.outer(s, self.q1 - self.q0)

    def velocity(self, t: float | np.ndarray) -> np.ndarray:
        """dq/dt at time(s) t (same shapes as position)."""
        if self.duration <= 0.0:
            return np.zeros(np.shape(t) + self.q0.shape)
        tau = self._tau(t)
        ds = 30.0 * tau ** 2 * (1.0 - tau) ** 2 / self.duration
        return np.multiply.outer(ds, self.q1 - self.q0)

    def done(self, t: float) -> bool:
        return t >= self.t_end


def pursuit_step(q: np.ndarray, target: np.ndarray, dt: float, gain: float,
                 max_velocity: np.ndarray | float) -> np.ndarray:
    """One step of smooth pursuit: first-order tracking of target with a velocity limit.

    v = clip(gain * (target - q), -max_velocity, max_velocity), and never past the target
    (gain * dt is capped at 1, so a slow control loop does not overshoot).
    """
    if dt <= 0.0:
        return np.asarray(q, dtype=float).copy()
    q = np.asarray(q, dtype=float)
    error = np.asarray(target, dtype=float) - q
    velocity = min(gain, 1.0 / dt) * error
    vmax = np.asarray(max_velocity, dtype=float)
    return q + np.clip(velocity, -vmax, vmax) * dt


# --- arbitration ----------------------------------------------------------------------------------

@dataclass(frozen=True)
class Claim:
    """The request being executed: who asked, how important, and how long it holds the eyes.

    accepted: when it was accepted [s]; reached: when its fixation was reached (its saccade
    ended and settled) [s], None while the saccade runs (a pursuit reaches it at once).
    """

    source: str
    priority: int
    accepted: float
    hold_time: float
    reached: float | None = None

    def held(self, now: float) -> bool:
        """Does it still hold the eyes against lower priorities (saccade running or in its hold)?"""
        return self.reached is None or now < self.reached + self.hold_time


def arbitrate(active: Claim | None, source: str, priority: int, now: float) -> str | None:
    """None if a new request (source, priority) takes over at time now [s], else why it loses.

    Priority first: a higher priority always takes over (preempting a running saccade). Then
    recency: at equal priority the newest request wins. A lower priority takes over only once
    the active request is no longer held: its saccade has finished and hold_time has passed
    since the fixation was reached.
    """
    if active is None or priority >= active.priority:
        return None
    if not active.held(now):
        return None
    if active.reached is None:
        until = 'until its saccade ends'
    else:
        until = f'for another {active.reached + active.hold_time - now:.3f} s'
    return (f'{source!r} (priority {priority}) lost to {active.source!r} '
            f'(priority {active.priority}), which holds the gaze {until}')


__all__ = [
    'BASE_FRAME', 'Claim', 'FixationSolution', 'GazeError', 'GazeSplit', 'GazeStatus',
    'LEFT_OPTICAL_FRAME', 'MinimumJerk', 'RIGHT_OPTICAL_FRAME', 'arbitrate', 'as_joint_array',
    'check_finite_point', 'cyclopean_ray', 'fixation_point', 'home_posture',
    'joint_limits', 'optical_errors', 'pursuit_step', 'saccade_duration', 'solve_fixation',
    'velocity_limits',
]
