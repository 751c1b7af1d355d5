"""Procedural walking people of the pedestrian scene (core/pedestrians.py)."""

import math

import mujoco
import numpy as np
import pytest

from vizzy_runtime.testing import no_renderer
from vizzy_sim_bridge.core.pedestrians import PedestrianCrowd, gait_angles, preview_scene_xml

AREA = ((1.5, 6.0), (-2.5, 2.5))


def build(seed: int = 7, count: int = 4, **kwargs):
    crowd = PedestrianCrowd(np.random.default_rng(seed), count, **kwargs)
    model = mujoco.MjModel.from_xml_string(preview_scene_xml(crowd, width=320, height=240))
    return crowd, model, mujoco.MjData(model)


@pytest.fixture(scope='module')
def scene():
    return build()


def snapshot(data: mujoco.MjData) -> np.ndarray:
    return np.concatenate([data.qpos, data.mocap_pos.ravel(), data.mocap_quat.ravel()])


def test_update_is_a_function_of_time_and_seed(scene) -> None:
    crowd, model, data = scene
    crowd.update(model, data, 3.7)
    direct = snapshot(data)
    for t in (0.0, 11.2, 1.05):  # any history in between
        crowd.update(model, data, t)
    crowd.update(model, data, 3.7)
    np.testing.assert_array_equal(snapshot(data), direct)

    twin, model2, data2 = build()  # same seed: same people, same motion
    assert twin.assets_xml() == crowd.assets_xml()
    assert twin.worldbody_xml() == crowd.worldbody_xml()
    twin.update(model2, data2, 3.7)
    np.testing.assert_array_equal(snapshot(data2), direct)

    other = PedestrianCrowd(np.random.default_rng(8), 4)
    assert other.worldbody_xml() != crowd.worldbody_xml()


def test_motion_repeats_with_the_period(scene) -> None:
    crowd, model, data = scene
    crowd.update(model, data, 2.3)
    first = snapshot(data)
    crowd.update(model, data, 2.3 + crowd.period)
    np.testing.assert_allclose(snapshot(data), first, atol=1e-6)


def test_legs_and_arms_swing_in_antiphase(scene) -> None:
    crowd, model, data = scene
    person = crowd.people[0]
    cycle = person.stride / person.speed
    times = np.linspace(0.0, cycle, 40, endpoint=False)
    q = np.array([crowd.joint_positions(t)[0] for t in times])
    col = {name: q[:, k] for k, name in enumerate(crowd.JOINTS)}

    def corr(a: str, b: str) -> float:
        return float(np.corrcoef(col[a], col[b])[0, 1])

    assert corr('l_hip', 'r_hip') < -0.95
    assert corr('l_shoulder', 'r_shoulder') < -0.95
    assert corr('l_hip', 'l_shoulder') < -0.95   # each arm opposite to the leg of its side
    assert corr('l_hip', 'r_shoulder') > 0.95
    for joint in ('l_hip', 'r_hip', 'l_shoulder', 'r_shoulder'):
        assert np.ptp(col[joint]) > math.radians(15)
    assert np.ptp(col['l_knee']) > math.radians(40)   # the swing leg folds
    assert col['l_knee'].min() >= 0.0                 # knees never hyperextend
    # the torso bobs a little (a few cm) as the legs swing
    bob = []
    for t in times:
        crowd.update(model, data, t)
        bob.append(data.mocap_pos[0, 2])
    assert 0.005 < np.ptp(bob) < 0.06


def test_gait_angles_left_and_right_half_a_cycle_apart() -> None:
    left = gait_angles(np.linspace(0, 1, 20, endpoint=False))
    right = gait_angles(np.linspace(0.5, 1.5, 20, endpoint=False))
    np.testing.assert_allclose(left['hip'][:10], right['hip'][10:])
    assert left['hip'][0] > 0 > left['hip'][10]  # flexed at heel strike, extended at mid-cycle


