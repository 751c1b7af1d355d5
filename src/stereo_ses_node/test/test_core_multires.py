"""Disparity maps of rectified pairs at the resolution each sensor needs (core.multires), the
search window from the geometry, and the synthetic layered pairs with ground truth."""

import math

import cv2
import numpy as np
import pytest

from stereo_ses_node.core.geometry import epipolar_distance, vergence_poses
from stereo_ses_node.core.multires import (
    DisparityWindow,
    FoveatedSGBM,
    SGBMParams,
    bad_fraction,
    cartesian_disparity,
    coarse_window,
    disparity_window,
    full_disparity,
    parallel_window,
    sgbm_window,
)
from stereo_ses_node.core.sensors import fovea_radius
from stereo_ses_node.core.stereo import StereoPipeline
from stereo_ses_node.core.synthetic import Layer, layered_pair, plane_texture, random_layers
from stereo_ses_node.core.ut import StereoRig
from vizzy_vision.logpolar import LogPolarRetina

W, H = 320, 240
FOVEA = 16.0


def _texture(seed: int) -> np.ndarray:
    t = plane_texture(W, seed=seed)[:H]
    return np.repeat(t[..., None], 3, axis=2)


@pytest.fixture(scope='module')
def scene():
    """A 320x240 rectified pair: slanted background at 10-16 px, three shapes at 20-36 px, the
    first across the centre."""
    layers = random_layers([_texture(s) for s in range(4)], W, H, seed=3,
                           background=(10.0, 16.0), foreground=(20.0, 36.0))
    left, right, gt, visible = layered_pair(layers, W, H, noise_sd=1.0, gain=0.98, seed=1)
    return left, right, np.where(visible, gt, np.nan)


def test_layered_pair_geometry_and_occlusions():
    tex = _texture(0)
    square = np.zeros((H, W), bool)
    square[80:160, 120:200] = True
    layers = [Layer(tex, (0.0, 0.0, 10.0)), Layer(_texture(1), (0.0, 0.0, 30.0), square)]
    left, right, gt, visible = layered_pair(layers, W, H)
    assert np.all(gt[square] == 30.0) and np.all(gt[~square] == 10.0)
    # a point at disparity d in the left image is at x - d in the right one
    np.testing.assert_array_equal(right[:40, 0:W - 10], left[:40, 10:W])
    np.testing.assert_array_equal(right[100, 90:170], left[100, 120:200])
    # the right camera cannot see the left 10 columns, nor the background the square hides
    # on its left (30 - 10 = 20 columns), and sees everything else
    assert not visible[:, :10].any() and visible[:, 10:].sum() > 0
    assert not visible[100, 100:120].any() and visible[100, 95:100].all()
    assert visible[square].all() and visible[100, 200:].all()


def test_windows_from_geometry():
    w = parallel_window(500.0, 0.1, 1.0, 10.0)
    assert (w.lo, w.hi) == (5, 51)
    assert parallel_window(500.0, 0.1, 0.5).lo == 0           # far = infinity
    k = np.array([[500.0, 0, 159.5], [0, 500.0, 119.5], [0, 0, 1]])
    right = np.eye(4)
    right[0, 3] = 0.1                                          # a parallel rig, baseline 0.1 m
    w = disparity_window(k, k, np.eye(4), right, W, H, 1.0, 10.0)
    assert (w.lo, w.hi) == (5, 51)
    # verged on a point 1 m ahead: ~0 there, negative beyond, positive nearer
    pl, pr = vergence_poses(0.204, 2 * np.arctan(0.102))
    w = disparity_window(k, k, pl, pr, W, H, 0.5, math.inf)
    assert w.lo < -50 and w.hi > 40
    with pytest.raises(ValueError):
        disparity_window(k, k, pl, pr, W, H, 2.0, 1.0)
    with pytest.raises(ValueError):
        DisparityWindow(3.0, 3.0)
    # one level px below the window (its first disparity must not be SGBM's textureless
    # answer), numDisparities a multiple of 16
    assert DisparityWindow(-40, 40).scaled(2.0) == (-21, 48)


def test_sgbm_window_equals_plain_sgbm_on_a_shift():
    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur((rng.random((60, 240)) * 255).astype(np.uint8), (0, 0), 1.0)
    left, right = img[:, :-23], img[:, 23:]         # right(x - 23) = left(x): disparity 23
    params = SGBMParams()
    mine = sgbm_window(left, right, 16, 16, params)
    raw = params.create(16, 16).compute(left, right)
    plain = np.where(raw >= 16 * 16, raw / 16.0, np.nan)
    assert np.all(np.isnan(mine[:, :32]))                      # x < lo + num: may leave the image
    cols = slice(40, 200)
    assert np.nanmedian(np.abs(mine[:, cols] - 23)) < 0.1
    assert np.mean(np.isfinite(mine[:, cols])) > 0.95
    both = np.isfinite(mine[:, cols]) & np.isfinite(plain[:, cols])
    assert np.median(np.abs(mine[:, cols] - plain[:, cols])[both]) < 0.05
    # any window holding the truth finds it, negative disparities included; the columns a
    # crop (x0, x1) asks for are those of the image (its last columns lack context: margins)
    wide = sgbm_window(left, right, -8, 48, params)
    assert np.nanmedian(np.abs(wide[:, cols] - 23)) < 0.1
    crop = sgbm_window(left, right, -8, 48, params, 100, 150)
    np.testing.assert_allclose(crop[:, 10:40], wide[:, 110:140], atol=0.07, equal_nan=True)


