"""Ego-motion compensation: the rotation homography moves beliefs exactly; tracks survive a
head rotation that breaks them without it."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mot_planner_node.core.egomotion import (
    rotation_between,
    rotation_homography,
    warp_beliefs,
    warp_points,
)
from mot_planner_node.core.metrics import MotEvaluator, summarize
from mot_planner_node.core.planner import PlannerConfig
from mot_planner_node.core.simulated import SimulatedDetector
from mot_planner_node.core.tracker import MotTracker, TrackerConfig

F = 347.0                      # the simulated eyes: 640x480, 85.4 deg horizontal FOV
K = np.array([[F, 0.0, 319.5], [0.0, F, 239.5], [0.0, 0.0, 1.0]])
BLANK = np.zeros((480, 640, 3), np.uint8)


def project(points: np.ndarray) -> np.ndarray:
    uvw = points @ K.T
    return uvw[:, :2] / uvw[:, 2:]


def test_rotation_homography_moves_points_exactly_at_any_depth() -> None:
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-2, 2, 20), rng.uniform(-1, 1, 20),
                           rng.uniform(1.5, 30.0, 20)])       # optical frame, in front
    # Camera orientations in a world frame: the head pans 12 deg left and tilts 4 deg down.
    r_prev = Rotation.from_euler('yx', [3.0, -2.0], degrees=True).as_matrix()
    r_cur = Rotation.from_euler('yx', [-9.0, 2.0], degrees=True).as_matrix()
    r = rotation_between(r_prev, r_cur)
    world = pts @ r_prev.T                                    # the same points, world-fixed
    cur = world @ r_cur                                       # seen by the rotated camera
    h = rotation_homography(K, r)
    uv, jac = warp_points(h, project(pts))
    np.testing.assert_allclose(uv, project(cur), atol=1e-9)
    # The Jacobian is the homography's derivative (central differences).
    e = 1e-4
    for j in range(2):
        d = np.zeros(2)
        d[j] = e
        num = (warp_points(h, project(pts) + d)[0] - warp_points(h, project(pts) - d)[0]) / (2 * e)
        np.testing.assert_allclose(jac[:, :, j], num, atol=1e-6)
    # A shift of the whole image: ~ f tan(12 deg) = 74 px for a point near the centre.
    shift = warp_points(h, np.array([[319.5, 239.5]]))[0][0] - [319.5, 239.5]
    assert 65.0 < abs(shift[0]) < 85.0


def test_warp_beliefs_moves_mean_velocity_and_covariance() -> None:
    r = Rotation.from_euler('y', 10.0, degrees=True).as_matrix()
    h = rotation_homography(K, r)
    x = np.array([[100.0, 300.0, 1.5, 2.0, -1.0, 0.01], [500.0, 239.5, 2.0, 0.0, 0.0, 0.0]])
    P = np.stack([np.diag([64.0, 81.0, 0.01, 4.0, 4.0, 1e-4])] * 2)
    x2, P2 = warp_beliefs(x, P, h)
    uv, jac = warp_points(h, x[:, :2])
    np.testing.assert_allclose(x2[:, :2], uv)
    m = np.linalg.norm(jac[:, :, 1], axis=1)
    np.testing.assert_allclose(x2[:, 2], m * x[:, 2])
    # A pure pan: heights scale by cos(alpha) / cos(alpha') on the principal row.
    alpha = np.arctan((x[:, 0] - K[0, 2]) / F)
    alpha2 = np.arctan((x2[:, 0] - K[0, 2]) / F)
    row = np.abs(x[:, 1] - K[1, 2]) < 1e-9
    np.testing.assert_allclose((x2[:, 2] / x[:, 2])[row], (np.cos(alpha) / np.cos(alpha2))[row])
    np.testing.assert_allclose(x2[0, 3:5], jac[0] @ x[0, 3:5])
    np.testing.assert_allclose(P2[0, :2, :2], jac[0] @ P[0, :2, :2] @ jac[0].T)
    # Velocity: two positions a frame apart, mapped, differ by the mapped velocity (to first
    # order: 0.1 % here).
    a, b = warp_points(h, np.array([x[0, :2], x[0, :2] + x[0, 3:5]]))[0]
    np.testing.assert_allclose(b - a, x2[0, 3:5], rtol=0.01)
    # Monte Carlo: the linearized covariance matches the spread of mapped samples.
    rng = np.random.default_rng(1)
    s = rng.multivariate_normal(x[0, :2], P[0, :2, :2], 20000)
    np.testing.assert_allclose(np.cov(warp_points(h, s)[0].T), P2[0, :2, :2],
                               rtol=0.03, atol=1.0)
    # No rotation: nothing changes; no tracks: fine.
    x3, P3 = warp_beliefs(x, P, np.eye(3))
    np.testing.assert_allclose(x3, x)
    np.testing.assert_allclose(P3, P)
    assert warp_beliefs(np.zeros((0, 6)), np.zeros((0, 6, 6)), h)[0].shape == (0, 6)


def lanes(n_frames: int) -> list[np.ndarray]:
    """Four people in separate lanes (object boxes x, y, w, h), a static camera."""
    heights = np.array([110.0, 120.0, 130.0, 140.0])
    x0 = np.array([150.0, 480.0, 250.0, 380.0])
    vx = np.array([1.5, -1.5, 1.0, -1.0])
    feet = np.array([170.0, 250.0, 330.0, 420.0])
    out = []
    for t in range(n_frames):
        cx = x0 + vx * t
        w = 0.41 * heights
        out.append(np.stack([cx - w / 2, feet - heights, w, heights], axis=1))
    return out


def warp_boxes(h: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Boxes seen by the rotated camera: centre through H, size by the vertical magnification."""
    c = boxes[:, :2] + boxes[:, 2:] / 2
    uv, jac = warp_points(h, c)
    size = boxes[:, 2:] * np.linalg.norm(jac[:, :, 1], axis=1)[:, None]
    return np.column_stack([uv - size / 2, size])