def test_ground_truth_boxes_hold_every_body_geom(scene) -> None:
    crowd, model, data = scene
    owner = crowd.geom_owner(model)
    for t in (0.0, 1.3, 7.9):
        crowd.update(model, data, t)
        truth = crowd.ground_truth(model, data)
        assert [g['id'] for g in truth] == list(range(len(crowd.people)))
        for g in truth:
            lo, hi = np.array(g['box_min']), np.array(g['box_max'])
            geoms = np.flatnonzero(owner == g['id'])
            assert len(geoms) >= 15
            pos = data.geom_xpos[geoms]
            assert np.all(pos >= lo) and np.all(pos <= hi)
            root = model.body(f'ped{g["id"]}_root').id
            body = data.xpos[(model.body_rootid == root) & (np.arange(model.nbody) != root)]
            assert np.all(body >= lo - 1e-9) and np.all(body <= hi + 1e-9)
            assert lo[2] == pytest.approx(0.0, abs=0.02)       # feet on the ground
            assert 1.55 < hi[2] < 1.95                          # standing height
            assert lo[0] <= g['position'][0] <= hi[0] and lo[1] <= g['position'][1] <= hi[1]
            heading = np.array([math.cos(g['heading']), math.sin(g['heading'])])
            assert np.linalg.norm(g['velocity']) == pytest.approx(
                crowd.people[g['id']].speed)
            np.testing.assert_allclose(np.array(g['velocity'][:2]) / np.linalg.norm(g['velocity']),
                                       heading, atol=1e-9)


def test_people_walk_inside_the_area_at_walking_speed_and_keep_apart() -> None:
    crowd = PedestrianCrowd(np.random.default_rng(3), 6, area=AREA)
    (x0, x1), (y0, y1) = AREA
    times = np.arange(0.0, 2 * crowd.period, 0.2)
    xy = np.array([crowd.positions(t)[0] for t in times])  # (T, N, 2)
    assert np.all(xy[..., 0] >= x0) and np.all(xy[..., 0] <= x1)
    assert np.all(xy[..., 1] >= y0) and np.all(xy[..., 1] <= y1)
    speed = np.linalg.norm(np.diff(xy, axis=0), axis=-1) / 0.2
    assert np.all(speed <= 1.5 + 1e-6)
    assert np.median(speed) >= 0.95  # corners are cut a little
    for p in crowd.people:
        assert 1.0 <= p.speed <= 1.5
        assert 1.6 <= p.body.height <= 1.9
    gaps = [np.linalg.norm(xy[:, a] - xy[:, b], axis=-1).min()
            for a in range(6) for b in range(a + 1, 6)]
    assert min(gaps) >= 0.5
    assert crowd.min_distance == pytest.approx(min(gaps), abs=0.15)
    # each walker turns: its heading covers a whole loop
    _, heading = crowd.positions(0.0)
    assert heading.shape == (6,)


def test_people_look_different() -> None:
    crowd = PedestrianCrowd(np.random.default_rng(1), 6)
    shirts = {tuple(round(c, 2) for c in p.shirt) for p in crowd.people}
    assert len(shirts) == 6
    assert len({round(p.body.height, 3) for p in crowd.people}) == 6
    xml = crowd.assets_xml()
    assert xml.count('<texture') == 18 and 'builtin=' in xml


def test_bad_arguments_are_rejected() -> None:
    with pytest.raises(ValueError, match='count'):
        PedestrianCrowd(np.random.default_rng(0), -1)
    with pytest.raises(ValueError, match='too small'):
        PedestrianCrowd(np.random.default_rng(0), 2, area=((1.0, 1.5), (0.0, 0.5)))
    empty = PedestrianCrowd(np.random.default_rng(0), 0)
    assert empty.assets_xml() == '' and empty.worldbody_xml() == ''
    model = mujoco.MjModel.from_xml_string(preview_scene_xml(empty))
    data = mujoco.MjData(model)
    empty.update(model, data, 1.0)
    assert empty.ground_truth(model, data) == []


