"""Cylinder fitting (thesis section 4.3.3): synthetic cylinders recovered; caps break the
baseline only."""

from __future__ import annotations

import numpy as np
import pytest

from cylinder_detector_node.core.accumulator import TABLE_4_1
from cylinder_detector_node.core.fitting import FitParams, fit_cylinder, make_directions
from cylinder_detector_node.core.geometry import normals_and_curvature
from cylinder_detector_node.core.synthetic import (
    axis_angle_deg,
    axis_distance,
    make_cylinder,
    random_axis,
)


@pytest.mark.parametrize('seed', range(8))
def test_random_pose_cylinders_are_recovered(seed: int) -> None:
    """Random axis, centre, radius 3-10 cm, height 2-6 radii, noise 1% of r, 900 points:
    axis within 6 deg, radius within 10%, axis within 0.2 r of the centre, height within 15%."""
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.03, 0.1)
    h = r * rng.uniform(2.0, 6.0)
    s = make_cylinder(rng, r, h, 900, 0.0, 0.01 * r, axis=random_axis(rng),
                      centre=rng.uniform(-1, 1, 3))
    c = fit_cylinder(s.points, FitParams(n_directions=2000))
    assert c is not None
    assert axis_angle_deg(np.array(c.axis), s.axis) < 6.0
    assert abs(c.radius - r) < 0.1 * r
    assert axis_distance(s.centre, np.array(c.centre), np.array(c.axis)) < 0.2 * r
    assert abs(c.height - h) < 0.15 * h
    assert c.confidence > 0.8


def test_capped_cylinders_break_the_baseline_not_ours() -> None:
    """Upright cylinders with lids holding 150% of the side's points (Eq. 4.5: 60% outliers)."""
    base = dict(radius_min=0.1, radius_max=0.5, min_confidence=0.0)
    rabbani, ours = FitParams(method='rabbani', **base), FitParams(gmm=TABLE_4_1['mild'], **base)
    d_r, d_o = make_directions(rabbani), make_directions(ours)
    err_r, err_o = [], []
    for i in range(10):
        rng = np.random.default_rng(100 + i)
        s = make_cylinder(rng, 0.3, rng.uniform(0.8, 2.0), 900, 1.5, centre=rng.uniform(-1, 1, 3))
        assert s.outlier_fraction == pytest.approx(0.6)
        err_r.append(axis_angle_deg(np.array(fit_cylinder(s.points, rabbani, d_r).axis), s.axis))
        err_o.append(axis_angle_deg(np.array(fit_cylinder(s.points, ours, d_o).axis), s.axis))
    assert np.mean(err_r) > 60.0       # the lids' normals win: the axis lies flat
    assert np.mean(err_o) < 10.0


def test_curvature_of_cylinder_and_plane() -> None:
    """Side points: normal and c_max orthogonal to the axis; lid points: k_max near 0."""
    rng = np.random.default_rng(3)
    s = make_cylinder(rng, 0.05, 0.3, 2000, 1.0)
    n, c, k = normals_and_curvature(s.points, 15)
    side = slice(0, 2000)
    assert np.median(np.abs(n[side] @ s.axis)) < 0.05
    assert np.median(np.abs(c[side] @ s.axis)) < 0.2
    assert np.median(k[2000:]) < 0.1 * np.median(k[side])


def test_bad_clusters_give_none() -> None:
    p = FitParams()
    assert fit_cylinder(np.zeros((0, 3)), p) is None
    assert fit_cylinder(np.full((500, 3), np.nan), p) is None
    # fewer than min_points
    assert fit_cylinder(np.random.default_rng(0).normal(size=(10, 3)), p) is None
    plane = np.column_stack([np.random.default_rng(1).uniform(-0.1, 0.1, (800, 2)), np.zeros(800)])
    # a flat patch is no cylinder
    assert fit_cylinder(plane, FitParams(min_confidence=0.5)) is None


def test_parameters_are_checked() -> None:
    with pytest.raises(ValueError, match='method'):
        FitParams(method='ransac')
    with pytest.raises(ValueError, match='radius'):
        FitParams(radius_min=0.2, radius_max=0.1)


