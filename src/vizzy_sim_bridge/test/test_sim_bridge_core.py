"""ROS-free parts of vizzy_sim_bridge: camera model and the head's kinematics.

The kinematic chain is checked against two independent encodings of the real robot: the
vizzy_description URDF (head.urdf.xacro: joints as xyz/rpy origins about local z axes) and the
real robot's iKin DH chain (vizzy_yarp_icub vizzyFwd.cpp), both in the robot's own signs.
The gaze controller's core is tested in test_gaze_core.py.
"""

import math

import numpy as np
import pytest

from vizzy_vision.camera import (
    camera_matrix,
    focal_length,
    fovy_deg,
    project,
    projection_matrix,
)
from vizzy_vision.frames import matrix_to_quaternion, rotation_matrix
from vizzy_vision.kinematics import (
    BASELINE,
    FRAME_NAMES,
    JOINT_LIMITS,
    JOINT_NAMES,
    VELOCITY_LIMIT,
    camera_poses,
    clamp_to_limits,
    eye_joints,
    fixation_from_joints,
    frames_in_base,
    from_robot_joints,
    gaze_angles,
    joint_transforms,
    static_transforms,
    to_robot_joints,
)

HOME = [0.0] * 5


def test_camera_matrix_matches_the_field_of_view() -> None:
    k = camera_matrix(640, 480, 85.4)
    assert k[0, 0] == pytest.approx(320.0 / math.tan(math.radians(42.7)))
    assert k[0, 0] == k[1, 1]
    assert (k[0, 2], k[1, 2]) == (319.5, 239.5)
    # the image edge is seen at half the field of view
    assert math.degrees(math.atan((639.5 - k[0, 2]) / k[0, 0])) == pytest.approx(42.7, abs=0.1)
    # MuJoCo's fovy (vertical) for the same camera
    assert math.tan(math.radians(fovy_deg(640, 480, 85.4)) / 2) * focal_length(640, 85.4) == (
        pytest.approx(240.0))


def test_projection_matrix_has_the_stereo_baseline() -> None:
    k = camera_matrix(640, 480, 85.4)
    p = projection_matrix(k, 0.204)
    assert p.shape == (3, 4)
    assert p[0, 3] == pytest.approx(-k[0, 0] * 0.204)
    np.testing.assert_array_equal(p[:, :3], k)
    assert projection_matrix(k)[0, 3] == 0.0


def test_project_puts_the_optical_axis_on_the_principal_point() -> None:
    k = camera_matrix(640, 480, 85.4)
    pose = camera_poses(HOME)['left']
    ahead = pose[:3, 3] + 2.0 * pose[:3, 2]
    behind = pose[:3, 3] - 2.0 * pose[:3, 2]
    uv = project(k, pose, np.array([ahead, behind]))
    np.testing.assert_allclose(uv[0], (319.5, 239.5), atol=1e-9)
    assert np.isnan(uv[1]).all()


def test_transforms_form_one_tree_rooted_at_base_link() -> None:
    transforms = joint_transforms(HOME) + static_transforms()
    children = [t.child for t in transforms]
    assert len(children) == len(set(children))
    assert {t.parent for t in transforms} - set(children) == {'base_link'}
    assert set(frames_in_base(HOME)) == set(FRAME_NAMES)
    for t in transforms:
        assert np.linalg.norm(t.rotation) == pytest.approx(1.0)


def test_the_real_robots_numbers() -> None:
    poses = frames_in_base(HOME)
    assert poses['neck_tilt_link'][2, 3] == pytest.approx(0.370)
    assert poses['ego'][:3, 3] == pytest.approx([0.0, 0.0, 0.370])
    left, right = poses['left_camera_optical_frame'], poses['right_camera_optical_frame']
    assert np.linalg.norm(left[:3, 3] - right[:3, 3]) == pytest.approx(BASELINE) == 0.204
    # each camera 0.0275 m in front of its eye's rotation axis
    for eye, cam in (('left_eye_link', left), ('right_eye_link', right)):
        assert cam[:3, 3] - poses[eye][:3, 3] == pytest.approx([0.0275, 0.0, 0.0])
    limits_deg = {n: tuple(round(math.degrees(v), 6) for v in lim)
                  for n, lim in JOINT_LIMITS.items()}
    assert limits_deg == {'neck_pan_joint': (-53, 53), 'neck_tilt_joint': (-37, 18),
                          'eyes_tilt_joint': (-38, 38), 'l_eye_joint': (-38, 38),
                          'r_eye_joint': (-38, 38)}
    assert VELOCITY_LIMIT == 5.0


