"""core.gaze without ROS: inverse kinematics, validation, trajectories, arbitration.

Every number about the head comes from core.kinematics (limits, frames, velocity limit), so these
tests hold for whatever geometry it describes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from vizzy_gaze.core.gaze import (
    LEFT_OPTICAL_FRAME,
    MIN_JERK_PEAK,
    RIGHT_OPTICAL_FRAME,
    Claim,
    GazeError,
    GazeSplit,
    GazeStatus,
    MinimumJerk,
    arbitrate,
    cyclopean_ray,
    fixation_point,
    home_posture,
    joint_limits,
    joint_targets,
    pursuit_step,
    saccade_duration,
    solve_fixation,
    velocity_limits,
)
from vizzy_vision import kinematics

# The test camera of the brief: 640x480, 85.4 deg horizontal field of view, no distortion.
WIDTH, HEIGHT, HFOV_DEG = 640, 480, 85.4
FX = (WIDTH / 2) / math.tan(math.radians(HFOV_DEG) / 2)
NAMES = list(kinematics.JOINT_NAMES)
IDX = {n: i for i, n in enumerate(NAMES)}
LO, HI = joint_limits()


def pixel_offsets(joints: np.ndarray, point: np.ndarray) -> np.ndarray:
    """(left du, left dv, right du, right dv): where point projects, minus the principal point [px].

    Straight from kinematics.frames_in_base (pinhole: u - cx = fx x / z, v - cy = fy y / z);
    inf when the point is not in front of a camera.
    """
    poses = kinematics.frames_in_base([float(v) for v in joints])
    out = []
    for frame in (LEFT_OPTICAL_FRAME, RIGHT_OPTICAL_FRAME):
        pose = poses[frame]
        x, y, z = pose[:3, :3].T @ (point - pose[:3, 3])
        out += [FX * x / z, FX * y / z] if z > 0 else [math.inf, math.inf]
    return np.array(out)


def axes_meet(joints: np.ndarray) -> np.ndarray | None:
    """Where the two optical axes meet in front of the cameras (least squares), None if they
    do not (parallel, diverging, or skew by more than 1 mm)."""
    poses = kinematics.frames_in_base([float(v) for v in joints])
    (ol, dl), (orr, dr) = ((poses[f][:3, 3], poses[f][:3, 2])
                           for f in (LEFT_OPTICAL_FRAME, RIGHT_OPTICAL_FRAME))
    a = np.column_stack([dl, -dr])
    (s, t), *_ = np.linalg.lstsq(a, orr - ol, rcond=None)
    if s <= 0 or t <= 0:
        return None
    pl, pr = ol + s * dl, orr + t * dr
    return 0.5 * (pl + pr) if np.linalg.norm(pl - pr) < 1e-3 else None


def random_fixations(n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """n (joints, point) pairs: random postures within the limits whose axes meet at point, at
    0.3 to 5 m from the eyes; such points are reachable by construction."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        q = rng.uniform(LO, HI) * 0.95
        point = axes_meet(q)
        if point is None:
            continue
        origin, _ = cyclopean_ray(q)
        if 0.3 <= np.linalg.norm(point - origin) <= 5.0:
            out.append((q, point))
    return out


def head_only_point(pan: float, tilt: float, distance: float) -> np.ndarray:
    """The point distance ahead of the eyes when the neck alone turns by (pan, tilt)."""
    q = home_posture()
    q[IDX['neck_pan_joint']], q[IDX['neck_tilt_joint']] = pan, tilt
    origin, rot = cyclopean_ray(q)
    return origin + distance * rot[:, 2]


# --- inverse kinematics --------------------------------------------------------------------------

@pytest.mark.parametrize('seed', [0, 1, 2])
def test_random_reachable_points_land_on_both_principal_points(seed: int) -> None:
    for joints, point in random_fixations(40, seed):
        solution = solve_fixation(point, min_distance=0.1, max_distance=10.0)
        offsets = pixel_offsets(solution.joints, point)
        assert np.all(np.abs(offsets) < 2.0), (
            f'{point} from {joints}: solution {solution.joints} is off by {offsets} px')
        assert np.all(solution.joints >= LO) and np.all(solution.joints <= HI)
        assert solution.error < 1e-6
        # the reported fixation of the solved posture is the point itself
        np.testing.assert_allclose(fixation_point(solution.joints), point, atol=1e-6)


