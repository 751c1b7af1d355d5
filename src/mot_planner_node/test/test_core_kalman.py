"""Kalman prediction, update, gating distance and log-determinant against hand-computed values."""

import numpy as np
import pytest

from mot_planner_node.core.association import associate, gate_threshold
from mot_planner_node.core.kalman import (
    MotionModel,
    logdet_sigma,
    mahalanobis_sq,
    predict,
    update,
    update_covariance,
)


def one_target():
    x = np.array([[10.0, 20.0, 1.0, 1.0, 2.0, 0.1]])
    P = np.diag([4.0, 4.0, 0.01, 1.0, 1.0, 0.001])[None]
    return x, P


def test_transition_matrix() -> None:
    F = MotionModel(dt=2.0).F
    expected = np.eye(6)
    expected[0, 3] = expected[1, 4] = expected[2, 5] = 2.0
    np.testing.assert_array_equal(F, expected)


def test_predict_by_hand() -> None:
    # accel std 0.5 px/frame^2 at scale 1 -> variance 0.25; G = [1/2, 1]:
    # Q_uu = 0.25/4, Q_u,du = 0.25/2, Q_du,du = 0.25. Scale: std 0.1 -> var 0.01.
    x, P = one_target()
    xp, Pp = predict(x, P, MotionModel(accel_std=0.5, scale_accel_std=0.1))
    np.testing.assert_allclose(xp[0], [11.0, 22.0, 1.1, 1.0, 2.0, 0.1])
    p = Pp[0]
    assert p[0, 0] == pytest.approx(4.0 + 1.0 + 0.0625)
    assert p[0, 3] == pytest.approx(1.0 + 0.125)
    assert p[3, 3] == pytest.approx(1.0 + 0.25)
    assert p[1, 1] == pytest.approx(5.0625)
    assert p[2, 2] == pytest.approx(0.01 + 0.001 + 0.0025)
    assert p[2, 5] == pytest.approx(0.001 + 0.005)
    assert p[5, 5] == pytest.approx(0.001 + 0.01)
    assert p[0, 1] == 0.0 and p[0, 2] == 0.0
    np.testing.assert_allclose(p, p.T)


def test_process_noise_scales_with_the_target_scale() -> None:
    q = MotionModel(accel_std=1.0).Q(np.array([1.0, 2.0]))
    assert q[1, 0, 0] == pytest.approx(4.0 * q[0, 0, 0])


def test_update_by_hand() -> None:
    # u: variance 4, covariance with du 2, du variance 3; R_u = 1; z_u - u = 5.
    # S = 5, K = [0.8, 0.4]: u = 10 + 4 = 14, du = 1 + 2 = 3;
    # P_uu = 4 - 16/5 = 0.8, P_u,du = 2 - 8/5 = 0.4, P_du,du = 3 - 4/5 = 2.2.
    x, P = one_target()
    P = P.copy()
    P[0, 0, 3] = P[0, 3, 0] = 2.0
    P[0, 3, 3] = 3.0
    z = np.array([[15.0, 20.0, 1.0]])
    R = np.diag([1.0, 1.0, 0.01])[None]
    xu, Pu = update(x, P, z, R)
    assert xu[0, 0] == pytest.approx(14.0)
    assert xu[0, 3] == pytest.approx(3.0)
    assert xu[0, 1] == pytest.approx(20.0) and xu[0, 2] == pytest.approx(1.0)
    assert Pu[0, 0, 0] == pytest.approx(0.8)
    assert Pu[0, 0, 3] == pytest.approx(0.4)
    assert Pu[0, 3, 3] == pytest.approx(2.2)
    assert Pu[0, 1, 1] == pytest.approx(4.0 - 16.0 / 5.0)
    assert Pu[0, 2, 2] == pytest.approx(0.01 - 0.0001 / 0.02)
    np.testing.assert_allclose(update_covariance(P, R), Pu)


def test_stacks_equal_one_by_one() -> None:
    rng = np.random.default_rng(0)
    K = 5
    x = rng.normal(size=(K, 6)) + [100, 100, 2, 0, 0, 0]
    A = rng.normal(size=(K, 6, 6))
    P = A @ np.swapaxes(A, 1, 2) + np.eye(6)
    z = x[:, :3] + rng.normal(size=(K, 3))
    R = np.broadcast_to(np.diag([2.0, 3.0, 0.1]), (K, 3, 3)).copy()
    motion = MotionModel()
    xs, Ps = predict(x, P, motion)
    xu, Pu = update(xs, Ps, z, R)
    for k in range(K):
        xk, Pk = predict(x[k:k + 1], P[k:k + 1], motion)
        xk, Pk = update(xk, Pk, z[k:k + 1], R[k:k + 1])
        np.testing.assert_allclose(xu[k], xk[0])
        np.testing.assert_allclose(Pu[k], Pk[0], atol=1e-12)


def test_mahalanobis_by_hand() -> None:
    x = np.array([[0.0, 0.0, 1.0, 0, 0, 0], [100.0, 0.0, 1.0, 0, 0, 0]])
    P = np.zeros((2, 6, 6))
    P[:, :3, :3] = np.diag([5.0, 12.0, 0.5])
    z = np.array([[3.0, 4.0, 1.0]])
    R = np.diag([4.0, 4.0, 0.5])[None]
    d2 = mahalanobis_sq(x, P, z, R)
    assert d2.shape == (2, 1)
    assert d2[0, 0] == pytest.approx(9 / 9 + 16 / 16)
    assert d2[1, 0] == pytest.approx(97 ** 2 / 9 + 16 / 16)


def test_association_gates_and_matches_one_to_one() -> None:
    x = np.array([[0.0, 0.0, 1.0, 0, 0, 0], [50.0, 0.0, 1.0, 0, 0, 0]])
    P = np.zeros((2, 6, 6))
    P[:, :3, :3] = np.diag([4.0, 4.0, 0.01])
    z = np.array([[49.0, 1.0, 1.0], [1.0, -1.0, 1.0], [300.0, 0.0, 1.0]])
    R = np.broadcast_to(np.diag([4.0, 4.0, 0.01]), (3, 3, 3))
    a = associate(x, P, z, R, gate_threshold(0.99))
    assert sorted(map(tuple, a.matches.tolist())) == [(0, 1), (1, 0)]
    assert a.unmatched_detections.tolist() == [2]
    assert a.unmatched_tracks.size == 0
    empty = associate(x[:0], P[:0], z, R, 11.0)
    assert empty.matches.shape == (0, 2) and empty.unmatched_detections.tolist() == [0, 1, 2]
    with pytest.raises(ValueError, match='gate probability'):
        gate_threshold(1.5)


def test_logdet_is_of_the_position_scale_block() -> None:
    P = np.diag([2.0, 3.0, 0.5, 100.0, 100.0, 100.0])[None]
    assert logdet_sigma(P)[0] == pytest.approx(np.log(3.0))


def test_bad_motion_model() -> None:
    with pytest.raises(ValueError, match='MotionModel'):
        MotionModel(accel_std=-1.0)
