"""ROS-free parts of vizzy_sim_bridge: camera model, kinematics, synthetic scene, gaze checks."""

import math

import numpy as np
import pytest

from vizzy_sim_bridge.core.camera import camera_matrix, projection_matrix
from vizzy_sim_bridge.core.gaze import (
    ActiveRequest, GazeStatus, check_fixation, check_joint_targets, preempts)
from vizzy_sim_bridge.core.kinematics import (
    JOINT_LIMITS, JOINT_NAMES, fixation_from_joints, frames_in_base, gaze_angles,
    joint_transforms, static_transforms)
from vizzy_sim_bridge.core.pattern import SyntheticStereoScene


def test_camera_matrix_matches_the_field_of_view() -> None:
    k = camera_matrix(640, 480, 85.4)
    assert k[0, 0] == pytest.approx(320.0 / math.tan(math.radians(42.7)))
    assert k[0, 0] == k[1, 1]
    assert (k[0, 2], k[1, 2]) == (319.5, 239.5)
    # the image edge is seen at half the field of view
    assert math.degrees(math.atan((639.5 - k[0, 2]) / k[0, 0])) == pytest.approx(42.7, abs=0.1)


def test_projection_matrix_has_the_stereo_baseline() -> None:
    k = camera_matrix(640, 480, 85.4)
    p = projection_matrix(k, 0.204)
    assert p.shape == (3, 4)
    assert p[0, 3] == pytest.approx(-k[0, 0] * 0.204)
    np.testing.assert_array_equal(p[:, :3], k)
    assert projection_matrix(k)[0, 3] == 0.0


def test_transforms_form_one_tree_rooted_at_base_link() -> None:
    transforms = joint_transforms([0.0] * 5) + static_transforms()
    children = [t.child for t in transforms]
    assert len(children) == len(set(children))
    assert {t.parent for t in transforms} - set(children) == {'base_link'}
    for t in transforms:
        assert np.linalg.norm(t.rotation) == pytest.approx(1.0)


def test_optical_frames_look_forward_with_x_right_and_y_down() -> None:
    poses = frames_in_base([0.0] * 5)
    for eye, side in (('left', 1.0), ('right', -1.0)):
        pose = poses[f'{eye}_camera_optical_frame']
        np.testing.assert_allclose(pose[:3, 2], [1, 0, 0], atol=1e-12)   # z forward
        np.testing.assert_allclose(pose[:3, 0], [0, -1, 0], atol=1e-12)  # x right
        np.testing.assert_allclose(pose[:3, 1], [0, 0, -1], atol=1e-12)  # y down
        assert pose[1, 3] == pytest.approx(side * 0.102)
    assert poses['ego'][2, 3] == pytest.approx(0.370)


def test_converging_eyes_fixate_the_point_their_axes_meet() -> None:
    # both cameras aim at a point 0.5 m ahead of the eyes on the midplane
    poses = frames_in_base([0.0] * 5)
    eyes_z = poses['eyes_tilt_link'][2, 3]
    a = math.atan2(0.102, 0.5)  # eye rotation; the camera centre rotates with the eye
    q = dict(zip(JOINT_NAMES, [0.0, 0.0, 0.0, -a, a]))
    point = fixation_from_joints(q)
    assert point[1] == pytest.approx(0.0, abs=1e-9)
    assert point[2] == pytest.approx(eyes_z)
    assert point[0] == pytest.approx(0.5, abs=1e-9)
    version, vergence, tilt = gaze_angles(q)
    assert (version, tilt) == (0.0, 0.0)
    assert vergence == pytest.approx(2 * a)


def test_parallel_eyes_fixate_far_ahead() -> None:
    point = fixation_from_joints([0.0] * 5, max_distance=10.0)
    assert point[0] == pytest.approx(10.0 + 0.0275)
    assert point[1] == pytest.approx(0.0)


def test_scene_renders_rgb_frames_with_disparity() -> None:
    scene = SyntheticStereoScene(64, 48, background_disparity_px=0.0, disk_disparity_px=5.0)
    left, right = scene.render(1.0, 'left'), scene.render(1.0, 'right')
    assert left.shape == (48, 64, 3) and left.dtype == np.uint8
    yellow_l = np.argwhere((left == (250, 230, 40)).all(axis=-1))
    yellow_r = np.argwhere((right == (250, 230, 40)).all(axis=-1))
    assert len(yellow_l) and len(yellow_r)
    assert yellow_l[:, 1].mean() - yellow_r[:, 1].mean() == pytest.approx(5.0, abs=1.0)
    assert not np.array_equal(scene.render(0.0), scene.render(2.0))
    with pytest.raises(ValueError):
        scene.render(0.0, 'middle')


def test_fixation_checks() -> None:
    assert check_fixation((1.0, 0.0, 0.0), 'base_link', 0.1, 10.0)[0] == GazeStatus.OK
    assert check_fixation((math.nan, 0.0, 0.0), 'ego', 0.1, 10.0)[0] == GazeStatus.REJECTED_NAN
    assert check_fixation((math.inf, 0.0, 0.0), 'ego', 0.1, 10.0)[0] == GazeStatus.REJECTED_NAN
    assert check_fixation((1.0, 0.0, 0.0), '', 0.1, 10.0)[0] == GazeStatus.REJECTED_UNKNOWN_FRAME
    status, why = check_fixation((100.0, 0.0, 0.0), 'ego', 0.1, 10.0)
    assert status == GazeStatus.REJECTED_UNREACHABLE and '100.000 m' in why


def test_joint_target_checks() -> None:
    ok = check_joint_targets(['neck_pan_joint'], [0.2], JOINT_LIMITS)
    assert ok == (GazeStatus.OK, '')
    assert check_joint_targets(['neck_pan_joint'], [0.1, 0.2], JOINT_LIMITS)[0] == (
        GazeStatus.REJECTED_INVALID)
    assert check_joint_targets(['elbow'], [0.1], JOINT_LIMITS)[0] == GazeStatus.REJECTED_INVALID
    assert check_joint_targets(['l_eye_joint'], [math.nan], JOINT_LIMITS)[0] == (
        GazeStatus.REJECTED_NAN)
    assert check_joint_targets(['l_eye_joint'], [3.0], JOINT_LIMITS)[0] == (
        GazeStatus.REJECTED_UNREACHABLE)
    assert check_joint_targets([], [], JOINT_LIMITS)[0] == GazeStatus.REJECTED_INVALID


def test_status_names_match_the_message_constants() -> None:
    from pathlib import Path
    msg = Path(__file__).resolve().parents[3] / 'msgs' / 'msg' / 'GazeState.msg'
    if not msg.is_file():
        pytest.skip('active_vision_msgs sources not beside this package')
    constants = {line.split()[1].split('=')[0] for line in msg.read_text().splitlines()
                 if line.startswith('uint8 STATUS_')}
    assert {f'STATUS_{s.name}' for s in GazeStatus} == constants


def test_arbitration_by_priority_then_hold_time() -> None:
    active = ActiveRequest('mot_planner', priority=5, since=10.0, hold_time=1.0)
    assert preempts(None, 0, 0.0)
    assert preempts(active, 5, 10.1)          # same priority: the newest wins
    assert preempts(active, 7, 10.1)
    assert not preempts(active, 1, 10.5)      # lower priority, active still held
    assert preempts(active, 1, 11.0)          # hold over