def test_textureless_pairs_have_no_disparity():
    flat = np.full((H, W, 3), 90, np.uint8)
    win = DisparityWindow(0, 64)
    fov = FoveatedSGBM(W, H, FOVEA)
    for res in (full_disparity(flat, flat, win), cartesian_disparity(flat, flat, win, (100, 100)),
                fov.compute(flat, flat, win)):
        assert res.valid_points == 0 and res.disparity.shape == (H, W)
        assert res.disparity.dtype == np.float32


def test_foveated_levels_partition_the_image():
    fov = FoveatedSGBM(W, H, FOVEA, center=(100.0, 80.0))
    dst = np.concatenate([lv.dst for lv in fov.levels])
    assert np.array_equal(np.sort(dst), np.arange(W * H))      # every pixel exactly once
    level, ecc = fov.level_map(), fov.eccentricity
    assert np.array_equal(level == 0, ecc < FOVEA)
    for lv in fov.levels[1:-1]:
        ring = (ecc >= FOVEA * 2 ** (lv.level - 1)) & (ecc < FOVEA * 2 ** lv.level)
        assert np.array_equal(level == lv.level, ring)
        x0, y0, x1, y1 = lv.box                                # a crop about its disc only
        assert (x1 - x0) * 2 ** lv.level <= 2 * (lv.r_outer + 8 * 2 ** lv.level) + 2 ** lv.level
    last = fov.levels[-1]
    assert math.isinf(last.r_outer) and last.box[:2] == (0, 0)
    with pytest.raises(ValueError, match='outside'):
        FoveatedSGBM(W, H, FOVEA, center=(W + 5.0, 10.0))


def test_foveated_matches_full_sgbm_in_the_fovea_for_a_third_of_the_work(scene):
    left, right, truth = scene
    true = DisparityWindow(math.floor(np.nanmin(truth)) - 2, math.ceil(np.nanmax(truth)) + 3)
    full = full_disparity(left, right, true)
    fov = FoveatedSGBM(W, H, FOVEA)
    res = fov.compute(left, right, DisparityWindow(0, W // 3))   # a wide window, searched
    fovea = fov.eccentricity < FOVEA
    bad_full, _ = bad_fraction(full.disparity, truth, 2.0, fovea)
    bad_fov, dens = bad_fraction(res.disparity, truth, 2.0, fovea)
    assert bad_fov <= bad_full + 0.01 and bad_fov < 0.05 and dens > 0.95
    # coarse-to-fine: the fovea searched far fewer disparities than the window holds
    lo, hi = res.ranges['level0']
    assert hi - lo <= 48 and lo <= np.nanmin(truth[fovea]) and hi > np.nanmax(truth[fovea])
    assert res.work * 3 < full.work                             # SGBM's cost-volume cells
    # the periphery is matched too, coarser: most pixels within a level pixel or two
    assert res.valid_points > 0.7 * W * H
    level = fov.level_map()
    err = np.abs(res.disparity - truth)
    ok = np.isfinite(err)
    assert np.median(err[ok & (level == fov.n_levels - 1)]) < 2 ** (fov.n_levels - 1) / 2
    assert set(res.stages_ms) >= {'pyramid', 'range search', 'level0'}


def test_cartesian_and_coarse_window(scene):
    left, right, truth = scene
    win = coarse_window(left, right, DisparityWindow(0, W // 3))
    assert win.lo <= np.nanmin(truth) and win.hi > np.nanmax(truth) and win.hi - win.lo < 64
    res = cartesian_disparity(left, right, win, (100, 100))
    bad, dens = bad_fraction(res.disparity, truth, 2.0 * W / 100)   # within ~2 grid px
    assert bad < 0.3 and dens > 0.6


def test_bad_fraction_counts_missing_as_bad():
    truth = np.array([[1.0, 2.0, np.nan, 4.0]])
    est = np.array([[1.5, np.nan, 3.0, 9.0]], np.float32)
    bad, dens = bad_fraction(est, truth, 2.0)
    assert bad == pytest.approx(2 / 3) and dens == pytest.approx(2 / 3)
    assert bad_fraction(est, truth, 2.0, np.zeros((1, 4), bool)) == (None, None)


def test_logpolar_pipeline_on_a_rectified_rig(scene):
    left, right, truth = scene
    f, b = 300.0, 0.1
    k = np.array([[f, 0, (W - 1) / 2], [0, f, (H - 1) / 2], [0, 0, 1]])
    pose_r = np.eye(4)
    pose_r[0, 3] = b
    rig = StereoRig.create(k, k, np.eye(4), pose_r)
    pipe = StereoPipeline(W, H, 'logpolar', (60, 60), retina_kwargs={'max_level': 2})
    assert pipe.matcher.fovea_radius == pytest.approx(fovea_radius(pipe.retina))
    window = disparity_window(k, k, np.eye(4), pose_r, W, H, 0.5, 10.0)
    frame = pipe.process(left, right, rig, window)
    # every match of a rectified rig lies on its epipolar line; depths are f b / d
    assert frame.rejected['off the epipolar line'] == 0 and frame.means.shape[0] > 1000
    u = np.rint(frame.uv_left).astype(int)
    d_true = truth[u[:, 1], u[:, 0]]
    ok = np.isfinite(d_true)
    z_true = f * b / d_true[ok]
    assert np.median(np.abs(frame.means[ok, 2] - z_true) / z_true) < 0.05
    assert np.allclose(epipolar_distance(frame.uv_left, frame.uv_right, k, k, np.eye(4), pose_r),
                       0.0, atol=1e-6)


def test_fovea_radius_of_the_thesis_retina():
    # 200 x 200 RFs on 640x480: RFs one pixel apart at r = 1 / (2 pi / 200) = 31.8 px
    assert fovea_radius(LogPolarRetina(640, 480, 200, 200)) == pytest.approx(31.83, abs=0.01)