def test_vergence_grows_as_the_point_comes_closer() -> None:
    vergences = []
    for distance in (0.3, 0.6, 1.2, 4.0):
        joints = solve_fixation(head_only_point(0.0, 0.0, distance)).joints
        assert np.all(np.abs(pixel_offsets(joints, head_only_point(0.0, 0.0, distance))) < 2.0)
        vergences.append(abs(kinematics.gaze_angles([float(v) for v in joints])[1]))
    assert vergences == sorted(vergences, reverse=True) and vergences[-1] > 0.0


def test_the_neck_takes_the_part_beyond_the_eyes_comfortable_range() -> None:
    pan_lo, pan_hi = LO[IDX['neck_pan_joint']], HI[IDX['neck_pan_joint']]
    split = GazeSplit(eye_pan_comfort=0.3, eye_tilt_comfort=0.2, neck_share=0.0)
    # straight ahead: eyes only
    joints = solve_fixation(head_only_point(0.0, 0.0, 1.5), split).joints
    assert joints[IDX['neck_pan_joint']] == pytest.approx(0.0, abs=1e-9)
    assert joints[IDX['neck_tilt_joint']] == pytest.approx(0.0, abs=1e-9)
    # within the comfortable range: still eyes only
    small = 0.5 * split.eye_pan_comfort
    joints = solve_fixation(head_only_point(small, 0.0, 1.5), split).joints
    assert joints[IDX['neck_pan_joint']] == pytest.approx(0.0, abs=1e-9)
    # beyond it: the neck turns by the excess, the eyes keep about the comfortable part
    for pan in (0.8 * pan_hi, 0.8 * pan_lo):
        point = head_only_point(pan, 0.0, 1.5)
        joints = solve_fixation(point, split).joints
        excess = pan - math.copysign(split.eye_pan_comfort, pan)
        assert joints[IDX['neck_pan_joint']] == pytest.approx(excess, abs=1e-6)
        version = kinematics.gaze_angles([float(v) for v in joints])[0]
        assert abs(version) == pytest.approx(split.eye_pan_comfort, abs=0.1)
        assert np.all(np.abs(pixel_offsets(joints, point)) < 2.0)
    # no comfortable range: the head turns all the way, the eyes only verge
    point = head_only_point(0.5 * pan_hi, 0.0, 1.5)
    joints = solve_fixation(point, GazeSplit(0.0, 0.0, 0.0)).joints
    assert joints[IDX['neck_pan_joint']] == pytest.approx(0.5 * pan_hi, abs=1e-6)
    assert kinematics.gaze_angles([float(v) for v in joints])[0] == pytest.approx(0.0, abs=1e-6)
    # neck_share = 1: the neck takes the comfortable part too
    joints = solve_fixation(head_only_point(small, 0.0, 1.5), GazeSplit(0.3, 0.2, 1.0)).joints
    assert joints[IDX['neck_pan_joint']] == pytest.approx(small, abs=1e-6)


def test_the_neck_takes_the_eyes_overflow_near_its_limits() -> None:
    # A near point far to the side: the comfortable split would push the inner eye past its limit.
    split = GazeSplit(eye_pan_comfort=float(HI[IDX['l_eye_joint']]), eye_tilt_comfort=0.2)
    pan = HI[IDX['neck_pan_joint']]
    point = head_only_point(0.9 * pan, 0.0, 0.35)
    joints = solve_fixation(point, split).joints
    assert np.all(np.abs(pixel_offsets(joints, point)) < 2.0)
    assert np.all(joints >= LO) and np.all(joints <= HI)


def _rejected(point: np.ndarray | tuple[float, ...], **kwargs: float) -> GazeError:
    with pytest.raises(GazeError) as err:
        solve_fixation(point, **kwargs)
    return err.value