def test_optical_frames_look_forward_with_x_right_and_y_down() -> None:
    poses = frames_in_base(HOME)
    for frame, side in (('left_camera_optical_frame', 1.0), ('right_camera_optical_frame', -1.0),
                        ('rgbd_camera_optical_frame', 0.0)):
        pose = poses[frame]
        assert pose[:3, 2][0] > 0.9                                       # z forward
        np.testing.assert_allclose(pose[:3, 0], [0, -1, 0], atol=1e-12)   # x right
        assert pose[:3, 1][2] < -0.9                                      # y down
        assert pose[1, 3] == pytest.approx(side * 0.102)


@pytest.mark.parametrize('joint, direction', [
    ('neck_pan_joint', 'left'), ('l_eye_joint', 'left'), ('r_eye_joint', 'left'),
    ('neck_tilt_joint', 'down'), ('eyes_tilt_joint', 'down')])
def test_joint_signs(joint, direction) -> None:
    """Positive pans look left, positive tilts look down (REP 103, as GazeState says)."""
    q = dict.fromkeys(JOINT_NAMES, 0.0)
    q[joint] = 0.2
    side = 'right' if joint == 'r_eye_joint' else 'left'
    axis = camera_poses(q)[side][:3, 2]
    if direction == 'left':
        assert axis[1] == pytest.approx(math.sin(0.2))
    else:
        assert axis[2] == pytest.approx(-math.sin(0.2))


def test_version_vergence_coupling() -> None:
    left, right = eye_joints(version=0.1, vergence=0.3)
    assert (left, right) == pytest.approx((-0.05, 0.25))
    version, vergence, tilt = gaze_angles({'l_eye_joint': left, 'r_eye_joint': right,
                                           'neck_tilt_joint': 0.1, 'eyes_tilt_joint': 0.2})
    assert (version, vergence, tilt) == pytest.approx((0.1, 0.3, 0.3))
    # in the real robot's signs: left = version + vergence / 2, right = version - vergence / 2
    robot = to_robot_joints({'l_eye_joint': left, 'r_eye_joint': right})
    assert robot['l_eye_joint'] == pytest.approx(-0.1 + 0.15)
    assert robot['r_eye_joint'] == pytest.approx(-0.1 - 0.15)
    assert from_robot_joints(robot) == pytest.approx(to_robot_joints(robot))


def test_clamping_names_each_clamped_joint() -> None:
    clamped, notes = clamp_to_limits({'neck_pan_joint': 2.0, 'l_eye_joint': 0.1})
    assert clamped['neck_pan_joint'] == JOINT_LIMITS['neck_pan_joint'][1]
    assert clamped['l_eye_joint'] == 0.1
    assert len(notes) == 1 and 'neck_pan_joint' in notes[0]
    with pytest.raises(KeyError):
        clamp_to_limits({'elbow': 0.0})


def test_quaternion_round_trip() -> None:
    rng = np.random.default_rng(1)
    for _ in range(50):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        q = q if q[3] >= 0 else -q
        np.testing.assert_allclose(matrix_to_quaternion(rotation_matrix(q)), q, atol=1e-12)


# ---- independent encodings of the real robot ------------------------------------------------

