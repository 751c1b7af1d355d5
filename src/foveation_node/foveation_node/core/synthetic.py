"""Seeded synthetic test images for the foveation analyses, tests and benchmarks.

- `white_noise`: a flat spectrum, the thesis's assumption in Eqs. 2.9-2.11.
- `pink_noise`: amplitude spectrum 1/f^beta (beta = 1: the average spectrum of natural images),
  a stand-in for camera images with the same second-order statistics.
"""

from __future__ import annotations

import numpy as np

from vizzy_vision.image_checks import check_size


def white_noise(width: int, height: int, channels: int = 3, std: float = 40.0,
                mean: float = 128.0, seed: int = 0) -> np.ndarray:
    """Gaussian white noise, float64, (H, W) if channels == 1 else (H, W, C); not clipped."""
    width, height = check_size(width, height)
    rng = np.random.default_rng(seed)
    shape = (height, width) if channels == 1 else (height, width, channels)
    return mean + std * rng.standard_normal(shape)


def pink_noise(width: int, height: int, channels: int = 3, beta: float = 1.0,
               std: float = 40.0, mean: float = 128.0, seed: int = 0) -> np.ndarray:
    """Noise with amplitude spectrum 1/f^beta, scaled to the given mean and std, float64."""
    width, height = check_size(width, height)
    rng = np.random.default_rng(seed)
    fy = np.fft.fftfreq(height)[:, None]
    fx = np.fft.rfftfreq(width)[None, :]
    f = np.hypot(fx, fy)
    f[0, 0] = 1.0
    planes = []
    for _ in range(channels):
        spectrum = (rng.standard_normal(f.shape) + 1j * rng.standard_normal(f.shape)) / f ** beta
        spectrum[0, 0] = 0.0
        plane = np.fft.irfft2(spectrum, s=(height, width))
        planes.append(mean + std * plane / plane.std())
    return planes[0] if channels == 1 else np.stack(planes, axis=-1)


def to_uint8(image: np.ndarray) -> np.ndarray:
    """Round and clip to 0..255."""
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)