def test_unreachable_points_are_rejected_with_the_reason() -> None:
    origin, rot = cyclopean_ray(home_posture())
    forward = rot[:, 2]
    behind = _rejected(origin - 1.0 * forward)
    assert behind.status == GazeStatus.REJECTED_UNREACHABLE and 'behind the head' in str(behind)
    close = _rejected(origin + 0.1 * forward, min_distance=0.2)
    assert close.status == GazeStatus.REJECTED_UNREACHABLE and 'too close' in str(close)
    far = _rejected(origin + 50.0 * forward, max_distance=10.0)
    assert far.status == GazeStatus.REJECTED_UNREACHABLE and 'too far' in str(far)
    # beyond the joint limits: more tilt than neck and eyes together have, either way
    eye_tilt = max(abs(LO[IDX['eyes_tilt_joint']]), abs(HI[IDX['eyes_tilt_joint']]))
    for total in (HI[IDX['neck_tilt_joint']] + eye_tilt + 0.15,
                  LO[IDX['neck_tilt_joint']] - eye_tilt - 0.15):
        if abs(total) >= math.pi / 2 - 0.05:
            continue  # this head looks almost straight up/down: nothing to test that way
        err = _rejected(head_only_point(0.0, total, 2.0))
        assert err.status == GazeStatus.REJECTED_UNREACHABLE
        assert 'joint limits' in str(err) or 'behind' in str(err)
    # far to the side, the neck and eyes at their limits together do not suffice
    pan_room = HI[IDX['neck_pan_joint']] + HI[IDX['l_eye_joint']]
    if pan_room + 0.15 < math.pi / 2 - 0.05:
        err = _rejected(head_only_point(pan_room + 0.15, 0.0, 2.0))
        assert err.status == GazeStatus.REJECTED_UNREACHABLE
    # too close to converge on, yet in front of the eyes
    near = _rejected(origin + 0.03 * forward, min_distance=0.01)
    assert near.status == GazeStatus.REJECTED_UNREACHABLE


def test_non_finite_points_are_rejected_naming_the_coordinate() -> None:
    err = _rejected((1.0, math.nan, 0.4))
    assert err.status == GazeStatus.REJECTED_NAN and 'fixation_point.y is nan' in str(err)
    err = _rejected((math.inf, 0.0, 0.4))
    assert err.status == GazeStatus.REJECTED_NAN and 'fixation_point.x' in str(err)


# --- joint targets -------------------------------------------------------------------------------

def test_joint_targets_outside_the_limits_are_refused_as_unreachable() -> None:
    current = home_posture()
    with pytest.raises(GazeError) as err:
        joint_targets(['l_eye_joint', 'neck_pan_joint'], [3.0, 0.1], current)
    assert err.value.status == GazeStatus.REJECTED_UNREACHABLE
    assert 'l_eye_joint target 3.0000 rad outside its limits' in str(err.value)
    assert 'neck_pan_joint' not in str(err.value)
    # on the limits (and a float hair beyond) is accepted; joints not named keep their target
    current = (LO + HI) / 2
    i = IDX['r_eye_joint']
    target = joint_targets(['r_eye_joint'], [LO[i] - 1e-12], current)
    assert target[i] == LO[i]
    np.testing.assert_array_equal(np.delete(target, i), np.delete(current, i))
    target = joint_targets(['l_eye_joint', 'neck_pan_joint'], [HI[IDX['l_eye_joint']], 0.1],
                           current)
    assert target[IDX['l_eye_joint']] == HI[IDX['l_eye_joint']]
    assert target[IDX['neck_pan_joint']] == 0.1


@pytest.mark.parametrize('names, positions, status, words', [
    (['neck_pan_joint'], [0.1, 0.2], GazeStatus.REJECTED_INVALID, '1 joint_names but 2'),
    ([], [], GazeStatus.REJECTED_INVALID, 'no joint_names'),
    (['elbow'], [0.1], GazeStatus.REJECTED_INVALID, "unknown joints ['elbow']"),
    (['l_eye_joint', 'l_eye_joint'], [0.1, 0.1], GazeStatus.REJECTED_INVALID, 'repeated'),
    (['l_eye_joint'], [math.nan], GazeStatus.REJECTED_NAN, 'l_eye_joint target is nan'),
])
def test_malformed_joint_targets_are_rejected(names, positions, status, words) -> None:
    with pytest.raises(GazeError) as err:
        joint_targets(names, positions, home_posture())
    assert err.value.status == status and words in str(err.value)


def test_status_names_match_the_message_constants() -> None:
    msg = Path(__file__).resolve().parents[3] / 'msgs' / 'msg' / 'GazeState.msg'
    if not msg.is_file():
        pytest.skip('active_vision_msgs sources not beside this package')
    constants = {line.split()[1].split('=')[0] for line in msg.read_text().splitlines()
                 if line.startswith('uint8 STATUS_')}
    assert {f'STATUS_{s.name}' for s in GazeStatus} == constants


# --- trajectories --------------------------------------------------------------------------------