def _rot(axis: str, a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    m = np.eye(4)
    i, j = {'x': (1, 2), 'y': (2, 0), 'z': (0, 1)}[axis]
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def _tr(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    return _rot('z', y) @ _rot('y', p) @ _rot('x', r)


def _urdf_left_camera(q: dict[str, float]) -> np.ndarray:
    """l_camera_link in waist_link, vizzy_description head.urdf.xacro (robot signs)."""
    pi = math.pi
    neck_pan = _rpy(pi / 2, 0, 0) @ _rot('z', q['neck_pan_joint'])
    neck_tilt = neck_pan @ _tr(0, 0, -0.370) @ _rpy(pi / 2, 0, 0) @ _rot('z', q['neck_tilt_joint'])
    eyes_tilt = (neck_tilt @ _tr(-0.12379, -0.04755, 0) @ _rpy(pi, 0, -2.77199351787335)
                 @ _rot('z', q['eyes_tilt_joint']))
    eyes_center = eyes_tilt @ _rpy(pi / 2, 0, 0.369599135716446)
    l_eye = eyes_center @ _tr(0, 0.102, 0) @ _rpy(0, pi, 0) @ _rot('z', q['l_eye_joint'])
    return l_eye @ _tr(-0.0275, 0, 0) @ _rpy(0, pi, 0)


def _fkin_left_eye(q: dict[str, float]) -> np.ndarray:
    """Left eye end effector in the waist, vizzy_yarp_icub vizzyFwd.cpp (iKin DH; robot signs)."""
    def dh(a: float, d: float, alpha: float, theta: float) -> np.ndarray:
        return _rot('z', theta) @ _tr(0, 0, d) @ _tr(a, 0, 0) @ _rot('x', alpha)
    pi = math.pi
    h = np.zeros((4, 4))
    h[0, 0], h[1, 2], h[2, 1], h[3, 3] = 1.0, -1.0, 1.0, 1.0
    h = h @ dh(0, 0, pi / 2, 0.0)                                        # torso (blocked)
    h = h @ dh(0, -0.37, pi / 2, q['neck_pan_joint'])
    h = h @ dh(0.13261, 0, pi, 19 * pi / 17 + q['neck_tilt_joint'])
    h = h @ dh(0, 0.1015, pi / 2, -15 * pi / 17 + q['eyes_tilt_joint'])
    h = h @ dh(0, 0, pi / 2, -pi / 2 + q['l_eye_joint'])
    return h @ _tr(0, 0, 0.0275)


# waist_link (URDF: x back, y up, z left) and the iKin root (x back, y right, z up) in base_link
URDF_WAIST = np.array([[-1.0, 0, 0, 0], [0, 0, 1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])
FKIN_WAIST = np.diag([-1.0, -1.0, 1.0, 1.0])


@pytest.mark.parametrize('seed', range(6))
def test_chain_matches_the_urdf_and_fkin_in_robot_signs(seed) -> None:
    rng = np.random.default_rng(seed)
    ours = {n: float(rng.uniform(*JOINT_LIMITS[n])) if seed else 0.0 for n in JOINT_NAMES}
    robot = to_robot_joints(ours)
    cam = camera_poses(ours)['left']
    urdf = URDF_WAIST @ _urdf_left_camera(robot)    # camera link: x forward, y left, z up
    np.testing.assert_allclose(cam[:3, 3], urdf[:3, 3], atol=1e-5)
    np.testing.assert_allclose(cam[:3, 2], urdf[:3, 0], atol=1e-9)    # optical axis
    np.testing.assert_allclose(cam[:3, 0], -urdf[:3, 1], atol=1e-9)   # image right
    fkin = FKIN_WAIST @ _fkin_left_eye(robot)       # end effector: z optical axis, x right
    np.testing.assert_allclose(cam[:3, :3], fkin[:3, :3], atol=1e-9)
    # fKin: eyes 0.1015 m to the side (URDF 0.102) and the eyes tilt axis 21.18 deg
    # (2 pi / 17) above the neck tilt's forward direction (URDF 21.01 deg): within 1.5 mm
    assert np.linalg.norm(cam[:3, 3] - fkin[:3, 3]) < 1.5e-3


def test_converging_eyes_fixate_the_point_their_axes_meet() -> None:
    poses = frames_in_base(HOME)
    eyes = poses['eyes_tilt_link'][:3, 3]
    target = eyes + np.array([0.5, 0.0, 0.0])
    # each optical axis passes through its eye's rotation axis (the camera, 0.0275 m ahead,
    # swings with the eye), so turning each eye by atan(0.102 / 0.5) inwards aims it at target
    left, right = eye_joints(0.0, 2 * math.atan2(0.102, 0.5))
    assert left < 0 < right
    point = fixation_from_joints(dict(zip(JOINT_NAMES, [0.0, 0.0, 0.0, left, right], strict=True)))
    np.testing.assert_allclose(point, target, atol=1e-9)


def test_parallel_eyes_fixate_far_ahead() -> None:
    point = fixation_from_joints(HOME, max_distance=10.0)
    cams = camera_poses(HOME)
    assert point[0] == pytest.approx(10.0 + cams['left'][0, 3])
    assert point[1] == pytest.approx(0.0)
