"""Foveation core (thesis section 2.3.1): the pyramid implementation against the direct one,
the fovea/periphery behaviour, the scale space it realises, and bad input."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from foveation_node.core.foveation import (
    PYRAMID_SIGMA_1,
    Foveator,
    fovea_kernel,
    fovea_sigmas,
    foveate,
    foveate_reference,
    gaussian_sigmas,
)
from foveation_node.core.synthetic import pink_noise, to_uint8

W, H = 320, 240
LEVELS = 5

# Stated tolerance of the pyramid implementation against the full-resolution reference, on 8-bit
# 1/f (natural-image-like) images, any fixation, sigma_1 in {sqrt(8/3), 2.5}, K = 5:
#   whole image: RMS <= 2.5 gray levels and <= 7 % of the foveation's own RMS change;
#   f_0 >= 25 px: RMS <= 1.5 gray levels and <= 5 % of the change;
#   farther than 2^K px from the border: RMS <= 1.2 gray levels.
# (Measured worst cases on 320x240 and 640x480: 2.06 / 5.9 %, 1.32 / 4.3 %, 1.06.) The output's
# own rounding to uint8 is 0.29 RMS; the rest is the binomial (not Gaussian) pyramid filters,
# aliasing of the subsampled levels, and mirrored borders applied at each level's resolution.
TOL_RMS, TOL_REL = 2.5, 0.07
TOL_RMS_WIDE, TOL_REL_WIDE = 1.5, 0.05
TOL_RMS_INTERIOR = 1.2


@pytest.fixture(scope='module')
def image() -> np.ndarray:
    return to_uint8(pink_noise(W, H, seed=3))


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(a, dtype=np.float64))))


@pytest.mark.parametrize('f0, fixation, sigma_1', [
    (2.0, (160, 120), PYRAMID_SIGMA_1),
    (10.0, (40, 235), PYRAMID_SIGMA_1),
    (25.0, (0, 0), PYRAMID_SIGMA_1),
    (50.0, (319, 17), 2.5),
    (100.0, (160.5, 120.25), PYRAMID_SIGMA_1),
    (100.0, (300, 200), 2.5),
])
def test_pyramid_matches_reference(image: np.ndarray, f0: float, fixation: tuple[float, float],
                                   sigma_1: float) -> None:
    reference = foveate_reference(image, fixation, f0, sigma_1, LEVELS)
    fast = Foveator(W, H, LEVELS, f0, sigma_1).foveate(image, fixation)
    assert fast.dtype == np.uint8 and fast.shape == image.shape
    diff = fast.astype(np.float64) - reference
    change = _rms(reference - image)
    rms_all = _rms(diff)
    assert rms_all <= TOL_RMS and rms_all <= TOL_REL * change
    if f0 >= 25:
        assert rms_all <= TOL_RMS_WIDE and rms_all <= TOL_REL_WIDE * change
    margin = 2 ** LEVELS
    assert _rms(diff[margin:-margin, margin:-margin]) <= TOL_RMS_INTERIOR


def test_pyramid_realises_the_scale_space_of_eq_2_1() -> None:
    """The level-k image brought back to full resolution has variance sigma_k^2 (Eq. 2.1)."""
    size = 257
    impulse = np.zeros((size, size), np.float32)
    impulse[128, 128] = 1.0
    for sigma_1 in (PYRAMID_SIGMA_1, 2.5):
        foveator = Foveator(size, size, LEVELS, 50.0, sigma_1)
        pyramid = foveator.gaussian_pyramid(impulse)
        sigmas = gaussian_sigmas(sigma_1, LEVELS)
        yy, xx = np.mgrid[0:size, 0:size]
        for k in range(1, LEVELS):
            level = pyramid[k]
            for j in range(k - 1, -1, -1):
                level = cv2.pyrUp(level, dstsize=foveator.level_sizes[j])
            mass = level.sum()
            variance = (level * ((xx - 128) ** 2 + (yy - 128) ** 2)).sum() / mass / 2.0
            assert mass == pytest.approx(1.0, abs=1e-3)
            assert variance == pytest.approx(sigmas[k] ** 2, rel=0.02), (sigma_1, k)


def test_fovea_keeps_pixels_and_periphery_loses_high_frequencies(image: np.ndarray) -> None:
    fixation = (80, 60)
    out = Foveator(W, H, LEVELS, 30.0).foveate(image, fixation)
    # at the fixation every H_k = 1, so F = I (to the output's rounding)
    u0, v0 = fixation
    disc = np.s_[v0 - 2:v0 + 3, u0 - 2:u0 + 3]
    near = np.abs(out[disc].astype(int) - image[disc])
    assert near.max() <= 1

    def high_power(patch: np.ndarray) -> float:
        """Power above 1/8 cycles/px in a Hann-windowed 48x48 patch (grey)."""
        grey = patch.astype(np.float64).mean(axis=2)
        grey = (grey - grey.mean()) * np.outer(np.hanning(48), np.hanning(48))
        spectrum = np.abs(np.fft.fft2(grey)) ** 2
        f = np.hypot(*np.meshgrid(np.fft.fftfreq(48), np.fft.fftfreq(48)))
        return float(spectrum[f > 0.125].sum())

    def ratio(u: int, v: int) -> float:
        window = np.s_[v - 24:v + 24, u - 24:u + 24]
        return high_power(out[window]) / high_power(image[window])

    assert ratio(80, 60) > 0.9      # the fovea keeps its fine detail
    assert ratio(270, 200) < 0.02   # 3.7 f_0 away: only the coarse levels remain


def test_huge_fovea_is_the_identity_and_tiny_fovea_the_coarsest_level(image: np.ndarray) -> None:
    fovea = Foveator(W, H, LEVELS, 1e6).foveate(image, (10, 10))
    assert np.abs(fovea.astype(int) - image).max() <= 1
    tiny = Foveator(W, H, LEVELS, 1.0)
    far = np.s_[100:200, 150:280]  # far from the fixation, >= 2^K px from the border
    coarsest = foveate_reference(image, (5, 5), 1.0, PYRAMID_SIGMA_1, LEVELS)
    assert _rms(tiny.foveate(image, (5, 5))[far] - coarsest[far]) <= TOL_RMS_INTERIOR
    assert _rms(image[far] - coarsest[far]) > 10


def test_kernels_follow_eq_2_3() -> None:
    foveator = Foveator(W, H, LEVELS, 20.0)
    kernels = foveator.kernels((64, 32))
    for k, kernel in enumerate(kernels):
        w, h = foveator.level_sizes[k]
        assert kernel.shape == (h, w)
        # level-k pixel j sits at full-resolution coordinate 2^k j
        expected = fovea_kernel(W, H, (64, 32), 20.0 * 2 ** k)[::2 ** k, ::2 ** k]
        assert np.allclose(kernel, expected[:h, :w], atol=1e-6)
    assert kernels[0][32, 64] == pytest.approx(1.0)
    assert np.allclose(fovea_sigmas(20.0, 3), [20.0, 40.0, 80.0])
    assert np.allclose(gaussian_sigmas(1.0, 3), [0.0, 1.0, 2.0, 4.0])


@pytest.mark.parametrize('dtype', [np.uint8, np.uint16, np.float32, np.float64])
@pytest.mark.parametrize('shape', [(H, W), (H, W, 1), (H, W, 3), (H, W, 4)])
def test_shapes_and_dtypes_are_kept(dtype: type, shape: tuple[int, ...]) -> None:
    grey = pink_noise(W, H, channels=1, seed=1)
    data = np.clip(np.broadcast_to(grey.reshape(H, W, 1), (H, W, 4)), 0, 255)[..., :shape[2]] \
        if len(shape) == 3 else np.clip(grey, 0, 255)
    image = data.reshape(shape).astype(dtype)
    out = foveate(image, (100, 100), f0=40.0)
    assert out.shape == image.shape and out.dtype == image.dtype
    reference = foveate_reference(image, (100, 100), 40.0)
    assert _rms(out.astype(np.float64) - reference) < TOL_RMS


def test_out_argument_is_filled(image: np.ndarray) -> None:
    foveator = Foveator(W, H)
    out = np.empty_like(image)
    assert foveator.foveate(image, (50, 50), out=out) is out
    assert np.array_equal(out, foveator.foveate(image, (50, 50)))


@pytest.mark.parametrize('dtype, channels', [(np.uint8, 3), (np.uint8, 1), (np.float32, 3),
                                             (np.uint16, 0)])
def test_foveate_many_gives_foveate_s_images_exactly(dtype: type, channels: int) -> None:
    grey = np.clip(pink_noise(W, H, channels=1, seed=3), 0, 255).reshape(H, W)
    image = (grey if channels == 0 else np.repeat(grey[..., None], channels, axis=2)) \
        .astype(dtype)
    foveator = Foveator(W, H)
    fixations = [(50, 50), (W - 1, 0), (120.5, 77.25), (0.0, H - 1.0)]
    many = foveator.foveate_many(image, fixations)
    assert len(many) == len(fixations)
    for fixation, out in zip(fixations, many, strict=True):
        assert out.shape == image.shape and out.dtype == image.dtype
        assert np.array_equal(out, foveator.foveate(image, fixation)), fixation
    assert foveator.foveate_many(image, []) == []
    with pytest.raises(ValueError, match='outside'):
        foveator.foveate_many(image, [(50, 50), (W + 5, 0)])


@pytest.mark.parametrize('width, height, dtype, channels', [
    (W, H, np.uint8, 3), (161, 97, np.uint8, 3), (161, 97, np.float32, 1), (97, 161, np.uint16, 0),
    (333, 250, np.uint8, 4)])
def test_foveate_many_regions_are_foveate_s_pixels_exactly_and_zero_elsewhere(
        width: int, height: int, dtype: type, channels: int) -> None:
    # a window model reads only the window around each pass-2 fixation: foveate only that
    rng = np.random.default_rng(5)
    shape = (height, width) if channels == 0 else (height, width, channels)
    image: np.ndarray = (rng.random(shape) * 250).astype(dtype)
    foveator = Foveator(width, height)
    fixations = [(10.0, 12.0), (width - 1.0, height - 1.0), (width / 2 + 0.25, height / 3),
                 (0.0, height - 1.0), (width / 3, 5.5)]
    regions = [(-70, -68, 90, 92), (width - 60, height - 50, width + 100, height + 110),
               (width // 2 - 40, height // 3 - 41, width // 2 + 41, height // 3 + 40),
               (-3, -3, width + 3, height + 3), (width + 5, 0, width + 50, 40)]  # last: outside
    many = foveator.foveate_many(image, fixations, regions)
    for fixation, (x0, y0, x1, y1), out in zip(fixations, regions, many, strict=True):
        assert out.shape == image.shape and out.dtype == image.dtype
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, width), min(y1, height)
        full = foveator.foveate(image, fixation)
        inside = np.zeros(shape[:2], bool)
        inside[y0:y1, x0:x1] = True
        assert np.array_equal(out[inside], full[inside]), fixation
        assert not out[~inside].any()
    with pytest.raises(ValueError, match='regions'):
        foveator.foveate_many(image, fixations, regions[:2])


def test_a_moving_fixation_gets_its_own_kernels() -> None:
    # foveate keeps the last fixation's kernels H_k; foveate_many writes the same buffers
    image: np.ndarray = np.clip(pink_noise(W, H, channels=3, seed=4), 0, 255).astype(np.uint8)
    foveator = Foveator(W, H)
    a, b = (40.5, 30.0), (W - 20.0, H - 10.0)
    first = foveator.foveate(image, a).copy()
    assert np.array_equal(foveator.foveate(image, b), Foveator(W, H).foveate(image, b))
    assert np.array_equal(foveator.foveate(image, a), first)
    foveator.foveate_many(image, [b])
    assert np.array_equal(foveator.foveate(image, a), first)


def test_a_window_model_s_pass_2_keeps_the_frame_s_kernels(monkeypatch: pytest.MonkeyPatch) -> None:
    # foveate_many with regions builds no H_k grids: the next frame's foveate reuses its own
    image: np.ndarray = np.clip(pink_noise(W, H, channels=3, seed=6), 0, 255).astype(np.uint8)
    foveator = Foveator(W, H)
    fixation = (W / 2, H / 2)
    first = foveator.foveate(image, fixation).copy()
    built: list[tuple[float, float]] = []
    kernels = foveator._kernels
    monkeypatch.setattr(foveator, '_kernels', lambda buf, channels, u0, v0: (
        built.append((u0, v0)), kernels(buf, channels, u0, v0))[1])
    foveator.foveate_many(image, [(40.0, 30.0), (W - 20.0, H - 10.0)],
                          [(0, 0, 80, 60), (W - 60, H - 50, W, H)])
    assert np.array_equal(foveator.foveate(image, fixation), first)
    assert built == []


@pytest.mark.parametrize('bad, message', [
    (np.zeros((0, 10, 3), np.uint8), 'empty'),
    (np.zeros((H, W, 3), np.int32), 'dtype'),
    (np.zeros((H, W, 3), bool), 'dtype'),
    (np.zeros((H, W, 2), np.uint8), 'channels'),
    (np.zeros((H, W, 5), np.uint8), 'channels'),
    (np.zeros((2, H, W, 3), np.uint8), 'shape'),
    ([[1, 2], [3, 4]], 'numpy array'),
    (np.zeros((H, W + 2, 3), np.uint8), 'Foveator is for'),
])
def test_bad_images_raise_value_error(bad: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Foveator(W, H).foveate(bad, (10, 10))  # type: ignore[arg-type]
    if 'Foveator' not in message:  # any size is fine for the reference
        with pytest.raises(ValueError, match=message):
            foveate_reference(bad, (10, 10))  # type: ignore[arg-type]


@pytest.mark.parametrize('fixation', [(-1, 10), (10, H), (W - 0.5, 0), (float('nan'), 3), (1, 2, 3),
                                      'centre', None])
def test_bad_fixations_raise_value_error(image: np.ndarray, fixation: object) -> None:
    with pytest.raises(ValueError, match='fixation'):
        Foveator(W, H).foveate(image, fixation)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match='fixation'):
        foveate_reference(image, fixation)  # type: ignore[arg-type]


def test_bad_parameters_raise_value_error(image: np.ndarray) -> None:
    with pytest.raises(ValueError, match='sigma_1'):
        Foveator(W, H, sigma_1=1.0)            # below what a subsampled pyramid realises
    with pytest.raises(ValueError, match='f0'):
        Foveator(W, H, f0=0.0)
    with pytest.raises(ValueError, match='f0'):
        Foveator(W, H, f0=float('inf'))
    with pytest.raises(ValueError, match='levels'):
        Foveator(W, H, levels=0)
    with pytest.raises(ValueError, match='levels'):
        Foveator(20, 20, levels=5)              # the coarsest level would be under 1 px
    with pytest.raises(ValueError, match='width'):
        Foveator(0, H)
    with pytest.raises(ValueError, match='out'):
        Foveator(W, H).foveate(image, (5, 5), out=np.empty((H, W), np.uint8))
