"""The head's URDF (core.urdf): its forward kinematics equal the sim's /tf and the MuJoCo model.

The URDF is read back with a small forward-kinematics helper written here (xml.etree + scipy's
Rotation, URDF's conventions: origin = translation then fixed-axis roll-pitch-yaw, a revolute
joint turns about its axis in the child frame after the origin) and, independently, with
MuJoCo's own URDF importer. Both must equal, to 1e-6 for random joint states within the limits:
the transforms the sim node puts on /tf and /tf_static (sim_node.transform_messages over
kinematics.joint_transforms, static_transforms and world_transform, composed here), and the
poses of the MuJoCo model the sim steps (HeadSimulation: bodies and sites after mj_kinematics).
"""

from __future__ import annotations

import importlib.util
import math
import sys
import types
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from vizzy_runtime.ros import message
from vizzy_sim_bridge import head_urdf as head_urdf_cli
from vizzy_sim_bridge.core.model import HeadSimulation
from vizzy_sim_bridge.core.scenes import Scene
from vizzy_sim_bridge.core.urdf import EFFORT_LIMIT, head_urdf, matrix_to_rpy
from vizzy_sim_bridge.sim_node import transform_messages
from vizzy_vision.kinematics import (
    FRAME_NAMES,
    JOINT_LIMITS,
    JOINT_NAMES,
    VELOCITY_LIMITS,
    frames_in_base,
    joint_transforms,
    static_transforms,
    world_transform,
)

TOL = 1e-6
TRIALS = 20
EMPTY = Scene(name='empty', seed=0, assets_xml='', worldbody_xml='')
PACKAGE = Path(__file__).resolve().parents[1]
TimeMsg = message('builtin_interfaces/msg/Time')


# ------------------------------------------------------------------ readers of the URDF
def _floats(text: str | None, n: int = 3) -> np.ndarray:
    values = np.array([float(v) for v in (text or ' '.join(['0'] * n)).split()])
    assert values.shape == (n,), text
    return values


def urdf_fk(urdf: str, q: dict[str, float]) -> dict[str, np.ndarray]:
    """4x4 pose of every link in the URDF's root link, for joint positions q [rad]."""
    robot = ET.fromstring(urdf)
    joints = robot.findall('joint')
    children = {j.find('child').get('link') for j in joints}
    roots = [link.get('name') for link in robot.findall('link') if link.get('name') not in children]
    assert len(roots) == 1, roots
    poses = {roots[0]: np.eye(4)}
    pending = list(joints)
    while pending:
        ready = [j for j in pending if j.find('parent').get('link') in poses]
        assert ready, [j.get('name') for j in pending]
        for j in ready:
            origin = j.find('origin')
            t = np.eye(4)
            if origin is not None:
                t[:3, :3] = Rotation.from_euler('xyz', _floats(origin.get('rpy'))).as_matrix()
                t[:3, 3] = _floats(origin.get('xyz'))
            if j.get('type') in ('revolute', 'continuous'):
                motion = np.eye(4)
                motion[:3, :3] = Rotation.from_rotvec(
                    _floats(j.find('axis').get('xyz')) * q[j.get('name')]).as_matrix()
                t = t @ motion
            else:
                assert j.get('type') == 'fixed', j.get('type')
            poses[j.find('child').get('link')] = poses[j.find('parent').get('link')] @ t
        pending = [j for j in pending if j not in ready]
    return poses


def mujoco_urdf_fk(urdf: str, q: dict[str, float]) -> dict[str, np.ndarray]:
    """The same, by MuJoCo's URDF importer (static links kept as bodies)."""
    robot = ET.fromstring(urdf)
    ET.SubElement(ET.SubElement(robot, 'mujoco'), 'compiler', fusestatic='false')
    model = mujoco.MjModel.from_xml_string(ET.tostring(robot, encoding='unicode'))
    data = mujoco.MjData(model)
    for name, value in q.items():
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = value
    mujoco.mj_kinematics(model, data)
    return {model.body(i).name: _pose(data.xpos[i], data.xmat[i]) for i in range(1, model.nbody)}


