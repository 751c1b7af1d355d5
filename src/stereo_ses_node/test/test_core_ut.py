"""Triangulation (Eq. 3.8) and the Unscented Transform (Eqs. 3.9-3.18) against references."""

import numpy as np
import pytest

from stereo_ses_node.core.geometry import project, triangulate_midpoint, vergence_poses
from stereo_ses_node.core.sensors import cartesian_sensor
from stereo_ses_node.core.ut import (
    UT_CHUNK,
    SigmaPointTable,
    StereoRig,
    UTParams,
    linearized_triangulate,
    monte_carlo_triangulate,
    unscented_transform,
)

F = 320.0 / np.tan(np.radians(85.4 / 2))       # Vizzy eye camera: 640x480, 85.4 deg
K = np.array([[F, 0, 319.5], [0, F, 239.5], [0, 0, 1.0]])
BASELINE = 0.204


def rig_fixating(distance: float, version: float = 0.0, tilt: float = 0.0) -> StereoRig:
    pl, pr = vergence_poses(BASELINE, 2 * np.arctan(BASELINE / 2 / distance), version, tilt)
    return StereoRig.create(K, K, pl, pr)


def test_triangulation_recovers_known_points():
    rng = np.random.default_rng(0)
    rig = rig_fixating(0.8, version=0.1, tilt=0.2)
    pts = np.stack([rng.uniform(-0.5, 0.5, 500), rng.uniform(-0.4, 0.4, 500),
                    rng.uniform(0.4, 3.0, 500)], axis=-1)
    ul = project(pts, K, rig.pose_left)
    ur = project(pts, K, rig.pose_right)
    est, ok = triangulate_midpoint(ul, ur, K, K, rig.pose_left, rig.pose_right)
    assert ok.all()
    np.testing.assert_allclose(est, pts, atol=1e-9)


def test_midpoint_of_skew_rays():
    rig = rig_fixating(1.0)
    x = np.array([0.1, 0.05, 1.2])
    ul, ur = project(x, K, rig.pose_left), project(x, K, rig.pose_right)
    est, ok = triangulate_midpoint(ul, ur + [0.0, 3.0], K, K, rig.pose_left, rig.pose_right)
    assert ok and np.linalg.norm(est - x) < 0.02           # rays miss; midpoint stays close


def test_degenerate_geometry_is_flagged():
    pl, pr = vergence_poses(BASELINE, 0.0)                   # parallel cameras
    uv = np.array([[300.0, 200.0]])
    _, ok = triangulate_midpoint(uv, uv, K, K, pl, pr)       # zero disparity: parallel rays
    assert not ok[0]
    _, ok = triangulate_midpoint(uv, uv + [10.0, 0.0], K, K, pl, pr)   # behind the cameras
    assert not ok[0]
    pts, ok = triangulate_midpoint(np.array([[np.nan, 1.0]]), uv, K, K, pl, pr)
    assert not ok[0] and np.isnan(pts).all()
    with pytest.raises(ValueError, match='matching'):
        triangulate_midpoint(uv, np.zeros((2, 2)), K, K, pl, pr)
    with pytest.raises(ValueError, match='zero baseline'):
        StereoRig.create(K, K, pl, pl)
    with pytest.raises(ValueError, match='pose_left'):
        StereoRig.create(K, K, np.eye(3), pr)


def test_weights_match_thesis_defaults():
    p = UTParams()                                           # L 4, alpha 0.25, beta 2, kappa 3
    wm, wc = p.weights()
    assert p.lam == pytest.approx(0.0625 * 7 - 4)
    assert wm.sum() == pytest.approx(1.0)
    assert wm[0] == pytest.approx(p.lam / (4 + p.lam))
    assert wc[0] == pytest.approx(wm[0] + 1 - 0.0625 + 2)
    assert np.allclose(wm[1:], 1 / (2 * (4 + p.lam)))
    with pytest.raises(ValueError):
        UTParams(L=3)


def test_sigma_point_table_is_eq_3_10_to_3_12():
    s = cartesian_sensor(640, 480, 20, 10)
    table = SigmaPointTable(s, s)
    il, ir = np.array([3, 7]), np.array([5, 5])
    sp = table.sigma_points(s.centers[il], s.centers[ir], il, ir)
    mu = np.concatenate([s.centers[il], s.centers[ir]], axis=1)
    p = UTParams()
    root = np.sqrt(4 + p.lam) * table.std(il, ir)           # sqrt((L+lambda) Sigma), diagonal
    np.testing.assert_allclose(sp[:, 0], mu)
    for j in range(4):
        np.testing.assert_allclose(sp[:, 1 + j], mu + root * np.eye(4)[j])
        np.testing.assert_allclose(sp[:, 5 + j], mu - root * np.eye(4)[j])


# moderately non-linear cases of the thesis's geometry: (fixation, depth, sigma px, offset px)
CASES = [(0.5, 1.0, 4.0, (200, 100)), (1.0, 2.0, 1.6, (150, 100)), (1.0, 1.0, 8.0, (250, 150)),
         (0.5, 2.0, 4.0, (200, 100))]


def ut_lin_mc(fix, depth, sigma, off, rng, samples=400_000):
    rig = rig_fixating(fix)
    x = np.array([off[0] / F * depth, off[1] / F * depth, depth])
    mu = np.concatenate([project(x, K, rig.pose_left), project(x, K, rig.pose_right)])[None]
    std = np.full((1, 4), sigma)
    p = UTParams()
    wm, wc = p.weights()
    root = np.sqrt(4 + p.lam) * np.diag(std[0])
    sp = mu[:, None, :] + np.concatenate([np.zeros((1, 4)), root, -root])[None]
    um, uc, uok = unscented_transform(rig, sp, wm, wc)
    lm, lc, lok = linearized_triangulate(rig, mu, std)
    mm, mc, frac = monte_carlo_triangulate(rig, mu[0], std[0], samples, rng)
    assert uok.all() and lok.all() and frac > 0.999
    return um[0], uc[0], lm[0], lc[0], mm, mc


