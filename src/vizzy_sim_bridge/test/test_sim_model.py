"""The MuJoCo head: bodies, frames and cameras equal core.kinematics; servo dynamics; targets."""

import math

import mujoco
import numpy as np
import pytest

from vizzy_runtime.testing import scaled, wait_until
from vizzy_sim_bridge.core.model import HeadSimulation, build_mjcf
from vizzy_sim_bridge.core.scenes import Scene
from vizzy_vision.kinematics import (
    FRAME_NAMES,
    JOINT_LIMITS,
    JOINT_NAMES,
    VELOCITY_LIMIT,
    WAIST_HEIGHT,
    frames_in_base,
)

EMPTY = Scene(name='empty', seed=0, assets_xml='', worldbody_xml='')
BODIES = ('base_link', 'neck_pan_link', 'neck_tilt_link', 'eyes_tilt_link', 'left_eye_link',
          'right_eye_link', 'rgbd_camera_link')
SITES = ('left_camera_optical_frame', 'right_camera_optical_frame', 'ego', 'cyclopean',
         'rgbd_camera_optical_frame')
CAMERAS = {'left_camera': 'left_camera_optical_frame', 'right_camera': 'right_camera_optical_frame',
           'rgbd_camera': 'rgbd_camera_optical_frame'}
# MuJoCo cameras look along -z with y up: optical frame = camera frame @ diag(1, -1, -1)
MJ_TO_OPTICAL = np.diag([1.0, -1.0, -1.0])


@pytest.fixture(scope='module')
def sim() -> HeadSimulation:
    return HeadSimulation(EMPTY)


def _pose(pos: np.ndarray, mat: np.ndarray) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = np.asarray(mat).reshape(3, 3)
    t[:3, 3] = pos
    return t


def test_mujoco_poses_equal_the_kinematic_chain(sim) -> None:
    m, d = sim.model, sim.data
    world_to_base = np.eye(4)
    world_to_base[2, 3] = -WAIST_HEIGHT
    rng = np.random.default_rng(0)
    for trial in range(25):
        q = {n: float(rng.uniform(*JOINT_LIMITS[n])) if trial else 0.0 for n in JOINT_NAMES}
        d.qpos[sim.qpos_adr] = [q[n] for n in JOINT_NAMES]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)
        expected = frames_in_base(q)
        seen = set()
        for name in BODIES:
            i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
            got = world_to_base @ _pose(d.xpos[i], d.xmat[i])
            np.testing.assert_allclose(got, expected[name], atol=1e-6, err_msg=name)
            seen.add(name)
        for name in SITES:
            i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, name)
            got = world_to_base @ _pose(d.site_xpos[i], d.site_xmat[i])
            np.testing.assert_allclose(got, expected[name], atol=1e-6, err_msg=name)
            seen.add(name)
        for cam, frame in CAMERAS.items():
            i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, cam)
            got = world_to_base @ _pose(d.cam_xpos[i], d.cam_xmat[i].reshape(3, 3) @ MJ_TO_OPTICAL)
            np.testing.assert_allclose(got, expected[frame], atol=1e-6, err_msg=cam)
        assert seen == set(FRAME_NAMES)


def test_joints_ranges_and_cameras_in_the_model(sim) -> None:
    m = sim.model
    for name in JOINT_NAMES:
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        np.testing.assert_allclose(m.jnt_range[j], JOINT_LIMITS[name])
        a = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        np.testing.assert_allclose(m.actuator_ctrlrange[a], JOINT_LIMITS[name])
    eye = m.cam_fovy[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, 'left_camera')]
    hfov = 2 * math.degrees(math.atan(math.tan(math.radians(eye) / 2) * 640 / 480))
    assert hfov == pytest.approx(85.4)
    rgbd = m.cam_fovy[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, 'rgbd_camera')]
    assert 2 * math.degrees(math.atan(math.tan(math.radians(rgbd) / 2) * 640 / 480)) == (
        pytest.approx(58.0))
    assert m.opt.timestep == 0.002
    assert m.vis.quality.shadowsize == 0 and m.vis.quality.offsamples == 0
    assert 'mesh' not in build_mjcf(EMPTY)