# ------------------------------------------------------------------ the sim's tf and MuJoCo
def _pose(pos: np.ndarray, mat: np.ndarray) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = np.asarray(mat).reshape(3, 3)
    t[:3, 3] = pos
    return t


def tf_fk(q: dict[str, float], root: str) -> dict[str, np.ndarray]:
    """Every frame in root, composed from the TransformStamped messages the sim publishes on
    /tf (joints) and /tf_static (world and the fixed frames)."""
    stamp = TimeMsg(sec=1, nanosec=0)
    msgs = (transform_messages(joint_transforms(q), stamp)
            + transform_messages([world_transform()] + static_transforms(), stamp))
    edges = {}
    for m in msgs:
        r, p = m.transform.rotation, m.transform.translation
        edges[m.child_frame_id] = (m.header.frame_id, _pose(
            (p.x, p.y, p.z), Rotation.from_quat((r.x, r.y, r.z, r.w)).as_matrix()))

    def in_root(frame: str) -> np.ndarray:
        if frame == root:
            return np.eye(4)
        parent, t = edges[frame]
        return in_root(parent) @ t

    frames = set(edges) | {p for p, _ in edges.values()}
    return {f: in_root(f) for f in frames if f == root or root in _ancestors(f, edges)}


def _ancestors(frame: str, edges: dict[str, tuple[str, np.ndarray]]) -> set[str]:
    out = set()
    while frame in edges:
        frame = edges[frame][0]
        out.add(frame)
    return out


@pytest.fixture(scope='module')
def sim() -> HeadSimulation:
    return HeadSimulation(EMPTY)   # the model the sim node builds (any scene: the same head)


def mujoco_fk(sim: HeadSimulation, q: dict[str, float]) -> dict[str, np.ndarray]:
    """Every head frame in the MuJoCo world: bodies, and sites for the frames without a body."""
    m, d = sim.model, sim.data
    d.qpos[sim.qpos_adr] = [q[n] for n in JOINT_NAMES]
    mujoco.mj_kinematics(m, d)
    out = {'world': np.eye(4)}
    for name in FRAME_NAMES:
        body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        if body >= 0:
            out[name] = _pose(d.xpos[body], d.xmat[body])
        else:
            site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, name)
            assert site >= 0, name
            out[name] = _pose(d.site_xpos[site], d.site_xmat[site])
    return out


def random_postures(n: int, seed: int = 0) -> list[dict[str, float]]:
    rng = np.random.default_rng(seed)
    postures = [{name: float(rng.uniform(*JOINT_LIMITS[name])) for name in JOINT_NAMES}
                for _ in range(n)]
    postures[0] = {name: JOINT_LIMITS[name][i % 2] for i, name in enumerate(JOINT_NAMES)}
    return postures


