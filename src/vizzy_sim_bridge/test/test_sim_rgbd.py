"""The RGB-D sensor model: depth noise grows with range, invalid depth is NaN, clouds are
organized."""

import numpy as np
import pytest

from vizzy_sim_bridge.core.rgbd import (
    CLOUD_DTYPE,
    XTION_SIGMA_COEFFICIENT,
    DepthProjector,
    depth_sigma,
    noisy_depth,
)
from vizzy_vision.camera import camera_matrix
from vizzy_vision.pointcloud import pack_rgb, unpack_rgb


def test_depth_noise_statistics_grow_with_range() -> None:
    rng = np.random.default_rng(0)
    stds = []
    for z in (0.6, 1.0, 1.5, 2.0, 3.0):
        noisy = noisy_depth(np.full((240, 320), z, np.float32), rng)
        err = noisy - z
        assert abs(err.mean()) < 5 * depth_sigma(z) / np.sqrt(err.size) + 1e-6   # unbiased
        stds.append(err.std())
        assert err.std() == pytest.approx(XTION_SIGMA_COEFFICIENT * z * z, rel=0.05)
    assert all(a < b for a, b in zip(stds, stds[1:], strict=False))
    assert stds[-1] / stds[0] == pytest.approx((3.0 / 0.6) ** 2, rel=0.1)    # quadratic


def test_invalid_depth_is_nan_and_noise_can_be_off() -> None:
    depth = np.array([[0.2, 0.5, 1.0], [3.5, 3.6, np.inf]], np.float32)
    out = noisy_depth(depth, None)
    np.testing.assert_array_equal(np.isnan(out), [[True, False, False], [False, True, True]])
    np.testing.assert_array_equal(out[~np.isnan(out)], depth[~np.isnan(out)])
    assert noisy_depth(depth, np.random.default_rng(1), coefficient=0.0)[0, 2] == 1.0


def test_rgb_packing_round_trips() -> None:
    rgb = np.random.default_rng(2).integers(0, 256, (4, 5, 3), dtype=np.uint8)
    packed = pack_rgb(rgb)
    assert packed.dtype == np.float32
    bits = packed.view(np.uint32)
    assert int(bits[0, 0]) == ((int(rgb[0, 0, 0]) << 16) | (int(rgb[0, 0, 1]) << 8)
                               | int(rgb[0, 0, 2]))
    np.testing.assert_array_equal(unpack_rgb(packed), rgb)


def test_cloud_is_organized_pinhole_back_projection() -> None:
    k = camera_matrix(64, 48, 58.0)
    depth = np.full((48, 64), 2.0, np.float32)
    depth[10, 20] = np.nan
    rgb = np.zeros((48, 64, 3), np.uint8)
    rgb[..., 0] = 255
    cloud = DepthProjector(k, 64, 48).cloud(depth, rgb)
    assert cloud.dtype == CLOUD_DTYPE and cloud.shape == (48, 64)
    assert cloud[5, 7]['x'] == pytest.approx((7 - k[0, 2]) * 2.0 / k[0, 0])
    assert cloud[5, 7]['y'] == pytest.approx((5 - k[1, 2]) * 2.0 / k[1, 1])
    assert np.isnan(cloud[10, 20]['z']) and np.isnan(cloud[10, 20]['x'])
    np.testing.assert_array_equal(unpack_rgb(cloud['rgb'])[0, 0], [255, 0, 0])
    with pytest.raises(ValueError):
        DepthProjector(k, 64, 48).cloud(depth[:10], rgb)


def test_noise_is_the_model_to_the_bit() -> None:
    # issue 27: computed in one temporary; the same numbers as zv + (c zv^2) n, n ~ N(0, 1)
    depth = np.random.default_rng(3).uniform(0.3, 4.0, (48, 64)).astype(np.float32)
    depth[5, :7] = np.inf
    out = noisy_depth(depth, np.random.default_rng(4))
    hit = np.isfinite(depth)
    zv = depth[hit]
    n = np.random.default_rng(4).standard_normal(zv.shape, dtype=np.float32)
    ref = depth.copy()
    ref[hit] = zv + (XTION_SIGMA_COEFFICIENT * zv * zv) * n
    ref[~hit | (ref < 0.5) | (ref > 3.5)] = np.nan
    np.testing.assert_array_equal(out, ref)
