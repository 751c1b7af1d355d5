"""Energy and information of a foveated image, thesis section 2.3.1 (Eqs. 2.5-2.18).

From the formulas: an image whose spectrum is flat with magnitude M (the thesis's assumption),
so its per-pixel power is P = M^2 / N^2 (gray levels^2). Its Laplacian level k carries energy
E_L_k (Eq. 2.11), spread evenly over the pixels (P_L_k, Eq. 2.12); the fovea kernels scale it by
sum H_k^2 (Eq. 2.14); the levels are summed as if uncorrelated (Eq. 2.15) into the power P_F
(Eq. 2.16), whose information is Z_F = 1/2 log2(1 + 3 P_F) bits per pixel (Eqs. 2.17-2.18: half a
cycle per pixel, quantisation noise power 1/3).

Measured: the same quantities from an actual image's full-resolution decomposition
(`foveation.laplacian_levels_reference`), after removing its mean.

Our foveated image also keeps the coarsest Gaussian level G_K (weight 1, see `foveation`); its
energy E_G_K is included in E_F (it is tiny: 0.03% of M^2 for K = 5, sigma_1 = 1). Ratios are taken
against the unfoveated image analysed the same way (every H_k = 1), so they tend to 1 as f_0 grows;
`Information.energy_ratio_parseval` uses E_I = M^2 (Eq. 2.5) instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import erf

from vizzy_vision.image_checks import (
    check_fixation,
    check_image,
    check_levels,
    check_positive,
    check_size,
)

from .foveation import DEFAULT_LEVELS, fovea_sigmas, gaussian_sigmas, laplacian_levels_reference

#: Power of quantisation noise for 1-level quantisation with truncation (Eq. 2.18).
QUANTISATION_NOISE_POWER = 1.0 / 3.0
#: Default per-pixel signal power: a flat spectrum at the full 8-bit scale.
FULL_SCALE_POWER = 255.0 ** 2


def half_band_integral(sigma: float | np.ndarray) -> np.ndarray:
    """A(sigma) = int_0^pi exp(-sigma^2 t^2) dt = sqrt(pi) erf(pi sigma) / (2 sigma), A(0) = pi.

    The change of variables of Eq. 2.10 that turns Eq. 2.9 into Eq. 2.11.
    """
    s = np.asarray(sigma, dtype=np.float64)
    safe = np.where(s > 1e-12, s, 1.0)
    return np.where(s > 1e-12, math.sqrt(math.pi) * erf(math.pi * safe) / (2.0 * safe), math.pi)


def laplacian_energy_fractions(sigma_1: float, levels: int) -> tuple[np.ndarray, float]:
    """(E_L_k / M^2 for k = 0..K-1 (Eq. 2.11), E_G_K / M^2) for a flat spectrum of magnitude M.

    E_L_k = M^2/pi^2 (A(sigma_k)^2 + A(sigma_(k+1))^2 - 2 A(sqrt((sigma_k^2 + sigma_(k+1)^2)/2))^2).
    """
    s = gaussian_sigmas(sigma_1, levels)
    a_k, a_next = half_band_integral(s[:-1]), half_band_integral(s[1:])
    a_mix = half_band_integral(np.sqrt((s[:-1] ** 2 + s[1:] ** 2) / 2.0))
    e_lap = (a_k ** 2 + a_next ** 2 - 2.0 * a_mix ** 2) / math.pi ** 2
    return e_lap, float(half_band_integral(s[-1]) ** 2 / math.pi ** 2)


def kernel_mean_square(width: int, height: int, fixation: tuple[float, float],
                       f0: float, levels: int) -> np.ndarray:
    """sum_{u,v} H_k(u, v)^2 / (W H) for k = 0..K-1: the fraction of P_L_k kept (Eq. 2.14)."""
    width, height = check_size(width, height)
    u0, v0 = check_fixation(fixation, width, height)
    f_k = fovea_sigmas(f0, levels)[:, None]
    su = np.exp(-((np.arange(width)[None, :] - u0) / f_k) ** 2).sum(axis=1)
    sv = np.exp(-((np.arange(height)[None, :] - v0) / f_k) ** 2).sum(axis=1)
    return su * sv / (width * height)


def information_bits(power: float | np.ndarray) -> np.ndarray:
    """Z = 1/2 log2(1 + P / Q) bits per pixel with Q = 1/3 (Eqs. 2.17-2.18)."""
    return 0.5 * np.log2(1.0 + np.asarray(power, dtype=np.float64) / QUANTISATION_NOISE_POWER)


@dataclass(frozen=True)
class Information:
    """Energy and information of a foveated image against its unfoveated original.

    Energies are per pixel (powers, gray levels^2); `bits_*` are Z (bits per pixel, Eq. 2.18);
    multiply by the pixel count for the image's total.
    """

    level_power: np.ndarray          # P_L_k (Eq. 2.12), k = 0..K-1
    level_power_foveated: np.ndarray  # E_F_k / N^2 (Eq. 2.14)
    residual_power: float            # power of G_K
    power_original: float            # sum_k P_L_k + P_G_K (every H_k = 1)
    power_foveated: float            # P_F (Eqs. 2.15-2.16)
    parseval_power: float            # M^2 / N^2 (Eq. 2.5), or the image's measured power

    @property
    def energy_ratio(self) -> float:
        """E_F / E_I with E_I analysed the same way (uncorrelated levels, every H_k = 1)."""
        return self.power_foveated / self.power_original

    @property
    def energy_ratio_parseval(self) -> float:
        """E_F / E_I with E_I = M^2 from Parseval (Eq. 2.5) or the image's own energy."""
        return self.power_foveated / self.parseval_power

    @property
    def bits_original(self) -> float:
        return float(information_bits(self.power_original))

    @property
    def bits_foveated(self) -> float:
        return float(information_bits(self.power_foveated))

    @property
    def information_ratio(self) -> float:
        """Z_F / Z_I (Eq. 2.18 for both)."""
        return self.bits_foveated / self.bits_original


