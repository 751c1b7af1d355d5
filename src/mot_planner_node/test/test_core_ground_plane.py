"""Ground-plane plausibility: implied metric heights of boxes, the per-track consistency gate."""

import numpy as np
import pytest

from mot_planner_node.core.ground_plane import ConsistencyGate, implied_size, plausible_height

K = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]])
# The optical frame (z forward, x right, y down) of a level camera in a z-up world looking
# along +x; the camera 1.2 m above the floor: centre at z = 0.7, floor at z = -0.5.
OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
FLOOR = -0.5


def _pose(rotation: np.ndarray, centre: tuple[float, float, float]) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = rotation, centre
    return pose


LEVEL = _pose(OPTICAL, (0.0, 0.0, 0.7))


def test_level_camera_hand_computed() -> None:
    # A 1.8 m person 6 m ahead: feet at v = 240 + 500 * 1.2 / 6 = 340, head 0.6 m above the
    # camera at v = 240 - 500 * 0.6 / 6 = 190: a 150 px box, H = 150 * 6 / 500 = 1.8 m.
    # A can 0.12 m tall on a 0.72 m table 1 m ahead: base 0.48 m below the camera at
    # v = 240 + 500 * 0.48 = 480, top at 240 + 500 * 0.36 = 420 (60 px); the base's ray falls
    # 0.48 m per metre, so it meets the floor at 1.2 / 0.48 = 2.5 m: H = 60 * 2.5 / 500 = 0.3 m.
    # A box whose bottom is above the horizon (v = 200 < 240) never meets the floor.
    boxes = np.array([[300.0, 190.0, 40.0, 150.0], [310.0, 420.0, 20.0, 60.0],
                      [300.0, 100.0, 40.0, 100.0]])
    size = implied_size(boxes, K, LEVEL, FLOOR)
    np.testing.assert_allclose(size.height[:2], [1.8, 0.3])
    np.testing.assert_allclose(size.depth[:2], [6.0, 2.5])
    assert np.isnan(size.height[2]) and np.isnan(size.depth[2])
    np.testing.assert_array_equal(plausible_height(size.height, (1.3, 2.2)), [True, False, False])
    # the pan of the camera does not matter for a level camera: the same person 30 deg left
    pan = np.radians(30.0)
    yaw = np.array([[np.cos(pan), -np.sin(pan), 0], [np.sin(pan), np.cos(pan), 0], [0, 0, 1]])
    turned = implied_size(boxes[:1], K, _pose(yaw @ OPTICAL, (1.0, 2.0, 0.7)), FLOOR)
    assert turned.height[0] == pytest.approx(1.8)


def _project(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    cam = (points - pose[:3, 3]) @ pose[:3, :3]       # world -> optical: R^T (p - c)
    uvw = cam @ K.T
    return uvw[:, :2] / uvw[:, 2:]


def test_tilted_camera_recovers_standing_heights() -> None:
    """People of known heights seen by a camera pitched 25 deg down (and panned): the heights
    come back exactly, where the pinhole h * depth / fy is off by several percent."""
    pitch, pan = np.radians(25.0), np.radians(-10.0)
    ry = np.array([[np.cos(pitch), 0, np.sin(pitch)], [0, 1, 0],
                   [-np.sin(pitch), 0, np.cos(pitch)]])
    rz = np.array([[np.cos(pan), -np.sin(pan), 0], [np.sin(pan), np.cos(pan), 0], [0, 0, 1]])
    pose = _pose(rz @ ry @ OPTICAL, (0.0, 0.0, 0.4))
    feet = np.array([[3.0, 0.5, FLOOR], [5.0, -1.5, FLOOR], [2.5, -0.8, FLOOR]])
    heights = np.array([1.75, 1.2, 1.95])
    foot_px = _project(feet, pose)
    head_px = _project(feet + heights[:, None] * [0.0, 0.0, 1.0], pose)
    h = foot_px[:, 1] - head_px[:, 1]
    boxes = np.stack([foot_px[:, 0] - 0.2 * h, head_px[:, 1], 0.4 * h, h], axis=1)
    size = implied_size(boxes, K, pose, FLOOR)
    np.testing.assert_allclose(size.height, heights, rtol=1e-9)
    depth = (feet - pose[:3, 3]) @ pose[:3, 2]          # along the optical axis
    np.testing.assert_allclose(size.depth, depth, rtol=1e-9)
    pinhole = h * size.depth / K[1, 1]
    assert np.all(np.abs(pinhole / heights - 1.0) > 0.03)


def test_degenerate_geometry() -> None:
    # camera below the floor plane (a wrong floor_z): no foot point in front of the camera
    size = implied_size(np.array([[300.0, 190.0, 40.0, 150.0]]), K, LEVEL, floor_z=1.0)
    assert np.isnan(size.height[0])
    # camera 1.2 m up looking straight down (image up = world +x): verticals radiate from the
    # principal point. Feet at v = 200 (ray (0.08, 0, -1): floor at depth 1.2), top at 150:
    # with g = K R^T e_z = (-320, -240, -1), H = 1.2 * 50 / (-150 + 240) = 2/3 m. A top on the
    # other side of the principal point, or nearer to it than the feet, fits no standing body.
    down = _pose(np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]), (0, 0, 0.7))
    size = implied_size(np.array([[300.0, 150.0, 40.0, 50.0], [300.0, 200.0, 40.0, 100.0],
                                  [300.0, 320.0, 40.0, 60.0]]), K, down, FLOOR)
    assert size.height[0] == pytest.approx(2.0 / 3.0) and size.depth[0] == pytest.approx(1.2)
    assert np.isinf(size.height[1:]).all()
    assert implied_size(np.zeros((0, 4)), K, LEVEL, FLOOR).height.shape == (0,)
    assert not plausible_height(np.array([np.nan, np.inf]), (1.0, 2.0)).any()


def test_consistency_gate() -> None:
    gate = ConsistencyGate((1.3, 2.5), frames=3, max_ratio=1.3)
    ids = np.array([1, 2])
    assert gate.update(ids, np.array([1.8, 1.7])).tolist() == [True, True]
    assert gate.update(ids, np.array([1.9, 1.0])).tolist() == [True, False]      # 2: too short
    # track 2 back in range: implausible until three in a row
    assert gate.update(ids, np.array([1.7, 1.7])).tolist() == [True, False]
    assert gate.update(ids, np.array([1.8, 1.7])).tolist() == [True, False]
    assert gate.update(ids, np.array([1.8, 1.75])).tolist() == [True, True]
    # a height sweeping through the range (a tabletop track while the head moved): in range
    # for four frames, but 1.42 -> 2.42 m is a ratio of 1.7 > 1.3
    sweep = ConsistencyGate((1.3, 2.5), frames=5, max_ratio=1.3)
    flags = [bool(sweep.update(np.array([7]), np.array([h]))[0])
             for h in (1.36, 1.42, 2.42, 2.45, 4.94)]
    assert flags == [True, True, False, False, False]
    # a track that left is forgotten; an unchecked one is plausible
    assert gate.update(np.array([2, 3]), np.array([np.nan, 1.6])).tolist() == [False, True]
    assert gate.plausible([1, 4]).tolist() == [True, True]
    with pytest.raises(ValueError):
        gate.update(ids, np.array([1.7]))
    with pytest.raises(ValueError):
        ConsistencyGate((1.3, 2.5), frames=0)
