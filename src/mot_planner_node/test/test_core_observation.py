"""Observation-model constants (Eqs. 5.8-5.15) for known detector configurations."""

import math

import numpy as np
import pytest

from mot_planner_node.core.detector import HogDetector
from mot_planner_node.core.observation import DetectorGeometry, ObservationModel


def test_hog_constants_come_from_the_descriptor() -> None:
    g = HogDetector().geometry
    assert (g.window_w, g.window_h, g.stride, g.scale_step, g.min_scale) == (64, 128, 8, 1.05, 1)
    assert g.scales_per_octave == pytest.approx(math.log(2) / math.log(1.05))   # 14.21
    g2 = HogDetector(win_stride=16, scale=1.1).geometry
    assert (g2.stride, g2.scale_step) == (16, 1.1)
    with pytest.raises(ValueError, match='multiple of the block stride'):
        HogDetector(win_stride=6)
    with pytest.raises(ValueError, match='scale'):
        HogDetector(scale=1.0)


def test_hog_noise_by_hand() -> None:
    obs = ObservationModel(HogDetector().geometry)
    # s = 1: Q_sl = 8 (Eq. 5.8); Q_scx = 64 * 0.05 / 2 = 1.6, Q_scy = 3.2 (Eqs. 5.10-5.11);
    # max (Eq. 5.15): 8 and 8; scale: one step, 0.05.
    np.testing.assert_allclose(obs.std(1.0), [8.0, 8.0, 0.05])
    np.testing.assert_allclose(obs.std(2.0), [16.0, 16.0, 0.10])
    np.testing.assert_allclose(obs.covariance(2.0), np.diag([256.0, 256.0, 0.01]))
    assert obs.scale_level(1.05 ** 3) == pytest.approx(3.0)


def test_thesis_configuration_eqs_5_8_to_5_15() -> None:
    # The thesis's detector: N = 8 scales per octave, smallest window 52x128, stride 4 px.
    g = DetectorGeometry(window_w=52, window_h=128, stride=4, scale_step=2 ** (1 / 8))
    assert g.scales_per_octave == pytest.approx(8.0)
    obs = ObservationModel(g)
    n = np.arange(0, 17)
    s = 2.0 ** (n / 8)                                                  # Eq. 5.9
    np.testing.assert_allclose(obs.scale_level(s), n, atol=1e-12)
    np.testing.assert_allclose(obs.sliding_window_jump(s), s * 4)       # Eq. 5.8
    q_scx, q_scy = obs.scale_jumps(s)
    np.testing.assert_allclose(q_scx, 52 * (2 ** ((n + 1) / 8) - 2 ** (n / 8)) / 2)   # Eq. 5.10
    np.testing.assert_allclose(q_scy, 128 * (2 ** ((n + 1) / 8) - 2 ** (n / 8)) / 2)  # Eq. 5.11
    sd = obs.std(s)
    # Eq. 5.15: horizontally the stride wins (4 s > 2.35 s), vertically the scale jump
    # (5.79 s > 4 s).
    np.testing.assert_allclose(sd[:, 0], s * 4)
    np.testing.assert_allclose(sd[:, 1], q_scy)
    np.testing.assert_allclose(sd[:, 2], s * (2 ** (1 / 8) - 1))


def test_uniform_quantization_and_extra_noise() -> None:
    g = DetectorGeometry()
    worst, uniform = ObservationModel(g), ObservationModel(g, quantization='uniform')
    np.testing.assert_allclose(uniform.std(1.5), worst.std(1.5) / np.sqrt(12))
    extra = ObservationModel(g, extra_std=(0.1, 0.0, 0.0))
    assert extra.std(1.0)[0] == pytest.approx(np.hypot(8.0, 6.4))
    with pytest.raises(ValueError, match='quantization'):
        ObservationModel(g, quantization='other')
    with pytest.raises(ValueError, match='extra_std'):
        ObservationModel(g, extra_std=(-1.0, 0.0, 0.0))


def test_expected_covariance_over_a_region_eq_5_22() -> None:
    obs = ObservationModel(DetectorGeometry())
    # No scale spread: the covariance at the mean scale.
    np.testing.assert_allclose(obs.expected_covariance(2.0, 0.0, 1.0), obs.covariance(2.0))
    np.testing.assert_allclose(obs.expected_covariance(2.0, 0.5, 0.0), obs.covariance(2.0))
    # Symmetric spread of a convex function of s: a little above the value at the mean.
    r = obs.expected_covariance(np.array([2.0, 3.0]), np.array([0.2, 0.2]), 1.0)
    assert r.shape == (2, 3, 3)
    assert r[0, 0, 0] > obs.covariance(2.0)[0, 0] and r[0, 0, 0] < obs.covariance(2.2)[0, 0]
    # Scales below the smallest window are clamped to it.
    low = obs.expected_covariance(1.0, 5.0, 1.0)
    assert np.all(np.isfinite(low)) and low[0, 0] >= obs.covariance(1.0)[0, 0]


def test_bad_geometry() -> None:
    with pytest.raises(ValueError, match='scale_step'):
        DetectorGeometry(scale_step=1.0)
    with pytest.raises(ValueError, match='stride'):
        DetectorGeometry(stride=0)
