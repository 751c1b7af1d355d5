"""Orientation accumulators (Eq. 4.1-4.3, Table 4.1)."""

from __future__ import annotations

import numpy as np
import pytest

from cylinder_detector_node.core.accumulator import (
    TABLE_4_1,
    OrientationGMM,
    sample_gmm_directions,
    uniform_directions,
    vote_curvature,
    vote_normals,
)


def test_directions_are_unit() -> None:
    d = sample_gmm_directions(TABLE_4_1['mild'], 450, np.random.default_rng(0))
    assert d.shape == (450, 3)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
    assert np.allclose(np.linalg.norm(uniform_directions(450), axis=1), 1.0)


def test_biased_accumulators_sample_where_the_gmm_says() -> None:
    rng = np.random.default_rng(1)
    z = {name: sample_gmm_directions(g, 20000, rng)[:, 2] for name, g in TABLE_4_1.items()}
    assert abs(z['unbiased'].mean()) < 0.02                    # symmetric
    assert abs(np.mean(np.abs(z['unbiased'])) - 0.5) < 0.02    # uniform on the sphere: E|z| = 1/2
    # a 45-degree cap: 14.6% of the sphere
    within45 = {k: np.mean(v > np.cos(np.radians(45))) for k, v in z.items()}
    assert abs(within45['unbiased'] - (1 - np.cos(np.radians(45))) / 2) < 0.01
    assert 0.45 < within45['mild'] < 0.7
    assert within45['strong'] > 0.98
    assert np.mean(np.abs(z['mild'])) > np.mean(np.abs(z['unbiased']))


def test_user_mixture_components() -> None:
    gmm = OrientationGMM((0.5, 0.5), ((1.0, 0, 0), (0, 1.0, 0)), ((0.01,) * 3, (0.01,) * 3))
    d = sample_gmm_directions(gmm, 4000, np.random.default_rng(2))
    near_x = np.abs(d[:, 0]) > 0.9
    near_y = np.abs(d[:, 1]) > 0.9
    assert np.mean(near_x | near_y) > 0.99
    assert 0.45 < near_x.mean() < 0.55
    with pytest.raises(ValueError):
        OrientationGMM((1.0,), ((0, 0, 1.0),), ((0.0, 1.0, 1.0),))


def test_votes_peak_at_the_axis() -> None:
    """Normals and c_max of an upright cylinder's side are horizontal: both votes peak at z
    (Eq. 4.3)."""
    th = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    n = np.column_stack([np.cos(th), np.sin(th), np.zeros_like(th)])
    c = np.column_stack([-np.sin(th), np.cos(th), np.zeros_like(th)])
    d = uniform_directions(500)
    assert abs(d[np.argmax(vote_curvature(d, n, c, np.ones(100)))][2]) > 0.99
    assert abs(d[np.argmax(vote_normals(d, n))][2]) > 0.99
    # a flat point (k_max = 0) casts no curvature vote
    assert np.allclose(vote_curvature(d, n, c, np.zeros(100)), 0.0)
