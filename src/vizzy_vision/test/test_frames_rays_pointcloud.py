"""The shared frame, ray and colour helpers: one quaternion convention (x, y, z, w), checked
against rotations built independently."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vizzy_vision.frames import (
    axis_angle_matrix,
    from_wxyz,
    matrices_from_transforms,
    matrix_to_quaternion,
    quaternion_about,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_z_to,
    quaternions_to_matrices,
    rotation_matrix,
    to_wxyz,
)
from vizzy_vision.pointcloud import pack_rgb, unpack_rgb
from vizzy_vision.rays import back_project, pixel_rays


def test_quaternion_about_turns_the_axes_by_the_right_hand_rule() -> None:
    # a quarter turn about +z takes +x to +y; about +y takes +z to +x; about +x takes +y to +z
    r = rotation_matrix(quaternion_about('z', math.pi / 2))
    np.testing.assert_allclose(r @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(rotation_matrix(quaternion_about('y', math.pi / 2)) @ [0, 0, 1],
                               [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(rotation_matrix(quaternion_about('x', math.pi / 2)) @ [0, 1, 0],
                               [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(axis_angle_matrix([0, 0, 2], math.pi / 2), r, atol=1e-12)


def test_products_compose_like_matrices_and_round_trip() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        a, b = rng.normal(size=4), rng.normal(size=4)
        a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
        ab = quaternion_multiply(a, b)
        np.testing.assert_allclose(rotation_matrix(ab), rotation_matrix(a) @ rotation_matrix(b),
                                   atol=1e-12)
        q = matrix_to_quaternion(rotation_matrix(a))
        assert q[3] >= 0.0
        np.testing.assert_allclose(q, a if a[3] >= 0 else -a, atol=1e-12)
        np.testing.assert_allclose(rotation_matrix(quaternion_multiply(a, quaternion_conjugate(a))),
                                   np.eye(3), atol=1e-12)
        assert from_wxyz(to_wxyz(a)) == pytest.approx(tuple(a))
    assert to_wxyz((1.0, 2.0, 3.0, 4.0)).tolist() == [4.0, 1.0, 2.0, 3.0]


def test_batched_matrices_and_transforms() -> None:
    q = np.array([[0, 0, 0, 1], [0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)],
                  [2, 0, 0, 0]])                     # the last one is not unit: normalized
    r = quaternions_to_matrices(q)
    np.testing.assert_allclose(r[1] @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(r[2], np.diag([1.0, -1.0, -1.0]), atol=1e-12)
    m = matrices_from_transforms(np.array([[1.0, 2.0, 3.0]]), q[1:2])[0]
    np.testing.assert_allclose(m @ [1, 0, 0, 1], [1, 3, 3, 1], atol=1e-12)
    with pytest.raises(ValueError, match='invalid rotation'):
        quaternions_to_matrices(np.zeros((1, 4)))
    with pytest.raises(ValueError, match='non-finite translation'):
        matrices_from_transforms(np.array([[np.nan, 0, 0]]), q[:1])


@pytest.mark.parametrize('axis', [(0, 0, 1), (1, 0, 0), (0.3, -0.4, 0.5), (0, 0, -1),
                                  (1e-12, 0, -1)])
def test_z_to_takes_z_onto_the_axis(axis) -> None:
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    np.testing.assert_allclose(rotation_matrix(quaternion_z_to(np.array(axis))) @ [0, 0, 1], a,
                               atol=1e-9)


def test_back_projection_follows_the_pinhole() -> None:
    k = [400.0, 0.0, 320.0, 0.0, 400.0, 240.0, 0.0, 0.0, 1.0]
    assert back_project(320.0, 240.0, k, 2.0) == pytest.approx((0.0, 0.0, 2.0))
    x, y, z = back_project(720.0, 240.0, k, 1.0)               # 45 deg to the right
    assert (x, y, z) == pytest.approx((math.sqrt(0.5), 0.0, math.sqrt(0.5)))
    rays = pixel_rays(np.array([320.0, 720.0]), np.array([240.0, 640.0]), np.array(k).reshape(3, 3))
    np.testing.assert_allclose(np.linalg.norm(rays, axis=-1), 1.0)
    np.testing.assert_allclose(rays[1], np.array([1.0, 1.0, 1.0]) / math.sqrt(3.0))


def test_packed_rgb_is_pcl_bits_and_round_trips() -> None:
    rgb = np.array([[[255, 128, 1], [0, 0, 0]]], np.uint8)
    packed = pack_rgb(rgb)
    assert packed.shape == (1, 2) and packed.dtype == np.float32
    assert packed.view(np.uint32)[0, 0] == 0xFF8001
    np.testing.assert_array_equal(unpack_rgb(packed), rgb)
