"""Observation model of a sliding-window detector (thesis section 5.3.2, Eqs. 5.8-5.15).

A sliding-window detector reports a window from a discrete set: positions on a grid of
`stride` pixels in the resized image, scales on a geometric ladder of `scale_step`. The error
this quantization puts on the reported box is the observation noise of the tracker:

- sliding window (Eq. 5.8): at scale ``s`` consecutive positions are ``Q_sl = s * stride``
  pixels apart;
- scale ladder (Eq. 5.9): ``s^n = 2^(n / N)`` with ``N`` scales per octave,
  ``N = ln 2 / ln(scale_step)`` (OpenCV HOG's 1.05 step gives N = 14.2; the thesis's
  detector has N = 8);
- scale jumps move the box centre by (Eqs. 5.10-5.11, written for any N)
  ``Q_scx = w0 (2^((n+1)/N) - 2^(n/N)) / 2 = w0 s (2^(1/N) - 1) / 2`` and the same with h0;
- both are taken as zero-mean Gaussians (Eqs. 5.12-5.13) and the larger one wins
  (Eqs. 5.14-5.15): ``Sigma^n = max(Sigma_sl^n, Sigma_sc^n)``.

The thesis takes the jump itself as the standard deviation (worst case, ``quantization =
'worst'``); the authors' C++ code uses the variance of a uniform error over one jump,
``Q^2 / 12`` (``quantization = 'uniform'``).

The thesis models the centre only. The state here also observes the scale, so the scale gets
the same treatment (an extension, documented in docs/mot_planner.md): the reported scale is
one ladder step from the true one at worst, ``Q_s = s (2^(1/N) - 1)``, variance ``Q_s^2``.

Scales are relative to the smallest window (w0 x h0): ``s = window height / h0``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class DetectorGeometry:
    """What the observation model needs to know about a sliding-window detector.

    window_w, window_h: the smallest window w0 x h0 in pixels (scale 1).
    stride: window step Q_sl(0) at scale 1, pixels (Eq. 5.8).
    scale_step: ratio between consecutive scales (2^(1/N), Eq. 5.9).
    min_scale: smallest scale the detector scans (1 for detectors that never upsample).
    upsample: in a region, the detector reads the crop at ``upsample`` times the region's
        smallest scale and enlarges it before scanning (1: reads it at that scale); what it
        reads, and so what the S_max constraint counts, shrinks by ``upsample**2``.
    """

    window_w: float = 64.0
    window_h: float = 128.0
    stride: float = 8.0
    scale_step: float = 1.05
    min_scale: float = 1.0
    upsample: float = 1.0

    def __post_init__(self) -> None:
        problems = []
        if not (self.window_w > 0 and self.window_h > 0):
            problems.append(f'window must be positive, got {self.window_w}x{self.window_h}')
        if not self.stride > 0:
            problems.append(f'stride must be > 0, got {self.stride}')
        if not self.scale_step > 1.0:
            problems.append(f'scale_step must be > 1, got {self.scale_step}')
        if not self.upsample >= 1.0:
            problems.append(f'upsample must be >= 1, got {self.upsample}')
        if not self.min_scale > 0:
            problems.append(f'min_scale must be > 0, got {self.min_scale}')
        if problems:
            raise ValueError('DetectorGeometry: ' + '; '.join(problems))

    @property
    def scales_per_octave(self) -> float:
        """N of Eq. 5.9: ``2^(1/N) = scale_step``."""
        return math.log(2.0) / math.log(self.scale_step)


class ObservationModel:
    """Quantization noise of a sliding-window detector as a function of scale (Eqs. 5.8-5.15).

    ``quantization``: 'worst' (std = jump, Eqs. 5.12-5.13) or 'uniform' (std = jump / sqrt(12)).
    ``extra_std`` adds, in quadrature, detector noise the quantization model does not have
    (fraction of the window size at that scale, per axis [u, v, s]); 0 follows the thesis.
    """

    def __init__(self, geometry: DetectorGeometry,
                 extra_std: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 quantization: str = 'worst') -> None:
        self.geometry = geometry
        if len(extra_std) != 3 or min(extra_std) < 0:
            raise ValueError(f'extra_std must be three values >= 0, got {extra_std}')
        if quantization not in ('worst', 'uniform'):
            raise ValueError(f"quantization must be 'worst' or 'uniform', got {quantization!r}")
        self.extra_std = tuple(float(e) for e in extra_std)
        self.quantization = quantization
        self._q_factor = 1.0 if quantization == 'worst' else 1.0 / np.sqrt(12.0)
        self._step_minus_one = 2.0 ** (1.0 / geometry.scales_per_octave) - 1.0
        self._quadrature: dict[tuple[float, int], tuple[FloatArray, FloatArray]] = {}

    def scale_level(self, s: ArrayLike) -> FloatArray:
        """n of Eq. 5.9 for scale s (real-valued: ``n = N log2 s``)."""
        return self.geometry.scales_per_octave * np.log2(np.asarray(s, dtype=float))

    def sliding_window_jump(self, s: ArrayLike) -> FloatArray:
        """Q_sl^n = s^n Q_sl(0), Eq. 5.8 (pixels)."""
        return np.asarray(s, dtype=float) * self.geometry.stride

    def scale_jumps(self, s: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(Q_scx^n, Q_scy^n) of Eqs. 5.10-5.11 with N scales per octave (pixels)."""
        s = np.asarray(s, dtype=float)
        g = self.geometry
        return (g.window_w * s * self._step_minus_one / 2.0,
                g.window_h * s * self._step_minus_one / 2.0)

    def scale_jump(self, s: ArrayLike) -> FloatArray:
        """Q_s: one ladder step at scale s, ``s (2^(1/N) - 1)`` (scale units; extension)."""
        return np.asarray(s, dtype=float) * self._step_minus_one

    def std(self, s: ArrayLike) -> FloatArray:
        """Per-axis noise std [u, v, s] at scale s, shape s.shape + (3,) (Eqs. 5.12-5.15)."""
        sc: FloatArray = np.maximum(np.asarray(s, dtype=float), 1e-6)
        q_sl = self.sliding_window_jump(sc)
        q_scx, q_scy = self.scale_jumps(sc)
        quant = self._q_factor * np.stack([np.maximum(q_sl, q_scx),   # Eq. 5.15, u
                                           np.maximum(q_sl, q_scy),   # Eq. 5.15, v
                                           self.scale_jump(sc)], axis=-1)
        g = self.geometry
        ex, ey, es = self.extra_std
        extra = np.stack([ex * g.window_w * sc, ey * g.window_h * sc, es * sc], axis=-1)
        return np.sqrt(quant ** 2 + extra ** 2)

    def covariance(self, s: ArrayLike) -> FloatArray:
        """R(s): diagonal observation covariance of [u, v, s], shape s.shape + (3, 3) (Eq. 5.14)."""
        sd = self.std(s)
        return sd[..., :, None] * np.eye(3) * sd[..., None, :]

    def expected_covariance(self, s_mean: ArrayLike, s_std: ArrayLike, alpha_s: float,
                            points: int = 5) -> FloatArray:
        """Observation covariance expected over the scales of a search region (Eq. 5.22).

        The region spans scales ``s_mean +- alpha_s s_std`` (Eq. 5.19); R is averaged over
        ``points`` scales of that span, weighted by the predicted belief there (a Gaussian in
        s). Moment matching stands in for the sum over detection windows of Eq. 5.22.
        """
        var = self.expected_variances(s_mean, s_std, alpha_s, points)
        return var[..., :, None] * np.eye(3)

    def expected_variances(self, s_mean: ArrayLike, s_std: ArrayLike, alpha_s: float,
                           points: int = 5) -> FloatArray:
        """The diagonal of :meth:`expected_covariance`, shape s_mean.shape + (3,)."""
        key = (float(alpha_s), int(points))
        if key not in self._quadrature:
            z = np.linspace(-alpha_s, alpha_s, points) if points > 1 else np.zeros(1)
            w = np.exp(-0.5 * z ** 2)
            self._quadrature[key] = (z, w / w.sum())
        z, w = self._quadrature[key]
        scales = (np.asarray(s_mean, dtype=float)[..., None]
                  + np.asarray(s_std, dtype=float)[..., None] * z)
        sd = self.std(np.maximum(scales, self.geometry.min_scale))      # (..., points, 3)
        return np.einsum('p,...pi->...i', w, sd * sd)
