"""Sensory Ego-Sphere: GMM cells (Eq. 3.21), association (Eq. 3.23), fusion (Eqs. 3.26-3.35)."""

import numpy as np
import pytest

from stereo_ses_node.core.ses import (
    BIASES,
    GMM,
    SensoryEgoSphere,
    SphereLookup,
    brute_force_associate,
    sample_directions,
)


def unit(rng, n):
    q = rng.standard_normal((n, 3))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_cells_are_unit_vectors():
    d = sample_directions(5000, 'unbiased', np.random.default_rng(0))
    assert d.shape == (5000, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)


def test_biases_put_more_cells_where_they_say():
    rng = np.random.default_rng(0)
    n = 20000
    unb = sample_directions(n, 'unbiased', rng)
    top = sample_directions(n, 'top', rng)
    down = sample_directions(n, 'down', rng)
    tgt = sample_directions(n, 'target', rng)
    up_frac = lambda d: np.mean(d[:, 2] > 0.5)   # noqa: E731
    assert 0.2 < up_frac(unb) < 0.3                      # uniform: 25% of the sphere
    assert up_frac(top) > 2 * up_frac(unb)
    assert np.mean(down[:, 2] < -0.5) > 2 * np.mean(unb[:, 2] < -0.5)
    t = np.array([0.61, 0.43, -0.67])
    t /= np.linalg.norm(t)
    near = lambda d: np.mean(d @ t > np.cos(np.radians(20)))   # noqa: E731
    assert near(tgt) > 10 * near(unb)
    # a user GMM with two lateral components (Fig. 3.7f)
    lateral = GMM.create([0.5, 0.5], [[0, 1, 0], [0, -1, 0]], [[0.1, 0.1, 0.1]] * 2)
    lat = sample_directions(n, lateral, rng)
    assert np.mean(np.abs(lat[:, 1]) > 0.8) > 3 * np.mean(np.abs(unb[:, 1]) > 0.8)


def test_bad_gmm_and_bias_rejected():
    with pytest.raises(ValueError, match='unknown bias'):
        sample_directions(10, 'sideways', np.random.default_rng(0))
    with pytest.raises(ValueError, match='positive definite'):
        GMM.create([1.0], [[0, 0, 0]], [[1.0, -1.0, 1.0]])
    with pytest.raises(ValueError):
        GMM.create([1.0, 1.0], [[0, 0, 0]], [[1.0, 1.0, 1.0]])


@pytest.mark.parametrize('bias', sorted(BIASES))
def test_fast_association_equals_brute_force(bias):
    ses = SensoryEgoSphere(20000, bias, seed=3)
    q = unit(np.random.default_rng(4), 40000 if bias == 'unbiased' else 10000)
    ref = brute_force_associate(q, ses.directions)
    np.testing.assert_array_equal(ses.associate(q, 'grid'), ref)
    np.testing.assert_array_equal(ses.associate(q, 'kdtree'), ref)
    np.testing.assert_array_equal(ses.associate(5.0 * q, 'brute'), ref)   # scale-free


def test_lookup_small_and_dense_spheres():
    rng = np.random.default_rng(5)
    for cells in (unit(rng, 7), sample_directions(3000, 'target', rng)):
        lk = SphereLookup(cells, max_candidates=8)
        q = unit(rng, 5000)
        np.testing.assert_array_equal(lk.query(q), brute_force_associate(q, cells))


