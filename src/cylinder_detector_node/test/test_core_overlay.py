"""Cylinders drawn on the RGB-D image: intrinsics recovered from an organized cloud, outlines
projected where the cylinder is."""

import numpy as np

from cylinder_detector_node.core.fitting import Cylinder
from cylinder_detector_node.core.overlay import (
    CYLINDER_COLOUR,
    cylinder_outline,
    draw_cylinders,
    intrinsics_from_organized,
    project,
)

K = np.array([[525.0, 0.0, 319.5], [0.0, 520.0, 239.5], [0.0, 0.0, 1.0]])


def _organized(depth: np.ndarray) -> np.ndarray:
    h, w = depth.shape
    v, u = np.mgrid[0:h, 0:w].astype(float)
    x = (u - K[0, 2]) / K[0, 0] * depth
    y = (v - K[1, 2]) / K[1, 1] * depth
    return np.stack([x, y, depth], -1)


def test_intrinsics_come_back_from_an_organized_cloud() -> None:
    rng = np.random.default_rng(0)
    depth = rng.uniform(0.6, 2.5, (480, 640))
    depth[rng.random(depth.shape) < 0.3] = np.nan              # holes, as a real sensor has
    k = intrinsics_from_organized(_organized(depth))
    assert k is not None and np.allclose(k, K, atol=1e-6)
    assert intrinsics_from_organized(np.full((10, 10, 3), np.nan)) is None


def test_a_cylinder_is_drawn_where_it_projects() -> None:
    c = Cylinder(centre=(0.05, 0.02, 1.0), axis=(0.0, -1.0, 0.0), radius=0.04, height=0.12,
                 confidence=0.9, n_inliers=500, n_points=600)
    bottom, top = cylinder_outline(c)
    assert np.allclose(np.linalg.norm(bottom - np.array([0.05, 0.08, 1.0]), axis=1), 0.04)
    out = draw_cylinders(np.zeros((480, 640, 3), np.uint8), K, [c])
    uv = project(top, K)
    # the rightmost point of the top ring
    u, v = np.round(uv[np.argmax(uv[:, 0])]).astype(int)
    patch = out[v - 2:v + 3, u - 2:u + 3]
    assert (patch == np.array(CYLINDER_COLOUR, np.uint8)).all(axis=-1).any()
    far = out[400:, 50:150]                                      # nowhere near the cylinder
    assert not (far == np.array(CYLINDER_COLOUR, np.uint8)).all(axis=-1).any()