def track_through_rotation(compensate: bool, mode: str) -> dict:
    """The head pans 8 deg and tilts 3 deg between frames 15 and 16 (a ~50 px jump)."""
    r = Rotation.from_euler('yx', [8.0, -3.0], degrees=True).as_matrix()
    h = rotation_homography(K, r)
    det = SimulatedDetector(p_detect=1.0, false_positives_per_frame=0.0, seed=3)
    planner = PlannerConfig(k_max=2, s_max=0.1, budget_ms=None, max_iterations=60, seed=0)
    tracker = MotTracker(det, TrackerConfig(mode=mode, new_tracks='none', planner=planner))
    ev = MotEvaluator()
    ids = np.arange(1, 5)
    for t, boxes in enumerate(lanes(45)):
        rotated = t >= 16
        truth = warp_boxes(h, boxes) if rotated else boxes
        det.set_truth(truth)
        res = tracker.step(BLANK, homography=h if (compensate and t == 16) else None)
        ev.update(t + 1, ids, truth, res.ids, res.boxes)
    return summarize({'s': ev})['s']


@pytest.mark.parametrize('mode', ['planner', 'full'])
def test_tracks_survive_a_head_rotation_only_with_compensation(mode: str) -> None:
    with_comp = track_through_rotation(True, mode)
    assert with_comp['num_switches'] == 0
    assert with_comp['num_false_positives'] == 0
    assert with_comp['mota'] > 0.95 and with_comp['idf1'] > 0.95
    without = track_through_rotation(False, mode)
    # Without it the predicted beliefs no longer cover anyone: tracks are lost (planner MOTA
    # 0.16, full frame 0.53) and the people's new positions count as misses.
    assert without['mota'] < 0.75
    assert without['num_misses'] > 40


def test_bad_homography_is_refused_and_changes_nothing() -> None:
    det = SimulatedDetector(p_detect=1.0, false_positives_per_frame=0.0, seed=0)
    tracker = MotTracker(det, TrackerConfig(mode='full', new_tracks='none'))
    det.set_truth(lanes(1)[0])
    tracker.step(BLANK)
    before = tracker.tracks.x.copy()
    with pytest.raises(ValueError, match='homography'):
        tracker.step(BLANK, homography=np.full((3, 3), np.nan))
    np.testing.assert_array_equal(tracker.tracks.x, before)
    assert tracker.frame_index == 1


def test_orientation_history_interpolates_at_image_stamps() -> None:
    from vizzy_vision.pose_history import PoseHistory
    hist = PoseHistory(max_age_s=1.0, max_extrapolation_s=0.05)
    assert hist.at(0.0) is None
    for t in (10.0, 10.01, 10.02):            # /tf at 100 Hz, panning at 5 deg per 10 ms
        hist.add(t, Rotation.from_euler('z', 500.0 * (t - 10.0), degrees=True).as_matrix())
    mid = Rotation.from_matrix(hist.at(10.015)).as_euler('zyx', degrees=True)[0]
    assert mid == pytest.approx(7.5)
    np.testing.assert_allclose(hist.at(10.04), hist.at(10.02))     # just after: the newest
    assert hist.at(10.2) is None and hist.at(9.0) is None            # not covered
    hist.add(11.5, np.eye(3))                 # older than max_age_s behind the newest: gone
    assert len(hist) == 1 and hist.at(10.01) is None