def test_ut_matches_monte_carlo_and_beats_linearization():
    rng = np.random.default_rng(1)
    ut_mean_err, lin_mean_err, ut_cov_err, lin_cov_err = [], [], [], []
    for case in CASES:
        um, uc, lm, lc, mm, mc = ut_lin_mc(*case, rng)
        sd = np.sqrt(np.trace(mc))
        ut_mean_err.append(np.linalg.norm(um - mm) / sd)
        lin_mean_err.append(np.linalg.norm(lm - mm) / sd)
        ut_cov_err.append(np.linalg.norm(uc - mc) / np.linalg.norm(mc))
        lin_cov_err.append(np.linalg.norm(lc - mc) / np.linalg.norm(mc))
    ut_mean_err, lin_mean_err = np.array(ut_mean_err), np.array(lin_mean_err)
    ut_cov_err, lin_cov_err = np.array(ut_cov_err), np.array(lin_cov_err)
    # UT within tolerance of Monte Carlo (MC standard error ~0.003 sd here)
    assert np.all(ut_mean_err < 0.02), ut_mean_err
    assert np.all(ut_cov_err < 0.12), ut_cov_err
    # and more precise than first-order linearization (the thesis's claim)
    assert np.all(ut_mean_err < lin_mean_err), (ut_mean_err, lin_mean_err)
    assert ut_cov_err.mean() < lin_cov_err.mean(), (ut_cov_err, lin_cov_err)


def test_ut_is_vectorized_over_points():
    s = cartesian_sensor(640, 480, 40, 30)
    table = SigmaPointTable(s, s)
    rig = rig_fixating(1.0)
    ul = s.centers
    ur = ul - [30.0, 0.0]
    il, ir = np.arange(s.n_rf), s.rf_index(ur[:, 0], ur[:, 1])
    m, c, ok = unscented_transform(rig, table.sigma_points(ul, ur, il, ir), table.wm, table.wc)
    assert m.shape == (s.n_rf, 3) and c.shape == (s.n_rf, 3, 3)
    # each row equals the single-point computation
    for i in (0, 17, s.n_rf - 1):
        m1, c1, _ = unscented_transform(rig, table.sigma_points(ul[i:i + 1], ur[i:i + 1],
                                                                il[i:i + 1], ir[i:i + 1]),
                                        table.wm, table.wc)
        np.testing.assert_allclose(m1[0], m[i], equal_nan=True)
        np.testing.assert_allclose(c1[0], c[i], equal_nan=True)
    good = ok & np.all(np.isfinite(c.reshape(len(c), -1)), axis=1)
    assert good.sum() > 0.5 * s.n_rf
    assert np.all(np.linalg.eigvalsh(c[good])[:, 0] > 0)  # covariances positive definite


def test_table_transform_equals_sigma_point_array_path():
    s = cartesian_sensor(640, 480, 30, 20)
    table = SigmaPointTable(s, s)
    rig = rig_fixating(1.5)
    ul = s.centers
    ur = ul - [12.0, 0.5]
    ur[::7, 0] += 250.0                                     # diverging rays: invalid
    il, ir = np.arange(s.n_rf), s.rf_index(ur[:, 0], ur[:, 1])
    ref = unscented_transform(rig, table.sigma_points(ul, ur, il, ir), table.wm, table.wc)
    got = table.transform(rig, ul, ur, il, ir)
    assert 0 < np.sum(got[2]) < got[2].size               # some rows invalid (behind a camera)
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15, equal_nan=True)


def test_transform_in_blocks_is_bit_identical_and_the_table_stores_no_offsets():
    # issue 27: the table keeps h = sqrt(L + lambda) sigma per RF, not (N_rf, 2L+1, 2) offset
    # arrays (23 MB for 40,000 RFs), and transform works UT_CHUNK rows at a time
    s = cartesian_sensor(640, 480, 200, 200)
    table = SigmaPointTable(s, s)
    arrays = {id(v): v for v in vars(table).values() if isinstance(v, np.ndarray)}
    assert sum(v.nbytes for v in arrays.values()) <= 4 * s.n_rf * 8
    rig = rig_fixating(1.2, version=0.05, tilt=0.1)
    rng = np.random.default_rng(7)
    il = rng.choice(s.n_rf, 2 * UT_CHUNK + 123, replace=False)
    ul = s.centers[il] + rng.uniform(-0.5, 0.5, (il.size, 2))
    ur = ul - [rng.uniform(5.0, 40.0), 0.3]
    ur[::11, 0] += 300.0                                    # diverging rays: invalid rows
    ir = s.rf_index(ur[:, 0], ur[:, 1])
    # the sigma points are mean + the stored offsets, as the thesis's table defines them
    old = np.concatenate([ul[:, None, :] + table.offsets_left[il],
                          ur[:, None, :] + table.offsets_right[ir]], axis=-1)
    sp = table.sigma_points(ul, ur, il, ir)
    np.testing.assert_array_equal(sp, old)
    ref = unscented_transform(rig, old, table.wm, table.wc)      # all rows at once
    got = table.transform(rig, ul, ur, il, ir)
    assert 0 < np.sum(got[2]) < got[2].size
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_array_equal(a, b)                     # the same bits, NaNs included
