"""Rendering: what MuJoCo draws agrees with CameraInfo (K, P) and the tf chain; depth is metric;
a missing renderer names the package to install. Skipped where no offscreen OpenGL works."""

import math

import mujoco
import numpy as np
import pytest

from vizzy_runtime.testing import no_renderer
from vizzy_sim_bridge.core import render as render_mod
from vizzy_sim_bridge.core.model import CameraSpec, HeadSimulation
from vizzy_sim_bridge.core.rgbd import DepthProjector
from vizzy_sim_bridge.core.scenes import Scene, build_scene
from vizzy_vision.camera import camera_matrix, project
from vizzy_vision.kinematics import JOINT_LIMITS, JOINT_NAMES, WAIST_HEIGHT, frames_in_base


@pytest.fixture(scope='module')
def backend() -> str:
    try:
        return render_mod.select_backend()
    except render_mod.RendererUnavailable as exc:
        no_renderer(str(exc))


def test_a_missing_renderer_names_the_debian_packages(monkeypatch) -> None:
    monkeypatch.delenv('MUJOCO_GL', raising=False)   # 'auto' tries EGL, then OSMesa

    def nothing_works(backend: str) -> str:
        return f'lib{backend}.so: cannot open shared object file'
    with pytest.raises(render_mod.RendererUnavailable) as err:
        render_mod.select_backend('auto', probe=nothing_works)
    assert 'libegl1' in str(err.value) and 'libosmesa6' in str(err.value)
    assert render_mod.select_backend('auto', probe=lambda b: None if b == 'osmesa' else 'no') == (
        'osmesa')
    with pytest.raises(ValueError):
        render_mod.select_backend('vulkan', probe=nothing_works)
    monkeypatch.setenv('MUJOCO_GL', 'osmesa')         # a user's choice is the only one tried
    with pytest.raises(render_mod.RendererUnavailable, match='osmesa'):
        render_mod.select_backend('auto', probe=nothing_works)


def test_smoke_render_at_reduced_resolution(backend) -> None:
    spec = CameraSpec(160, 120, 85.4)
    sim = HeadSimulation(build_scene('tabletop', 0), {'neck_tilt_joint': 0.3},
                         eye=spec, rgbd=CameraSpec(160, 120, 58.0))
    data = mujoco.MjData(sim.model)
    sim.snapshot_into(data)
    mujoco.mj_forward(sim.model, data)
    with render_mod.CameraRenderer(sim.model, 160, 120, backend) as renderer:
        for cam in ('left_camera', 'right_camera', 'rgbd_camera'):
            rgb, depth = renderer.render(data, cam, depth=True)
            assert rgb.shape == (120, 160, 3) and rgb.dtype == np.uint8
            assert rgb.std() > 10.0                        # a scene, not a blank image
            assert depth.shape == (120, 160) and np.isfinite(depth).all()
            assert 0.2 < depth.min() < depth.max() < 10.0
        left, _ = renderer.render(data, 'left_camera')
        left = left.copy()
        right, _ = renderer.render(data, 'right_camera')
        assert not np.array_equal(left, right)             # two viewpoints


def _spheres_scene(points_world: np.ndarray, radii: np.ndarray) -> Scene:
    geoms = '\n'.join(
        f'<geom name="dot{i}" type="sphere" size="{r}" pos="{p[0]} {p[1]} {p[2]}" '
        f'material="glow"/>' for i, (p, r) in enumerate(zip(points_world, radii, strict=True)))
    return Scene(name='dots', seed=0, worldbody_xml=geoms,
                 assets_xml='<material name="glow" rgba="1 1 1 1" emission="1" specular="0"/>')


def _centroids(rgb: np.ndarray) -> list[np.ndarray]:
    import cv2
    mask = (rgb.min(axis=2) > 200).astype(np.uint8)
    n, labels, stats, cents = cv2.connectedComponentsWithStats(mask)
    return [cents[i] for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] >= 12]


@pytest.mark.parametrize('seed', range(4))
def test_known_points_render_where_camera_info_projects_them(backend, seed) -> None:
    """Reprojection error < 1 px: small bright spheres at known 3D points, any eye posture."""
    rng = np.random.default_rng(seed)
    q = {n: float(rng.uniform(*JOINT_LIMITS[n])) * 0.6 if seed else 0.0 for n in JOINT_NAMES}
    poses = frames_in_base(q)
    k = camera_matrix(640, 480, 85.4)
    left = poses['left_camera_optical_frame']
    # points spread over the left image at 0.6-2.5 m, expressed in base_link
    uv = np.array([[80, 60], [560, 70], [320, 240], [100, 420], [540, 400], [250, 330]], float)
    depth = rng.uniform(0.6, 2.5, len(uv))
    rays = np.column_stack([(uv[:, 0] - k[0, 2]) / k[0, 0], (uv[:, 1] - k[1, 2]) / k[1, 1],
                            np.ones(len(uv))])
    points = (rays * depth[:, None]) @ left[:3, :3].T + left[:3, 3]
    world = points + np.array([0.0, 0.0, WAIST_HEIGHT])
    sim = HeadSimulation(_spheres_scene(world, 0.008 * depth), q)   # ~3 px across
    data = mujoco.MjData(sim.model)
    sim.snapshot_into(data)
    mujoco.mj_forward(sim.model, data)
    with render_mod.CameraRenderer(sim.model, 640, 480, backend) as renderer:
        for side in ('left', 'right'):
            rgb, _ = renderer.render(data, f'{side}_camera')
            seen = _centroids(rgb)
            expected = project(k, poses[f'{side}_camera_optical_frame'], points)
            expected = expected[np.isfinite(expected).all(axis=1)
                                & (expected[:, 0] > 8) & (expected[:, 0] < 631)
                                & (expected[:, 1] > 8) & (expected[:, 1] < 471)]
            assert len(seen) == len(expected) >= (6 if side == 'left' else 3)
            for e in expected:
                err = min(np.linalg.norm(s - e) for s in seen)
                assert err < 1.0, f'{side}: a sphere at {e} px renders {err:.2f} px away'


