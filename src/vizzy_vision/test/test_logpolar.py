"""Log-polar retina (thesis Eq. 1.1, Gaussian RFs of section 3.3.2): geometry, maps, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from foveation_node.core.synthetic import pink_noise
from vizzy_vision.logpolar import LogPolarRetina

W, H = 320, 240


@pytest.fixture(scope='module')
def retina() -> LogPolarRetina:
    return LogPolarRetina(W, H, rings=100, wedges=100)


def _smooth(channels: int = 3) -> np.ndarray:
    yy, xx = np.mgrid[0:H, 0:W]
    base = 128 + 60 * np.sin(xx / 40.0) * np.cos(yy / 55.0)
    return np.stack([base, 255 - base, 0.5 * base][:channels], axis=-1).astype(np.float32)


def test_geometry_grows_with_eccentricity(retina: LogPolarRetina) -> None:
    radii = retina.ring_radii
    assert radii[0] == pytest.approx(retina.rho_min)
    assert np.allclose(radii[1:] / radii[:-1], retina.growth)
    assert radii[-1] * retina.growth == pytest.approx(retina.rho_max)
    sigmas = retina.rf_sigmas
    assert np.all(np.diff(sigmas) >= 0) and sigmas[-1] > 10 * sigmas[0]
    beyond_floor = sigmas > retina.sigma_min
    assert beyond_floor.sum() > retina.rings // 4 and np.all(np.diff(sigmas[beyond_floor]) > 0)
    centres = retina.rf_centers
    assert centres.shape == (retina.wedges, retina.rings, 2)
    distance = np.hypot(centres[..., 0] - retina.center[0], centres[..., 1] - retina.center[1])
    assert np.allclose(distance, radii[None, :])
    # the whole image is covered by default, and most RFs see it
    assert retina.retina_mask.all() and retina.rf_valid.mean() > 0.9


def test_cortical_coordinates_invert(retina: LogPolarRetina) -> None:
    ring = np.array([0.0, 3.5, 50.25, 99.0])
    wedge = np.array([0.0, 10.5, 73.0, 99.75])
    x, y = retina.retina_coordinates(ring, wedge)
    back_ring, back_wedge = retina.cortex_coordinates(x, y)
    assert np.allclose(back_ring, ring) and np.allclose(back_wedge, wedge)


def test_receptive_fields_average(retina: LogPolarRetina) -> None:
    constant = np.full((H, W, 3), 77.0, np.float32)
    cortex = retina.to_cortex(constant)
    assert cortex.shape == (retina.wedges, retina.rings, 3)
    assert np.allclose(cortex[retina.rf_valid], 77.0, atol=1e-3)
    assert np.all(cortex[~retina.rf_valid] == 0)
    # a symmetric RF reads a linear ramp at its centre (away from the borders)
    ramp = np.tile(np.arange(W, dtype=np.float32), (H, 1))
    response = retina.to_cortex(ramp)
    inner = (retina.ring_radii < 100)[None, :] & retina.rf_valid
    assert np.allclose(response[inner], retina.rf_centers[..., 0][inner], atol=0.05)


def test_multiscale_forward_matches_exact_gaussian_rfs(retina: LogPolarRetina) -> None:
    exact = LogPolarRetina(W, H, rings=100, wedges=100, max_level=0)
    assert retina.ring_levels.max() >= 1 and exact.ring_levels.max() == 0
    image = pink_noise(W, H, channels=1, seed=4).astype(np.float32)
    both = retina.rf_valid & exact.rf_valid
    diff = (retina.to_cortex(image) - exact.to_cortex(image))[both]
    assert np.sqrt(np.mean(diff ** 2)) < 0.5 and np.abs(diff).max() < 8


def test_round_trip_of_a_smooth_image(retina: LogPolarRetina) -> None:
    image = _smooth()
    back = retina.to_retina(retina.to_cortex(image))
    assert back.shape == image.shape
    err = np.abs(back - image)
    yy, xx = np.mgrid[0:H, 0:W]
    r = np.hypot(xx - retina.center[0], yy - retina.center[1])
    assert np.sqrt(np.mean(err ** 2)) < 0.02 * 120                  # 2 % of the range
    assert err[r < min(W, H) / 2 - 5].max() < 0.02 * 120            # inscribed disc


def test_point_sampling_and_grey_images(retina: LogPolarRetina) -> None:
    xs = np.tile(np.arange(W, dtype=np.float32), (H, 1))
    samples = retina.sample(xs)
    assert samples.shape == retina.cortex_shape
    x, y = retina.rf_centers[..., 0], retina.rf_centers[..., 1]
    inside = (x >= 0) & (x <= W - 1) & (y >= 0) & (y <= H - 1)
    assert np.allclose(samples[inside], retina.rf_centers[..., 0][inside], atol=1 / 16)
    grey = _smooth(1)[..., 0].astype(np.uint8)
    assert retina.to_cortex(grey).shape == retina.cortex_shape
    assert retina.to_retina(retina.to_cortex(grey)).shape == (H, W)


def test_off_centre_retina() -> None:
    retina = LogPolarRetina(W, H, rings=60, wedges=64, rho_min=2.0, center=(40.0, 200.0))
    assert retina.retina_mask.all()
    assert retina.rf_centers[0, 0, 0] == pytest.approx(42.0)
    back = retina.to_retina(retina.to_cortex(_smooth()))
    assert np.sqrt(np.mean((back - _smooth()) ** 2)) < 0.03 * 120


def test_bad_input_raises_value_error(retina: LogPolarRetina) -> None:
    with pytest.raises(ValueError, match='retina is for'):
        retina.to_cortex(np.zeros((H + 1, W, 3), np.uint8))
    with pytest.raises(ValueError, match='empty'):
        retina.to_cortex(np.zeros((0, W, 3), np.uint8))
    with pytest.raises(ValueError, match='dtype'):
        retina.to_cortex(np.zeros((H, W, 3), np.int64))
    with pytest.raises(ValueError, match='channels'):
        retina.sample(np.zeros((H, W, 2), np.uint8))
    with pytest.raises(ValueError, match='cortex'):
        retina.to_retina(np.zeros((5, 5)))
    with pytest.raises(ValueError, match='cortex'):
        retina.to_retina(np.zeros(retina.cortex_shape, np.int32))
    with pytest.raises(ValueError, match='rho_max'):
        LogPolarRetina(W, H, rho_min=50.0, rho_max=10.0)
    with pytest.raises(ValueError, match='center'):
        LogPolarRetina(W, H, center=(W + 5.0, 0.0))
    with pytest.raises(ValueError, match='rings'):
        LogPolarRetina(W, H, rings=0)
    with pytest.raises(ValueError, match='max_level'):
        LogPolarRetina(W, H, max_level=-1)