def _information(level_power: np.ndarray, kept: np.ndarray, residual: float,
                 parseval: float) -> Information:
    foveated = level_power * kept
    return Information(level_power=level_power, level_power_foveated=foveated,
                       residual_power=residual,
                       power_original=float(level_power.sum() + residual),
                       power_foveated=float(foveated.sum() + residual),
                       parseval_power=parseval)


def predicted_information(width: int, height: int, f0: float, sigma_1: float = 1.0,
                          levels: int = DEFAULT_LEVELS, pixel_power: float = FULL_SCALE_POWER,
                          fixation: tuple[float, float] | None = None) -> Information:
    """Eqs. 2.11-2.18 for a flat-spectrum image of per-pixel power `pixel_power` (= M^2 / N^2).

    `fixation` defaults to the image centre (u_0 = v_0 = 0 in the thesis's centred coordinates).
    """
    width, height = check_size(width, height)
    levels = check_levels(levels)
    pixel_power = check_positive('pixel_power', pixel_power)
    if fixation is None:
        fixation = ((width - 1) / 2.0, (height - 1) / 2.0)
    fractions, residual = laplacian_energy_fractions(sigma_1, levels)
    kept = kernel_mean_square(width, height, fixation, f0, levels)
    return _information(fractions * pixel_power, kept, residual * pixel_power, pixel_power)


def measured_information(image: np.ndarray, fixation: tuple[float, float], f0: float,
                         sigma_1: float = 1.0, levels: int = DEFAULT_LEVELS) -> Information:
    """The same quantities measured on an image (mean removed; channels averaged).

    P_L_k = mean(L_k^2) (Eq. 2.12), E_F_k / N^2 = mean((H_k L_k)^2) (Eq. 2.13, measured instead of
    the approximation of Eq. 2.14), residual = mean((G_K - mean)^2); `parseval_power` is the
    image's own power mean((I - mean)^2).
    """
    height, width, _ = check_image(image)
    u0, v0 = check_fixation(fixation, width, height)
    data = image.astype(np.float64)
    data = data - data.mean(axis=(0, 1))
    laplacians, residual = laplacian_levels_reference(data, sigma_1, levels)
    f_k = fovea_sigmas(f0, levels)
    row = np.arange(width)[None, :]
    col = np.arange(height)[:, None]
    level_power, kept_power = [], []
    for lap, f in zip(laplacians, f_k, strict=True):
        h2 = np.exp(-((row - u0) ** 2 + (col - v0) ** 2) / f ** 2)  # H_k^2
        sq = lap ** 2 if lap.ndim == 2 else (lap ** 2).mean(axis=2)
        level_power.append(sq.mean())
        kept_power.append((sq * h2).mean())
    lp = np.array(level_power)
    kept = np.divide(np.array(kept_power), lp, out=np.zeros_like(lp), where=lp > 0)
    return _information(lp, kept, float((residual ** 2).mean()), float((data ** 2).mean()))