def test_short_capped_cylinders_recovered_by_retrying_peaks() -> None:
    """Short cylinders (height 0.05-0.5 m = 0.2-1.7 r) under 150% lid points: the top accumulator
    peak is often flat (rims outvote the side), its Eq. 4.4 fit is weak, and the next well-separated
    peaks find the axis; without the retry most of these scenes fail (8 of these 12)."""
    base = dict(gmm=TABLE_4_1['mild'], radius_min=0.1, radius_max=0.5, min_confidence=0.0)
    with_retry, without = FitParams(**base), FitParams(retry_peaks=0, **base)
    d = make_directions(with_retry)
    err_with, err_without = [], []
    for i in range(12):
        rng = np.random.default_rng(500 + i)
        s = make_cylinder(rng, 0.3, rng.uniform(0.05, 0.5), 900, 1.5, centre=rng.uniform(-1, 1, 3))
        err_with.append(axis_angle_deg(np.array(fit_cylinder(s.points, with_retry, d).axis),
                                       s.axis))
        err_without.append(axis_angle_deg(np.array(fit_cylinder(s.points, without, d).axis),
                                          s.axis))
    assert np.mean(np.array(err_without) > 60.0) >= 0.5     # flat axes (about 90 degrees off)
    # no flat axis left; disks (h < 0.2 m) stay off by 30-45
    assert max(err_with) < 60.0
    assert np.median(err_with) < 5.0


def test_coarse_to_fine_vote_and_closed_form_curvature_match_the_full_ones() -> None:
    """The speed-ups change no result: the coarse-to-fine accumulator picks the full vote's cell,
    and the 2x2 closed-form curvature equals the 3x3 eigendecomposition."""
    from cylinder_detector_node.core.fitting import axis_votes
    from cylinder_detector_node.core.geometry import pca_normals, principal_curvature
    p = FitParams(gmm=TABLE_4_1['unbiased'])
    d = make_directions(p)
    same = 0
    for i in range(10):
        rng = np.random.default_rng(900 + i)
        s = make_cylinder(rng, 0.05, 0.2, 600, 0.5, 0.0005, axis=random_axis(rng))
        n, idx = pca_normals(s.points)
        c, k = principal_curvature(n, idx)
        full, _ = axis_votes(n, c, k, d, 'ours', p.curvature_saturation, p.vote_sharpness)
        fast, _ = axis_votes(n, c, k, d, 'ours', p.curvature_saturation, p.vote_sharpness, 100, 16)
        same += full == fast
        # reference curvature: the largest eigenpair of the projected normals' 3x3 covariance
        nn = n[idx] * np.where(np.einsum('nkj,nj->nk', n[idx], n) < 0, -1.0, 1.0)[..., None]
        proj = nn - np.einsum('nkj,nj->nk', nn, n)[..., None] * n[:, None, :]
        proj -= proj.mean(axis=1, keepdims=True)
        val, vec = np.linalg.eigh(np.einsum('nki,nkj->nij', proj, proj) / idx.shape[1])
        assert np.allclose(k, val[:, 2], atol=1e-12)
        curved = val[:, 2] > 1e-3
        assert np.allclose(np.abs(np.sum(c * vec[:, :, 2], axis=1))[curved], 1.0, atol=1e-6)
    assert same >= 9


def test_curvature_is_the_same_in_any_tangent_basis_and_defined_on_planes() -> None:
    """normals_and_curvature (the PCA's tangent eigenvectors as the basis) gives the k_max of the
    branch-free basis to 1e-12 and the same c_max up to sign; a perfectly flat patch (every
    neighbour normal equal, isotropic 2x2 covariance) gives k_max = 0 and a finite unit c_max in
    the tangent plane."""
    from cylinder_detector_node.core.geometry import pca_normals, principal_curvature
    rng = np.random.default_rng(7)
    s = make_cylinder(rng, 0.05, 0.2, 600, 0.5, 0.0005, axis=random_axis(rng))
    n, c, k = normals_and_curvature(s.points)
    n2, idx = pca_normals(s.points)
    c2, k2 = principal_curvature(n2, idx)
    assert np.array_equal(n, n2)
    assert np.allclose(k, k2, atol=1e-12)
    curved = k > 1e-3
    assert curved.sum() > 300
    assert np.allclose(np.abs(np.sum(c * c2, axis=1))[curved], 1.0, atol=1e-9)
    # signs as PCA leaves them
    flat_n = np.tile([0.0, 0.0, 1.0], (50, 1)) * rng.choice([-1.0, 1.0], (50, 1))
    flat_idx = np.array([np.roll(np.arange(50), -i)[:15] for i in range(50)])
    c3, k3 = principal_curvature(flat_n, flat_idx)
    assert np.all(k3 == 0.0)
    assert np.all(np.isfinite(c3))
    assert np.allclose(np.linalg.norm(c3, axis=1), 1.0) and np.allclose(c3[:, 2], 0.0)
