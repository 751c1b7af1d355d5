"""Sensors as sets of Gaussian receptive fields (thesis section 3.3.2, Eqs. 3.6-3.7).

A sensor is N_rf RFs with centres mu (image pixels) and isotropic support sigma (px). Two kinds,
with equal resources in the thesis (N_rf = 200 x 200 for both):

- `cartesian_sensor`: a uniform nx x ny grid over the image, sigma = sigma_ratio * spacing;
- `logpolar_sensor`: the foveation package's `LogPolarRetina` (rings x wedges, Eq. 1.1), reused,
  not re-implemented: its RF centres and per-ring sigmas.

`rf_index(x, y)` maps image points to the nearest RF (the RF a correspondence falls in), used to
look up the precomputed sigma points of `ut.SigmaPointTable`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from vizzy_vision.logpolar import LogPolarRetina


@dataclass(frozen=True)
class RFSensor:
    """N_rf Gaussian RFs: centres (N_rf, 2) px, sigmas (N_rf,) px, and a point -> RF lookup."""

    kind: str
    width: int
    height: int
    centers: np.ndarray
    sigmas: np.ndarray
    _index: Callable[[np.ndarray, np.ndarray], np.ndarray]

    @property
    def n_rf(self) -> int:
        return int(self.centers.shape[0])

    def rf_index(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Index of the RF whose centre is nearest (in the sensor's own layout) to (x, y)."""
        return self._index(np.asarray(x, np.float64), np.asarray(y, np.float64))


def cartesian_sensor(width: int, height: int, nx: int = 200, ny: int = 200,
                     sigma_ratio: float = 0.5) -> RFSensor:
    """Uniform grid of nx x ny RFs covering a width x height image (row-major, y then x)."""
    if min(width, height, nx, ny) <= 0 or sigma_ratio <= 0:
        raise ValueError('cartesian_sensor: sizes and sigma_ratio must be positive')
    sx, sy = width / nx, height / ny
    xs = (np.arange(nx) + 0.5) * sx - 0.5
    ys = (np.arange(ny) + 0.5) * sy - 0.5
    gx, gy = np.meshgrid(xs, ys)
    centers = np.stack([gx.ravel(), gy.ravel()], axis=-1)
    sigmas = np.full(nx * ny, sigma_ratio * max(sx, sy))

    def index(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        ix = np.clip(np.rint((x + 0.5) / sx - 0.5), 0, nx - 1).astype(np.int64)
        iy = np.clip(np.rint((y + 0.5) / sy - 0.5), 0, ny - 1).astype(np.int64)
        return iy * nx + ix

    return RFSensor('cartesian', width, height, centers, sigmas, index)


def logpolar_sensor(retina: LogPolarRetina) -> RFSensor:
    """The RFs of a foveation-package log-polar retina, flattened wedge-major (S, R) -> S*R."""
    centers = retina.rf_centers.reshape(-1, 2)
    sigmas = np.broadcast_to(retina.rf_sigmas[None, :],
                             (retina.wedges, retina.rings)).reshape(-1).copy()
    rings, wedges = retina.rings, retina.wedges

    def index(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        ring, wedge = retina.cortex_coordinates(x, y)
        ir = np.clip(np.rint(ring), 0, rings - 1).astype(np.int64)
        iw = np.mod(np.rint(wedge), wedges).astype(np.int64)
        return iw * rings + ir

    return RFSensor('logpolar', retina.width, retina.height, centers, sigmas, index)


def fovea_radius(retina: LogPolarRetina) -> float:
    """Eccentricity (px) inside which the retina's RF lattice is at least as dense as the pixels.

    The RFs of ring i are r_i max(a - 1, 2 pi / wedges) apart (radially and along the ring, the
    larger; `LogPolarRetina`, Eq. 1.1), so they reach one pixel apart at
    r = 1 / max(a - 1, 2 pi / wedges): 31.8 px for 200 x 200 RFs on 640x480. Inside, the sensor
    resolves full resolution (its fovea in this sense; the retina's `rho_min`, 1 px by default, is
    only the central disc without RFs); beyond, the RF spacing grows linearly and pyramid level l
    (pixel spacing 2^l) suffices from r = 2^l times this radius on.
    """
    return 1.0 / max(retina.growth - 1.0, 2.0 * np.pi / retina.wedges)
