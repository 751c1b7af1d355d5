"""End to end with the MuJoCo head: put the joints at the gaze IK solution, render both eyes, and
find a small sphere placed at the fixation point on both principal points (within 2 px).

Skipped where MuJoCo or an offscreen renderer (EGL/OSMesa) is missing.
"""

from __future__ import annotations

import numpy as np
import pytest

from vizzy_gaze.core.gaze import solve_fixation
from vizzy_runtime.testing import no_renderer
from vizzy_vision import kinematics

mujoco = pytest.importorskip('mujoco')
model_mod = pytest.importorskip('vizzy_sim_bridge.core.model')
render_mod = pytest.importorskip('vizzy_sim_bridge.core.render')
scenes_mod = pytest.importorskip('vizzy_sim_bridge.core.scenes')

EYES = {'left': 'left_camera', 'right': 'right_camera'}   # MuJoCo camera names (model.py)
# Fixation points in the ego frame [m]: ahead and down (a table), up-left near, far right.
POINTS_EGO = [(0.8, 0.1, -0.25), (0.45, 0.2, 0.1), (2.0, -1.2, 0.15)]


@pytest.fixture(scope='module')
def renderer_backend() -> str:
    try:
        return render_mod.select_backend()
    except render_mod.RendererUnavailable as exc:
        no_renderer(str(exc))


def _target_scene() -> object:
    sphere = ('<geom name="fixation_target" type="sphere" size="0.01" pos="0 0 3" '
              'rgba="1 0 0 1" contype="0" conaffinity="0"/>')
    return scenes_mod.Scene(name='fixation_target', seed=0, assets_xml='', worldbody_xml=sphere)


def _red_centroid(rgb: np.ndarray) -> tuple[np.ndarray, int]:
    r, g, b = (rgb[..., i].astype(int) for i in range(3))
    mask = (r > 120) & (g < 0.4 * r) & (b < 0.4 * r)
    rows, cols = np.nonzero(mask)
    if not len(rows):
        return np.array([np.nan, np.nan]), 0
    return np.array([cols.mean(), rows.mean()]), len(rows)


def test_a_sphere_at_the_fixation_point_renders_on_both_principal_points(renderer_backend) -> None:
    eye = model_mod.EYE_CAMERA
    sim = model_mod.HeadSimulation(_target_scene())
    model, data = sim.model, sim.data
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, 'fixation_target')
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, 'base_link')
    renderer = render_mod.CameraRenderer(model, eye.width, eye.height, backend=renderer_backend)
    principal = np.array([(eye.width - 1) / 2.0, (eye.height - 1) / 2.0])
    fx = 0.5 * eye.width / np.tan(np.radians(eye.hfov_deg) / 2.0)
    ego = kinematics.frames_in_base([0.0] * len(kinematics.JOINT_NAMES))['ego']
    try:
        for point_ego in POINTS_EGO:
            point = ego[:3, :3] @ np.array(point_ego) + ego[:3, 3]   # base_link
            joints = solve_fixation(point).joints
            # put the joints there (kinematically: this checks the IK against the model's
            # geometry and cameras, not the servos' steady-state accuracy)
            data.qpos[sim.qpos_adr] = joints
            data.qvel[:] = 0.0
            # the sphere at the point (base_link -> world from MuJoCo's own base pose), 1 cm
            # across per metre of distance so it spans a few pixels wherever it is
            base_rot = data.xmat[bid].reshape(3, 3)
            model.geom_pos[gid] = base_rot @ point + data.xpos[bid]
            distance = float(np.linalg.norm(point - ego[:3, 3]))
            model.geom_size[gid][0] = 0.01 * distance
            mujoco.mj_forward(model, data)
            poses = kinematics.frames_in_base(joints.tolist())
            for side, camera in EYES.items():
                rgb, _ = renderer.render(data, camera)
                centroid, pixels = _red_centroid(rgb)
                assert pixels >= 9, f'{point_ego}: sphere not seen by the {side} eye'
                offset = centroid - principal
                assert np.all(np.abs(offset) < 2.0), (
                    f'{point_ego}: {side} eye sees the sphere {offset} px off the principal '
                    f'point (joints {joints})')
                # the size it appears with agrees with the camera model (the test's sanity)
                seen_from = np.linalg.norm(point - poses[f'{side}_camera_optical_frame'][:3, 3])
                expected_r = fx * 0.01 * distance / seen_from
                assert np.sqrt(pixels / np.pi) == pytest.approx(expected_r, rel=0.25)
    finally:
        renderer.close()