def test_saccades_stay_within_the_joint_and_velocity_limits_and_end_at_the_target() -> None:
    vmax = velocity_limits()
    rng = np.random.default_rng(5)
    for _ in range(50):
        q0, q1 = rng.uniform(LO, HI), rng.uniform(LO, HI)
        duration = saccade_duration(q0, q1, vmax, 0.05, 0.15)
        traj = MinimumJerk(q0, q1, 2.0, duration)
        t = np.linspace(2.0 - 0.1, traj.t_end + 0.1, 2001)
        q = traj.position(t)
        assert np.all(q >= LO - 1e-12) and np.all(q <= HI + 1e-12)
        np.testing.assert_allclose(q[0], q0)
        np.testing.assert_allclose(q[-1], q1)
        np.testing.assert_allclose(traj.position(traj.t_end), q1, atol=1e-15)
        assert traj.done(traj.t_end) and not traj.done(traj.t_end - 1e-3)
        velocity = traj.velocity(t)
        assert np.all(np.abs(velocity) <= vmax * (1 + 1e-9))
        # the analytic velocity is the trajectory's derivative; finite differences agree
        finite = np.diff(q, axis=0) / np.diff(t)[:, None]
        assert np.all(np.abs(finite) <= vmax * (1 + 1e-9))
        np.testing.assert_allclose(finite, 0.5 * (velocity[1:] + velocity[:-1]),
                                   atol=1e-3 * float(vmax.max()))


def test_saccade_duration_follows_the_main_sequence_and_the_velocity_cap() -> None:
    q0 = np.zeros(len(NAMES))
    durations = []
    for amplitude in (0.01, 0.05, 0.1, 0.3):
        q1 = q0.copy()
        q1[IDX['l_eye_joint']] = amplitude
        durations.append(saccade_duration(q0, q1, 1e9, 0.02, 0.1))  # no velocity cap
        assert durations[-1] == pytest.approx(0.02 + 0.1 * amplitude)
    assert durations == sorted(durations)
    q1 = q0.copy()
    q1[IDX['neck_pan_joint']] = 0.8
    capped = saccade_duration(q0, q1, 5.0, 0.0, 0.0)
    assert MIN_JERK_PEAK * 0.8 / capped == pytest.approx(5.0)  # peak velocity exactly at the cap
    assert saccade_duration(q0, q0, 5.0, 0.02, 0.1) == 0.0


def test_pursuit_tracks_smoothly_within_its_velocity_limit() -> None:
    q = home_posture()
    target = np.clip(q + 0.4, LO, HI)
    vmax, dt = 1.0, 0.01
    previous_error = np.abs(target - q)
    for _ in range(300):
        nxt = pursuit_step(q, target, dt, gain=8.0, max_velocity=vmax)
        assert np.all(np.abs(nxt - q) <= vmax * dt * (1 + 1e-12))
        error = np.abs(target - nxt)
        assert np.all(error <= previous_error + 1e-15)  # never overshoots
        q, previous_error = nxt, error
    np.testing.assert_allclose(q, target, atol=1e-6)
    # a slow control loop does not overshoot either (gain * dt capped at 1)
    np.testing.assert_allclose(pursuit_step(home_posture(), target, 1.0, 50.0, 100.0), target)
    np.testing.assert_array_equal(pursuit_step(q, target, 0.0, 8.0, 1.0), q)


# --- arbitration ---------------------------------------------------------------------------------

def test_arbitration_by_priority_then_recency_then_hold() -> None:
    assert arbitrate(None, 'anyone', 0, 0.0) is None
    moving = Claim('mot_planner', priority=5, accepted=10.0, hold_time=1.0, reached=None)
    # priority: a higher one always takes over, even mid-saccade
    assert arbitrate(moving, 'user', 7, 10.01) is None
    # recency: at equal priority the newest wins
    assert arbitrate(moving, 'stereo_ses', 5, 10.01) is None
    # hold: a lower priority waits for the saccade to end ...
    why = arbitrate(moving, 'foveation', 1, 100.0)
    assert why is not None and 'until its saccade ends' in why
    assert "'foveation' (priority 1) lost to 'mot_planner' (priority 5)" in why
    # ... and then for hold_time after the fixation was reached
    reached = Claim('mot_planner', priority=5, accepted=10.0, hold_time=1.0, reached=10.2)
    why = arbitrate(reached, 'foveation', 1, 10.5)
    assert why is not None and 'for another 0.700 s' in why
    assert arbitrate(reached, 'foveation', 1, 11.2) is None
    assert reached.held(11.19) and not reached.held(11.2)
    # no hold: lower priorities take over as soon as the fixation is reached
    assert arbitrate(Claim('a', 5, 0.0, 0.0, reached=0.1), 'b', 0, 0.1) is None
