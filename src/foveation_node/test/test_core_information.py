"""Information analysis of the fovea (thesis Eqs. 2.5-2.18): formulas, measurement, Fig. 2.6."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from foveation_node.core.information import (
    information_bits,
    kernel_mean_square,
    laplacian_energy_fractions,
    measured_information,
    predicted_information,
)
from foveation_node.core.synthetic import pink_noise, white_noise

N = 227  # the thesis's Fig. 2.6: 227x227, sigma_1 = 1


def test_eq_2_11_closed_form_matches_the_integral_of_eq_2_8() -> None:
    fractions, residual = laplacian_energy_fractions(1.0, 4)
    sigmas = [0.0, 1.0, 2.0, 4.0, 8.0]
    for k, expected in enumerate(fractions):
        def band(wv: float, wu: float, k: int = k) -> float:
            g = [np.exp(-s ** 2 / 2 * (wu ** 2 + wv ** 2)) for s in (sigmas[k], sigmas[k + 1])]
            return (g[0] - g[1]) ** 2
        value, _ = integrate.dblquad(band, -np.pi, np.pi, -np.pi, np.pi, epsabs=1e-10)
        assert value / (4 * np.pi ** 2) == pytest.approx(expected, rel=1e-6)
    value, _ = integrate.dblquad(lambda wv, wu: np.exp(-64.0 * (wu ** 2 + wv ** 2)),
                                 -np.pi, np.pi, -np.pi, np.pi)
    assert value / (4 * np.pi ** 2) == pytest.approx(residual, rel=1e-6)


def test_information_grows_monotonically_with_the_fovea() -> None:
    for size in (64, N, 640):
        f0 = np.geomspace(0.1, 2 * size, 60)
        info = [predicted_information(size, size, f, 1.0, 5) for f in f0]
        energy = np.array([i.energy_ratio for i in info])
        bits = np.array([i.information_ratio for i in info])
        assert np.all(np.diff(energy) > 0) and np.all(np.diff(bits) > 0)
        assert 0 < energy[0] < 0.01 and energy[-1] > 0.9
        assert bits[-1] > 0.98 and np.all(bits <= 1.0)


def test_fig_2_6_information_ratio_at_f0_100() -> None:
    """The thesis: information ratio about 94 % at f_0 = 100 (227x227, sigma_1 = 1)."""
    info = predicted_information(N, N, 100.0, 1.0, 5)
    assert info.information_ratio == pytest.approx(0.94, abs=0.01)
    assert info.energy_ratio == pytest.approx(0.5, abs=0.03)   # "roughly half of the energy"


def test_ratios_depend_on_f0_over_image_size() -> None:
    small = predicted_information(100, 100, 30.0, 1.0, 5)
    large = predicted_information(400, 400, 120.0, 1.0, 5)
    assert small.energy_ratio == pytest.approx(large.energy_ratio, abs=0.01)


def test_measured_on_white_noise_matches_the_formulas() -> None:
    """A flat spectrum is the formulas' assumption, so measurement and prediction agree."""
    image = white_noise(N, N, channels=1, std=255.0, mean=0.0, seed=7)
    centre = ((N - 1) / 2, (N - 1) / 2)
    for f0 in (10.0, 50.0, 100.0, 200.0):
        predicted = predicted_information(N, N, f0, 1.0, 5)
        measured = measured_information(image, centre, f0, 1.0, 5)
        assert measured.energy_ratio == pytest.approx(predicted.energy_ratio, abs=0.02)
        assert measured.information_ratio == pytest.approx(predicted.information_ratio, abs=0.01)
        # Eq. 2.11 per level; the coarse levels hold few independent samples in 227x227
        assert np.allclose(measured.level_power[:3], predicted.level_power[:3], rtol=0.05)
        assert np.allclose(measured.level_power[3:], predicted.level_power[3:], rtol=0.25)


def test_measured_information_is_monotonic_on_natural_like_images() -> None:
    image = pink_noise(N, N, channels=3, seed=2)
    ratios = [measured_information(image, (60, 150), f0, 1.0, 5).information_ratio
              for f0 in (1.0, 5.0, 20.0, 60.0, 150.0)]
    assert np.all(np.diff(ratios) > 0)


def test_helpers_and_bad_input() -> None:
    assert information_bits(0.0) == 0.0
    assert information_bits(1.0) == pytest.approx(1.0)             # 1/2 log2(1 + 3)
    kept = kernel_mean_square(N, N, (113, 113), 1e6, 3)
    assert np.allclose(kept, 1.0)
    with pytest.raises(ValueError, match='pixel_power'):
        predicted_information(N, N, 10.0, pixel_power=0.0)
    with pytest.raises(ValueError, match='fixation'):
        predicted_information(N, N, 10.0, fixation=(N, 0))
    with pytest.raises(ValueError, match='f0'):
        predicted_information(N, N, -1.0)
    with pytest.raises(ValueError, match='empty'):
        measured_information(np.zeros((0, 5)), (0, 0), 10.0)
