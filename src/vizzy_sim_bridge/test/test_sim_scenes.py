"""Scenes: seeded and repeatable, with the content the thesis's experiments need."""

import math

import numpy as np
import pytest

from vizzy_sim_bridge.core.model import compile_model
from vizzy_sim_bridge.core.scenes import (
    CAN_HEIGHT,
    CAN_RADIUS,
    SCENE_NAMES,
    TABLE_TOP_Z,
    SceneUnavailable,
    build_scene,
    pedestrian_boxes,
)
from vizzy_vision.camera import camera_matrix, project
from vizzy_vision.kinematics import WAIST_HEIGHT, camera_poses, frames_in_base

HOME = [0.0] * 5
K = camera_matrix(640, 480, 85.4)


def _corners(obj) -> np.ndarray:
    from vizzy_vision.frames import rotation_matrix
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    return (0.5 * signs * np.array(obj.size)) @ rotation_matrix(obj.orientation).T + obj.position


@pytest.mark.parametrize('name', ['tabletop', 'visual_search'])
def test_same_seed_same_scene_and_other_seeds_differ(name) -> None:
    a, b, c = build_scene(name, 7), build_scene(name, 7), build_scene(name, 8)
    assert a.worldbody_xml == b.worldbody_xml and a.assets_xml == b.assets_xml
    assert a.assets == b.assets
    assert [o.as_dict() for o in a.objects] == [o.as_dict() for o in b.objects]
    assert a.worldbody_xml != c.worldbody_xml
    model_a, mjcf_a = compile_model(a)
    model_b, mjcf_b = compile_model(b)
    assert mjcf_a == mjcf_b
    np.testing.assert_array_equal(model_a.geom_pos, model_b.geom_pos)
    np.testing.assert_array_equal(model_a.tex_data, model_b.tex_data)


def test_unknown_scene_is_refused() -> None:
    with pytest.raises(ValueError, match='tabletop'):
        build_scene('kitchen', 0)


@pytest.mark.parametrize('seed', [0, 1, 2, 3])
def test_tabletop_has_cylinders_of_every_kind_among_distractors(seed) -> None:
    scene = build_scene('tabletop', seed)
    kinds = {o.kind for o in scene.objects}
    assert {'table', 'can', 'bottle', 'jar', 'pipe', 'box', 'sphere', 'handle'} <= kinds
    cylinders = [o for o in scene.objects if o.is_cylinder]
    assert len({round(o.radius, 4) for o in cylinders}) >= 3       # different radii
    assert len({round(o.height, 4) for o in cylinders}) >= 3       # and heights
    assert any(o.lid for o in cylinders)
    top = TABLE_TOP_Z - WAIST_HEIGHT                                # in base_link
    lying = [o for o in cylinders if abs(o.axis[2]) < 1e-9]
    upright = [o for o in cylinders if abs(o.axis[2] - 1.0) < 1e-9]
    assert {o.kind for o in lying} >= {'pipe', 'can'} and len(upright) >= 3
    for o in cylinders:
        assert np.linalg.norm(o.axis) == pytest.approx(1.0)
        assert o.size == pytest.approx((2 * o.radius, 2 * o.radius, o.height))
        bottom = o.position[2] - (o.height / 2 if o in upright else o.radius)
        assert bottom == pytest.approx(top, abs=1e-9)               # resting on the table
    # footprints do not overlap (upright: discs; lying: the length's bounding disc)
    items = [o for o in scene.objects if o.kind != 'table']
    for i, a in enumerate(items):
        for b in items[i + 1:]:
            ra = 0.5 * max(a.size[0], a.size[1], a.size[2] if a in lying else 0.0)
            rb = 0.5 * max(b.size[0], b.size[1], b.size[2] if b in lying else 0.0)
            d = math.hypot(a.position[0] - b.position[0], a.position[1] - b.position[1])
            assert d > 0.7 * (ra + rb), (a.name, b.name)
    assert scene.objects[0].kind == 'table' and scene.objects[0].role == 'support'
    assert [o.id for o in scene.objects] == list(range(len(scene.objects)))