def _step_response(joint: str, target: float, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    sim = HeadSimulation(EMPTY)
    i = JOINT_NAMES.index(joint)
    assert sim.set_targets({joint: target}) == []
    times, positions = [], []
    for _ in range(int(round(seconds / sim.dt))):
        sim.step()
        s = sim.sample()
        times.append(s.time)
        positions.append(s.position[i])
    return np.array(times), np.array(positions)


@pytest.mark.parametrize('joint, max_settle_s', [
    ('l_eye_joint', 0.10), ('r_eye_joint', 0.10), ('eyes_tilt_joint', 0.12),
    ('neck_pan_joint', 0.18), ('neck_tilt_joint', 0.20)])
def test_a_20_degree_step_is_fast_but_not_instantaneous(joint, max_settle_s) -> None:
    """In sim time: within the velocity limit, settled to 0.1 deg in the documented time."""
    target = min(math.radians(20.0), JOINT_LIMITS[joint][1])
    t, q = _step_response(joint, target, 0.4)
    velocity = np.diff(q) / np.diff(t)
    assert np.max(np.abs(velocity)) <= 1.05 * VELOCITY_LIMIT
    assert q[np.searchsorted(t, 0.05)] < 0.9 * target          # not instantaneous
    off = np.abs(q - target) > math.radians(0.1)
    settle = t[np.nonzero(off)[0][-1] + 1]
    assert settle <= max_settle_s, f'{joint} settles in {settle * 1000:.0f} ms'
    assert abs(q[-1] - target) < 1e-4                          # no steady-state error
    assert np.max(q) - target < math.radians(0.5)               # little overshoot


def test_targets_are_clamped_and_unknown_joints_refused() -> None:
    sim = HeadSimulation(EMPTY)
    notes = sim.set_targets({'neck_pan_joint': 3.0, 'l_eye_joint': -3.0, 'r_eye_joint': 0.1})
    assert len(notes) == 2 and any('neck_pan_joint' in n for n in notes)
    targets = sim.targets()
    assert targets['neck_pan_joint'] == JOINT_LIMITS['neck_pan_joint'][1]
    assert targets['l_eye_joint'] == JOINT_LIMITS['l_eye_joint'][0]
    assert targets['r_eye_joint'] == 0.1
    with pytest.raises(KeyError, match='elbow'):
        sim.set_targets({'elbow': 0.0, 'r_eye_joint': 0.3})
    assert sim.targets()['r_eye_joint'] == 0.1                  # nothing changed
    sim.step(300)
    q = sim.sample().position
    for name, value in zip(JOINT_NAMES, q, strict=True):
        lo, hi = JOINT_LIMITS[name]
        assert lo - 1e-3 <= value <= hi + 1e-3


def test_a_slower_speed_can_be_asked_for() -> None:
    sim = HeadSimulation(EMPTY)
    sim.set_targets({'l_eye_joint': 0.3}, speeds={'l_eye_joint': 1.0})
    sim.step(100)   # 0.2 s at 1 rad/s: about 0.2 rad, not yet 0.3
    assert 0.15 < sim.sample().position[3] < 0.25


def test_initial_posture_and_real_time_thread() -> None:
    sim = HeadSimulation(EMPTY, {'neck_tilt_joint': 0.2, 'l_eye_joint': 9.0})
    assert sim.sample().position[1] == pytest.approx(0.2)
    assert sim.sample().position[3] == pytest.approx(JOINT_LIMITS['l_eye_joint'][1])
    sim.start()
    try:
        assert wait_until(lambda: sim.steps >= 20, scaled(2.0))
        assert sim.time > 0.0
    finally:
        sim.stop()