def _max_difference(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> float:
    assert set(a) == set(b), set(a) ^ set(b)
    return max(float(np.max(np.abs(a[k] - b[k]))) for k in a)


# ------------------------------------------------------------------ tests
def test_urdf_forward_kinematics_equal_the_published_tf_and_the_mujoco_model(sim) -> None:
    urdf_base, urdf_world = head_urdf(), head_urdf(world=True)
    worst = {'urdf-tf': 0.0, 'urdf-mujoco': 0.0, 'mujoco-urdf-import': 0.0,
             'urdf-frames_in_base': 0.0}
    for q in random_postures(TRIALS):
        urdf = urdf_fk(urdf_world, q)                          # in world
        assert set(urdf) == set(FRAME_NAMES) | {'world'}
        worst['urdf-tf'] = max(worst['urdf-tf'], _max_difference(urdf, tf_fk(q, 'world')))
        worst['urdf-mujoco'] = max(worst['urdf-mujoco'], _max_difference(urdf, mujoco_fk(sim, q)))
        imported = mujoco_urdf_fk(urdf_world, q)
        worst['mujoco-urdf-import'] = max(worst['mujoco-urdf-import'], _max_difference(
            {k: v for k, v in urdf.items() if k != 'world'}, imported))
        base = urdf_fk(urdf_base, q)                           # rooted at base_link
        worst['urdf-frames_in_base'] = max(worst['urdf-frames_in_base'],
                                           _max_difference(base, frames_in_base(q)))
    print(f'largest |difference| of a 4x4 pose entry over {TRIALS} postures: {worst}')
    assert all(v <= TOL for v in worst.values()), worst


def test_joints_axes_limits_and_frames() -> None:
    robot = ET.fromstring(head_urdf())
    assert robot.tag == 'robot' and robot.get('name') == 'vizzy_head'
    assert sorted(link.get('name') for link in robot.findall('link')) == sorted(FRAME_NAMES)
    joints = {j.get('name'): j for j in robot.findall('joint')}
    revolute = {n: j for n, j in joints.items() if j.get('type') == 'revolute'}
    assert sorted(revolute) == sorted(JOINT_NAMES)
    assert all(j.get('type') == 'fixed' for n, j in joints.items() if n not in revolute)
    axes = {'neck_pan_joint': (0, 0, 1), 'neck_tilt_joint': (0, 1, 0),
            'eyes_tilt_joint': (0, 1, 0), 'l_eye_joint': (0, 0, 1), 'r_eye_joint': (0, 0, 1)}
    parents = {t.child: t.parent for t in joint_transforms({}) + static_transforms()}
    for name, j in joints.items():
        child = j.find('child').get('link')
        assert j.find('parent').get('link') == parents[child], name
    for name, j in revolute.items():
        np.testing.assert_array_equal(_floats(j.find('axis').get('xyz')), axes[name])
        limit = j.find('limit')
        assert (float(limit.get('lower')), float(limit.get('upper'))) == JOINT_LIMITS[name]
        assert float(limit.get('velocity')) == VELOCITY_LIMITS[name] == 5.0
        assert float(limit.get('effort')) == EFFORT_LIMIT > 0.0
    # the optical frames: z forward, x right, y down (REP 103), rpy = (-pi/2, 0, -pi/2)
    optical = joints['left_camera_optical_frame_joint'].find('origin')
    np.testing.assert_allclose(_floats(optical.get('rpy')), (-math.pi / 2, 0, -math.pi / 2))
    np.testing.assert_allclose(_floats(optical.get('xyz')), (0.0275, 0, 0))
    # with world: one more link and the fixed joint the sim publishes on /tf_static
    world = ET.fromstring(head_urdf(world=True))
    base = next(j for j in world.findall('joint') if j.find('child').get('link') == 'base_link')
    assert base.find('parent').get('link') == 'world' and base.get('type') == 'fixed'
    np.testing.assert_allclose(_floats(base.find('origin').get('xyz')),
                               world_transform().translation)


def test_visuals_and_inertials_come_from_the_mujoco_model(sim) -> None:
    robot = ET.fromstring(head_urdf())
    links = {link.get('name'): link for link in robot.findall('link')}
    m = sim.model
    for name, link in links.items():
        body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        if body < 0:   # frames that are sites in MuJoCo: nothing to draw or weigh
            assert not list(link), name
            continue
        assert link.findall('visual'), name
        inertial = link.find('inertial')
        if name == 'base_link':   # the root: welded to the world, no inertial (KDL warns)
            assert inertial is None
            continue
        assert float(inertial.find('mass').get('value')) == pytest.approx(m.body_mass[body])
        inertia = inertial.find('inertia')
        np.testing.assert_allclose([float(inertia.get(k)) for k in ('ixx', 'iyy', 'izz')],
                                   m.body_inertia[body], rtol=1e-8)
    # the eye: a 22 mm sphere at the rotation centre and the dark pupil cylinder in front
    eye = links['left_eye_link'].findall('visual')
    shapes = sorted((v.find('geometry')[0].tag, float(v.find('geometry')[0].get('radius')))
                    for v in eye)
    assert shapes == [('cylinder', 0.009), ('sphere', 0.022)]
    names = {mat.get('name') for mat in robot.findall('material')}
    assert all(v.find('material').get('name') in names
               for link in links.values() for v in link.findall('visual'))


def test_rpy_conversion_round_trips() -> None:
    rng = np.random.default_rng(1)
    for rot in Rotation.random(200, random_state=rng):
        rpy = matrix_to_rpy(rot.as_matrix())
        np.testing.assert_allclose(Rotation.from_euler('xyz', rpy).as_matrix(), rot.as_matrix(),
                                   atol=1e-12)
    lock = Rotation.from_euler('xyz', (0.3, math.pi / 2, -0.2)).as_matrix()  # gimbal lock
    np.testing.assert_allclose(Rotation.from_euler('xyz', matrix_to_rpy(lock)).as_matrix(), lock,
                               atol=1e-9)


def test_console_script_prints_and_writes(tmp_path, capsys) -> None:
    assert head_urdf_cli.main([]) == 0
    assert capsys.readouterr().out == head_urdf()
    out = tmp_path / 'vizzy.urdf'
    assert head_urdf_cli.main(['-o', str(out), '--world']) == 0
    assert out.read_text() == head_urdf(world=True)
    assert head_urdf_cli.main(['-o', str(tmp_path / 'missing' / 'x.urdf')]) == 1
    assert 'cannot write' in capsys.readouterr().err


class _Recorded:
    """Stands in for a launch / launch_ros class: keeps its arguments."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args, self.kwargs = args, kwargs


def _fake_launch_modules(monkeypatch) -> None:
    """Just enough of launch, launch_ros and ament_index_python to build the descriptions."""
    fakes = {
        'ament_index_python': {}, 'launch_ros': {},
        'ament_index_python.packages': {
            'get_package_share_directory': lambda pkg: f'/opt/share/{pkg}'},
        'launch': {'LaunchDescription': lambda actions: list(actions)},
        'launch.actions': {'DeclareLaunchArgument': _Recorded},
        'launch.conditions': {'IfCondition': _Recorded},
        'launch.substitutions': {'LaunchConfiguration': _Recorded},
        'launch_ros.actions': {'Node': _Recorded},
        'launch_ros.parameter_descriptions': {'ParameterValue': _Recorded},
    }
    for name, attrs in fakes.items():
        module = types.ModuleType(name)
        module.__dict__.update(attrs)
        monkeypatch.setitem(sys.modules, name, module)


def _load_launch(path: Path) -> list[Any]:
    spec = importlib.util.spec_from_file_location(path.stem.replace('.', '_'), path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.generate_launch_description()


def test_launch_files_feed_robot_state_publisher_and_rviz(monkeypatch) -> None:
    _fake_launch_modules(monkeypatch)
    actions = _load_launch(PACKAGE / 'launch' / 'robot_state_publisher.launch.py')
    nodes = {a.kwargs['executable']: a for a in actions if 'executable' in a.kwargs}
    rsp = nodes['robot_state_publisher']
    value = rsp.kwargs['parameters'][0]['robot_description']
    assert value.args == (head_urdf(),) and value.kwargs == {'value_type': str}
    assert nodes['rviz2'].kwargs['arguments'] == [
        '-d', '/opt/share/vizzy_runtime/config/vizzy.rviz']
    actions = _load_launch(PACKAGE / 'launch' / 'rviz.launch.py')
    (rviz,) = [a for a in actions if 'executable' in a.kwargs]
    assert rviz.kwargs['arguments'] == ['-d', '/opt/share/vizzy_runtime/config/vizzy.rviz']