class OffscreenCamera:
    """Renders one model camera offscreen through an explicit EGL or OSMesa context (so the
    test neither reads nor sets MUJOCO_GL, which other tests in the process may rely on)."""

    def __init__(self, model: mujoco.MjModel, camera: str, width: int, height: int) -> None:
        errors = []
        for backend in ('egl', 'osmesa'):
            try:
                if backend == 'egl':
                    from mujoco.egl import GLContext
                else:
                    from mujoco.osmesa import GLContext
                self.gl = GLContext(width, height)
                self.gl.make_current()
                break
            except Exception as err:  # noqa: BLE001 - ImportError, OSError, GL errors
                errors.append(f'{backend}: {type(err).__name__}: {err}')
        else:
            no_renderer('install libegl1 or libosmesa6: ' + '; '.join(errors))
        self.model, self.width, self.height = model, width, height
        self.context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self.context)
        self.scene = mujoco.MjvScene(model, maxgeom=2000)
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self.camera.fixedcamid = model.camera(camera).id
        self.option = mujoco.MjvOption()

    def render(self, data: mujoco.MjData) -> np.ndarray:
        self.gl.make_current()
        mujoco.mjv_updateScene(self.model, data, self.option, None, self.camera,
                               mujoco.mjtCatBit.mjCAT_ALL, self.scene)
        viewport = mujoco.MjrRect(0, 0, self.width, self.height)
        mujoco.mjr_render(viewport, self.scene, self.context)
        rgb = np.empty((self.height, self.width, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(rgb, None, viewport, self.context)
        return np.flipud(rgb).copy()

    def close(self) -> None:
        self.context.free()
        self.gl.free()


def test_hog_people_detector_fires_on_the_rendered_walkers() -> None:
    cv2 = pytest.importorskip('cv2')
    crowd = PedestrianCrowd(np.random.default_rng(0), 4)
    # the robot's field of view at 3/4 of its resolution: people 2-4 m away are 110-220 px tall
    width, height = 480, 360
    model = mujoco.MjModel.from_xml_string(
        preview_scene_xml(crowd, width=width, height=height, hfov_deg=85.4, camera_height=1.1))
    data = mujoco.MjData(model)
    renderer = OffscreenCamera(model, 'eye', width, height)
    hog = cv2.HOGDescriptor()
    hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())
    hits = 0
    try:
        for t in (0.4, 1.9, 3.4, 6.4):
            crowd.update(model, data, t)
            image = cv2.cvtColor(renderer.render(data), cv2.COLOR_RGB2BGR)
            assert image.std() > 10.0  # a scene, not a blank frame
            rects, _ = hog.detectMultiScale(image, winStride=(8, 8), scale=1.05, hitThreshold=0)
            # a hit: a detection whose box holds a walker from head to feet (its centre line)
            for x, y, w, h in rects:
                for g in crowd.ground_truth(model, data):
                    u, v_top = project(model, data, width, height,
                                       [g['position'][0], g['position'][1], g['box_max'][2]])
                    _, v_bottom = project(model, data, width, height, g['position'])
                    if (x <= u <= x + w and y - 0.1 * h <= v_top and v_bottom <= y + 1.1 * h
                            and v_bottom - v_top > 0.5 * h):
                        hits += 1
                        break
    finally:
        renderer.close()
    assert hits >= 4  # 10-11 on this seed with Mesa's llvmpipe


def project(model, data, width, height, point):
    """Pixel (u, v) of a world point in camera 'eye' (MuJoCo camera: -z forward, y up)."""
    cam = model.camera('eye').id
    rot = data.cam_xmat[cam].reshape(3, 3)
    p = rot.T @ (np.asarray(point, dtype=float) - data.cam_xpos[cam])
    f = 0.5 * height / math.tan(math.radians(model.cam_fovy[cam]) / 2)
    return width / 2 + f * p[0] / -p[2], height / 2 - f * p[1] / -p[2]