@pytest.mark.parametrize('seed', [0, 1, 2, 3, 4])
def test_visual_search_nearest_can_is_out_of_the_initial_view(seed) -> None:
    scene = build_scene('visual_search', seed)
    ego = frames_in_base(HOME)['ego'][:3, 3]
    cans = [o for o in scene.objects if o.kind == 'can']
    assert len(cans) == 8 and all(o.radius == CAN_RADIUS and o.height == CAN_HEIGHT for o in cans)
    distances = {o.name: np.linalg.norm(np.array(o.position) - ego) for o in cans}
    target = next(o for o in cans if o.role == 'target')
    assert distances[target.name] == min(distances.values())
    assert sorted(distances.values())[1] - distances[target.name] > 0.2
    cams = camera_poses(HOME)
    for side in ('left', 'right'):
        uv = project(K, cams[side], _corners(target))
        inside = ((uv[:, 0] >= -0.5) & (uv[:, 0] <= 639.5) & (uv[:, 1] >= -0.5)
                  & (uv[:, 1] <= 479.5))
        assert not inside.any(), f'the target can is in the {side} image at home posture'
    for o in cans:
        if o is target:
            continue
        u, v = project(K, cams['left'], np.array([o.position]))[0]
        assert 0 <= u < 640 and 0 <= v < 480, f'{o.name} not in view'


def test_pedestrian_boxes_are_normalized_to_base_link() -> None:
    raw = [{'id': 3, 'box_min': [2.0, -0.3, 0.0], 'box_max': [2.4, 0.3, 1.8]},
           {'center': [4.0, 1.0, 0.9], 'size': [0.5, 0.6, 1.8], 'yaw': 0.5}]
    boxes = pedestrian_boxes(raw)
    assert boxes[0]['id'] == 3 and boxes[0]['center'] == pytest.approx(
        (2.2, 0.0, 0.9 - WAIST_HEIGHT))
    assert boxes[0]['size'] == pytest.approx((0.4, 0.6, 1.8))
    assert boxes[1]['id'] == 1 and boxes[1]['orientation'][2] == pytest.approx(math.sin(0.25))


def test_pedestrians_scene_uses_the_crowd_module() -> None:
    try:
        scene = build_scene('pedestrians', 5, count=3)
    except SceneUnavailable as exc:
        assert 'pedestrians' in str(exc)
        pytest.skip(str(exc))
    assert scene.crowd is not None and 'pedestrians' in SCENE_NAMES
    again = build_scene('pedestrians', 5, count=3)
    assert scene.worldbody_xml == again.worldbody_xml
    import mujoco
    model, _ = compile_model(scene)
    data = mujoco.MjData(model)
    scene.update(model, data, 1.5)
    mujoco.mj_forward(model, data)
    boxes = scene.moving_ground_truth(model, data)
    assert len(boxes) == 3
    from vizzy_sim_bridge.sim_node import box_corners, image_box
    cam = camera_poses(HOME)['left']
    for box in boxes:
        assert box['center'][0] > 0.5                  # in front of the robot
        assert box['center'][2] - box['size'][2] / 2 == pytest.approx(-WAIST_HEIGHT, abs=0.1)
        # the image box from the walker's own geoms is within the projected 3D box
        loose = image_box(K, cam, box_corners(box['center'], box['size'], box['orientation']),
                          640, 480)
        tight = image_box(K, cam, box['corners'], 640, 480)
        if loose is None:
            continue
        assert tight is not None
        assert (tight[2] - tight[0]) <= (loose[2] - loose[0]) + 1.0
        assert loose[0] - 1.0 <= (tight[0] + tight[2]) / 2 <= loose[2] + 1.0


def test_pedestrians_walk_in_the_area_given() -> None:
    # A wider area than the default (y within +-2.5 m) lets people leave the view and come
    # back, as on a real street (bench/mot_peers.py --sim-area).
    wide = ((1.5, 6.0), (-5.0, 5.0))
    try:
        scene = build_scene('pedestrians', 0, count=4, area=wide)
    except SceneUnavailable as exc:
        pytest.skip(str(exc))
    crowd = scene.crowd
    assert crowd.area == wide
    xy = np.concatenate([p.path_xy for p in crowd.people])
    lo, hi = np.array([1.5, -5.0]) + crowd.margin, np.array([6.0, 5.0]) - crowd.margin
    assert np.all(xy >= lo - 1e-6) and np.all(xy <= hi + 1e-6)
    assert np.abs(xy[:, 1]).max() > 2.5                 # beyond the default area
    default = build_scene('pedestrians', 0, count=4).crowd
    assert np.abs(np.concatenate([p.path_xy for p in default.people])[:, 1]).max() <= 2.5