def test_lookup_stores_each_bin_once():
    # issue 27: every padded width's table held every bin (92 MB for 20,000 cells); each bin's
    # candidates are now in its own width's table only, and the answers stay the brute force's
    ses = SensoryEgoSphere(20000, 'unbiased', seed=0)
    lk = ses.lookup
    rows = sum(t[0].shape[0] for t in lk.tables.values())
    assert rows == np.count_nonzero(lk.bin_group)
    for width, (idx, *_) in lk.tables.items():
        members = np.nonzero(lk.bin_group == width // 8)[0]
        assert idx.shape == (members.size, width)
        np.testing.assert_array_equal(lk.bin_row[members], np.arange(members.size))
    stored = sum(a.nbytes for t in lk.tables.values() for a in t)
    assert stored < 20e6, stored
    q = unit(np.random.default_rng(11), 20000)
    np.testing.assert_array_equal(lk.query(q), brute_force_associate(q, ses.directions))


def test_fusion_shrinks_covariance_as_eq_3_34_says():
    ses = SensoryEgoSphere(500, seed=0, init_sigma=10.0)
    d = ses.directions[42]
    x = 2.0 * d
    cov = np.diag([0.01, 0.02, 0.03])
    lam0 = np.eye(3) / 100.0
    for n in range(1, 6):
        ses.fuse(x[None], cov[None])
        expect = np.linalg.inv(lam0 + n * np.linalg.inv(cov))               # Eq. 3.34
        np.testing.assert_allclose(ses.cov[42], expect, rtol=1e-9)
        mu = expect @ (lam0 @ (10.0 * d) + n * np.linalg.inv(cov) @ x)      # Eq. 3.35
        np.testing.assert_allclose(ses.mean[42], mu, rtol=1e-9)
    assert ses.n_obs[42] == 5
    assert ses.n_obs.sum() == 5


def test_batch_fusion_equals_sequential_and_uses_rigid_transform():
    rng = np.random.default_rng(2)
    a = SensoryEgoSphere(300, seed=1)
    b = SensoryEgoSphere(300, seed=1)
    pts = unit(rng, 50) * rng.uniform(0.5, 3.0, (50, 1))
    m = rng.standard_normal((50, 3, 3)) * 0.1
    covs = m @ m.transpose(0, 2, 1) + 0.01 * np.eye(3)
    ang = 0.3
    pose = np.eye(4)
    pose[:3, :3] = [[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]]
    pose[:3, 3] = [0.1, -0.2, 0.05]
    rep = a.fuse(pts, covs, pose)
    assert rep.fused == 50 and rep.cells_updated > 0
    r, t = pose[:3, :3], pose[:3, 3]
    for i in range(50):                                  # one by one, already in the ego frame
        b.fuse((r @ pts[i] + t)[None], (r @ covs[i] @ r.T)[None])
    np.testing.assert_allclose(a.cov, b.cov, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(a.mean, b.mean, rtol=1e-8, atol=1e-10)


def test_bad_observations_skipped_and_sphere_consistent():
    ses = SensoryEgoSphere(400, seed=0)
    before = (ses.mean.copy(), ses.cov.copy(), ses.info.copy())
    with pytest.raises(ValueError, match='expected means'):
        ses.fuse(np.zeros((3, 3)), np.zeros((2, 3, 3)))
    with pytest.raises(ValueError, match='rigid'):
        ses.fuse(np.ones((1, 3)), np.eye(3)[None], np.zeros((4, 4)))
    for arr, ref in zip((ses.mean, ses.cov, ses.info), before, strict=True):
        np.testing.assert_array_equal(arr, ref)
    good = np.eye(3)[None] * 0.01
    means = np.array([[1.0, 0, 0], [np.nan, 0, 0], [0, 1.0, 0], [0, 0, 0], [0, 0, 1.0]])
    covs = np.concatenate([good, good, -good, good, np.full((1, 3, 3), np.nan)])
    rep = ses.fuse(means, covs)
    assert rep.fused == 1 and rep.received == 5
    assert rep.rejected == {'non-finite mean': 1, 'bad covariance': 2, 'at ego origin': 1}
    assert 'rejected' in rep.summary()
    assert np.all(np.isfinite(ses.mean)) and np.all(np.isfinite(ses.cov))
    assert np.all(np.linalg.eigvalsh(ses.cov)[:, 0] > 0)
    assert ses.n_obs.sum() == 1


def test_n_frames_counts_the_fuse_calls_that_observed_a_cell() -> None:
    ses = SensoryEgoSphere(500, seed=0)
    points = np.array([[2.0, 0.0, 0.0]] * 7)             # seven points, one cell
    covs = np.broadcast_to(np.eye(3) * 1e-4, (7, 3, 3))
    ses.fuse(points, covs)
    ses.fuse(points[:2], covs[:2])
    cell = int(np.argmax(ses.n_obs))
    assert ses.n_obs[cell] == 9 and ses.n_frames[cell] == 2
    assert ses.n_frames.sum() == 2