def test_right_camera_projection_matches_p_with_the_baseline(backend) -> None:
    """At zero vergence the pair is rectified: a point's disparity is fx * baseline / z, as the
    right CameraInfo's P (Tx = -fx * baseline) says."""
    from vizzy_vision.camera import projection_matrix
    from vizzy_vision.kinematics import BASELINE
    k = camera_matrix(640, 480, 85.4)
    poses = frames_in_base([0.0] * 5)
    left = poses['left_camera_optical_frame']
    p_cam = np.array([0.1, -0.05, 1.2])                 # in the left optical frame
    point = left[:3, :3] @ p_cam + left[:3, 3]
    sim = HeadSimulation(_spheres_scene(point[None] + [0, 0, WAIST_HEIGHT], [0.01]))
    data = mujoco.MjData(sim.model)
    sim.snapshot_into(data)
    mujoco.mj_forward(sim.model, data)
    p_right = projection_matrix(k, BASELINE)
    uvw = p_right @ np.append(p_cam, 1.0)
    expected_right = uvw[:2] / uvw[2]
    with render_mod.CameraRenderer(sim.model, 640, 480, backend) as renderer:
        rgb, _ = renderer.render(data, 'right_camera')
        (seen,) = _centroids(rgb)
    assert np.linalg.norm(seen - expected_right) < 1.0


def test_depth_is_the_distance_along_the_optical_axis(backend) -> None:
    """A wall 1.5 m ahead of the RGB-D sensor, square to its axis: depth 1.5 m everywhere, and
    the back-projected cloud lies on the wall."""
    poses = frames_in_base([0.0] * 5)
    cam = poses['rgbd_camera_optical_frame']
    centre = cam[:3, 3] + 1.5 * cam[:3, 2] + [0.0, 0.0, WAIST_HEIGHT]
    normal = -cam[:3, 2]
    from vizzy_vision.frames import matrix_to_quaternion
    rot = np.column_stack([cam[:3, 0], -cam[:3, 1], normal])   # plane z = normal, right-handed
    x, y, z, w = matrix_to_quaternion(rot)
    wall = (f'<geom type="plane" size="5 5 0.5" pos="{centre[0]} {centre[1]} {centre[2]}" '
            f'quat="{w} {x} {y} {z}" rgba="0.6 0.6 0.6 1"/>')
    sim = HeadSimulation(Scene(name='wall', seed=0, assets_xml='', worldbody_xml=wall))
    data = mujoco.MjData(sim.model)
    sim.snapshot_into(data)
    mujoco.mj_forward(sim.model, data)
    with render_mod.CameraRenderer(sim.model, 640, 480, backend) as renderer:
        rgb, depth = renderer.render(data, 'rgbd_camera', depth=True)
    assert np.abs(depth - 1.5).max() < 2e-3
    k = camera_matrix(640, 480, 58.0)
    cloud = DepthProjector(k, 640, 480).cloud(depth, rgb)
    corner = cloud[0, 0]
    half_w = 1.5 * 319.5 / k[0, 0]
    assert (corner['x'], corner['y'], corner['z']) == pytest.approx(
        (-half_w, -1.5 * 239.5 / k[1, 1], 1.5), abs=3e-3)
    assert math.degrees(2 * math.atan(320 / k[0, 0])) == pytest.approx(58.0)


def test_depth_conversion_and_scene_size(backend) -> None:
    """Depth is d / (raw + c) of the reversed-Z buffer, to the bit (issue 27: computed in one
    float64 buffer), and the visual scene is sized to the model (every geom and site fits; 4000
    geoms by default were ~2.5 MB for the tabletop's 47)."""
    sim = HeadSimulation(build_scene('tabletop', 0), {'neck_tilt_joint': 0.3},
                         eye=CameraSpec(160, 120, 85.4), rgbd=CameraSpec(160, 120, 58.0))
    data = mujoco.MjData(sim.model)
    sim.snapshot_into(data)
    mujoco.mj_forward(sim.model, data)
    with render_mod.CameraRenderer(sim.model, 160, 120, backend) as renderer:
        _, depth = renderer.render(data, 'rgbd_camera', depth=True)
        raw = renderer._depth[:160 * 120].reshape(120, 160)[::-1].astype(np.float64)
        with np.errstate(divide='ignore'):
            ref = (renderer._d / (raw + renderer._c)).astype(np.float32)
        ref[raw <= 0.0] = np.inf
        np.testing.assert_array_equal(depth, ref)
        scene = renderer._scene
        assert 0 < scene.ngeom < scene.maxgeom            # nothing dropped for want of room
        assert scene.maxgeom <= 4 * (sim.model.ngeom + sim.model.nsite) + 200
