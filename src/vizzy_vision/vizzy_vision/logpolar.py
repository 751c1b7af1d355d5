"""A log-polar retina with overlapping Gaussian receptive fields (thesis Eq. 1.1, section 3.3.2).

Receptive field (RF) (j, i) sits on ring i and wedge j:

    r_i = rho_min * a^i,  a = (rho_max / rho_min)^(1 / rings),   theta_j = 2 pi j / wedges,

so its cortical coordinates are the log-polar map of Eq. 1.1, (log_a(r / rho_min), theta):
neighbouring RFs are r_i (a - 1) apart radially and r_i 2 pi / wedges apart along the ring, both
proportional to eccentricity. Each RF is an isotropic Gaussian (Eqs. 3.6-3.7: mean = centre,
standard deviation = support radius) with

    sigma_i = max(sigma_min, sigma_ratio * r_i * max(a - 1, 2 pi / wedges)),

so RF size grows linearly with eccentricity and neighbours overlap (sigma_ratio = 0.5: adjacent
centres are 2 sigma apart). The disc r < rho_min is the fovea; it has no RFs of its own and is
filled from ring 0 when mapping back.

Maps, precomputed once per geometry:

- retina -> cortex (`to_cortex`): each RF's Gaussian-weighted mean of the pixels within
  `truncate` sigma, as sparse matrices; RFs with less than half their weight on the image are
  flagged in `rf_valid` and read 0. A large RF is read from a pyrDown level of the image
  (`ring_levels`: the coarsest level where it still spans >= 1 level px), with its Gaussian
  narrowed by the pyramid's own blur (variance (4^l - 1)/3 px^2 at level l), which cuts the
  weights from 2.4 M to 0.93 M for 200 x 200 RFs on 640x480; `max_level=0` gives the exact
  full-resolution weights (they agree to 0.06 gray levels RMS on a 1/f image, 640x480).
- cortex -> retina (`to_retina`): bilinear interpolation in (ring, wedge) at each pixel's
  log-polar coordinates, wrapping in angle, as fixed-point cv2.remap maps; an invalid RF
  (mostly off the image) stands in with its wedge's nearest valid RF, so the image's edges and
  corners are rebuilt from the RFs that see them.
- `sample`: point sampling at the RF centres (cv2.remap), the non-overlapping retina.

Cortical images are (wedges, rings[, C]) arrays: rows are angles, columns eccentricities, the
layout of cv2.warpPolar. warpPolar itself is not used: its WARP_POLAR_LOG mode maps
log(r + 1) (rings start at the centre, 0.03 px apart for 200 rings), not Eq. 1.1 with a minimum
radius; the remap maps here are the same operation for our geometry.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from scipy import sparse

from .image_checks import check_count, check_image, check_positive, check_size


class LogPolarRetina:
    """Log-polar sensor for width x height images; see the module docstring for the geometry.

    Parameters: `rings` x `wedges` RFs; `rho_min` (px) the fovea radius = innermost ring;
    `rho_max` (px) the outer edge (default: just past the farthest image corner, so the whole
    image is covered); `center` (x, y) the fixation (default: image centre); `sigma_ratio`,
    `sigma_min` (px) the RF size law; `truncate` the RF support in sigmas; `max_level` the
    coarsest pyramid level large RFs may be read from (0: exact full-resolution weights).
    Cortical arrays are (wedges, rings[, C]); all maps are built once here.
    """

    def __init__(self, width: int, height: int, rings: int = 200, wedges: int = 200,
                 rho_min: float = 1.0, rho_max: float | None = None,
                 center: tuple[float, float] | None = None, sigma_ratio: float = 0.5,
                 sigma_min: float = 0.5, truncate: float = 3.0, max_level: int = 4) -> None:
        self.width, self.height = check_size(width, height)
        self.rings, self.wedges = check_count('rings', rings), check_count('wedges', wedges)
        if center is None:
            center = ((self.width - 1) / 2.0, (self.height - 1) / 2.0)
        cx, cy = (float(c) for c in center)
        if not (0.0 <= cx <= self.width - 1 and 0.0 <= cy <= self.height - 1):
            raise ValueError(f'center ({cx:g}, {cy:g}) is outside the '
                             f'{self.width}x{self.height} image')
        self.center = (cx, cy)
        self.rho_min = check_positive('rho_min', rho_min)
        if rho_max is None:
            rho_max = math.hypot(max(cx, self.width - 1 - cx), max(cy, self.height - 1 - cy)) + 1.0
        self.rho_max = check_positive('rho_max', rho_max)
        if self.rho_max <= self.rho_min:
            raise ValueError(f'rho_max ({self.rho_max:g}) must exceed rho_min ({self.rho_min:g})')
        self.sigma_ratio = check_positive('sigma_ratio', sigma_ratio)
        self.sigma_min = check_positive('sigma_min', sigma_min)
        self.truncate = check_positive('truncate', truncate)
        if isinstance(max_level, bool) or not isinstance(max_level, (int, np.integer)) \
                or not 0 <= max_level <= 8:
            raise ValueError(f'max_level must be an integer in [0, 8], got {max_level!r}')
        self.max_level = int(max_level)

        self.growth = (self.rho_max / self.rho_min) ** (1.0 / self.rings)   # a
        self.ring_radii = self.rho_min * self.growth ** np.arange(self.rings)
        self.wedge_angles = 2.0 * math.pi * np.arange(self.wedges) / self.wedges
        spacing = self.ring_radii * max(self.growth - 1.0, 2.0 * math.pi / self.wedges)
        self.rf_sigmas = np.maximum(self.sigma_min, self.sigma_ratio * spacing)
        cos, sin = np.cos(self.wedge_angles)[:, None], np.sin(self.wedge_angles)[:, None]
        self.rf_centers = np.stack([cx + self.ring_radii[None, :] * cos,
                                    cy + self.ring_radii[None, :] * sin], axis=-1)  # (S, R, 2)
        self.ring_levels = self._ring_levels()
        self._forward, self.rf_valid = self._build_forward()
        self._inverse_maps, self.retina_mask = self._build_inverse()
        self._sample_x = self.rf_centers[..., 0].astype(np.float32)
        self._sample_y = self.rf_centers[..., 1].astype(np.float32)

    @property
    def cortex_shape(self) -> tuple[int, int]:
        """(wedges, rings): rows are angles, columns eccentricities."""
        return self.wedges, self.rings

    @property
    def forward_matrices(self) -> list[sparse.csr_matrix]:
        """Retina -> cortex: one (wedges * rings) x (pixels of level l) matrix per pyramid level l.

        Each RF's row lives in the matrix of the level it reads (`ring_levels`) and sums to 1
        (0 for an invalid RF).
        """
        return self._forward

    def cortex_coordinates(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(ring, wedge) fractional indices of image points (Eq. 1.1 scaled to RF units).

        ring = log(r / rho_min) / log(a), wedge = theta * wedges / (2 pi) in [0, wedges).
        """
        dx = np.asarray(x, np.float64) - self.center[0]
        dy = np.asarray(y, np.float64) - self.center[1]
        r = np.hypot(dx, dy)
        ring = np.log(np.maximum(r, 1e-12) / self.rho_min) / math.log(self.growth)
        wedge = np.mod(np.arctan2(dy, dx), 2.0 * math.pi) * (self.wedges / (2.0 * math.pi))
        return ring, np.where(wedge >= self.wedges, 0.0, wedge)

    def retina_coordinates(self, ring: np.ndarray,
                           wedge: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) image coordinates of fractional cortical indices (the inverse of Eq. 1.1)."""
        r = self.rho_min * self.growth ** np.asarray(ring, np.float64)
        theta = 2.0 * math.pi * np.asarray(wedge, np.float64) / self.wedges
        return self.center[0] + r * np.cos(theta), self.center[1] + r * np.sin(theta)

    def to_cortex(self, image: np.ndarray) -> np.ndarray:
        """Gaussian RF responses, (wedges, rings[, C]) float32; invalid RFs read 0."""
        _, _, channels = self._check(image)
        level = image.reshape(image.shape[:2]) if image.ndim == 3 and channels == 1 else image
        level = level if level.dtype == np.float32 else level.astype(np.float32)
        out = np.zeros((self.wedges * self.rings, channels), np.float32)
        for lvl, matrix in enumerate(self._forward):
            if lvl:
                level = cv2.pyrDown(level)
            if matrix.nnz:
                flat = level.reshape(-1, channels)
                for c in range(channels):   # one sparse mat-vec per channel: faster than mat-mat
                    out[:, c] += matrix @ flat[:, c]
        shape = self.cortex_shape if image.ndim == 2 else self.cortex_shape + (channels,)
        return out.reshape(shape)

    def sample(self, image: np.ndarray, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
        """Point samples at the RF centres (no RF weighting), (wedges, rings[, C]), image dtype."""
        self._check(image)
        return cv2.remap(image, self._sample_x, self._sample_y, interpolation,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=0)

    def to_retina(self, cortex: np.ndarray) -> np.ndarray:
        """Cortex -> image (H, W[, C]) by bilinear interpolation; pixels beyond rho_max read 0."""
        if not isinstance(cortex, np.ndarray) or cortex.ndim not in (2, 3) \
                or cortex.shape[:2] != self.cortex_shape:
            got = cortex.shape if isinstance(cortex, np.ndarray) else type(cortex).__name__
            raise ValueError(f'cortex must be {self.cortex_shape} or {self.cortex_shape} + (C,), '
                             f'got {got}')
        check_image(cortex, 'cortex')
        # invalid RFs (mostly off the image) take the value of the nearest valid RF of their
        # wedge; one wrapped row so angles in [wedges - 1, wedges) interpolate towards wedge 0
        filled = cortex.reshape(self.wedges * self.rings, -1)[self._fill].reshape(cortex.shape)
        padded = np.concatenate([filled, filled[:1]], axis=0)
        return cv2.remap(padded, self._inverse_maps[0], self._inverse_maps[1], cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=0)

    def _check(self, image: np.ndarray) -> tuple[int, int, int]:
        height, width, channels = check_image(image)
        if (width, height) != (self.width, self.height):
            raise ValueError(f'image is {width}x{height}, this retina is for '
                             f'{self.width}x{self.height}')
        return height, width, channels

    def _ring_levels(self) -> np.ndarray:
        """Pyramid level each ring reads: the coarsest where its RF is still >= 1 level px wide.

        Level l = l times cv2.pyrDown, whose binomial cascade already blurs with variance
        (4^l - 1)/3 full-resolution px^2; the RF's Gaussian supplies the rest of sigma_i^2.
        """
        levels = np.zeros(self.rings, int)
        for lvl in range(1, self.max_level + 1):
            rest = self.rf_sigmas ** 2 - (4.0 ** lvl - 1.0) / 3.0
            fits = rest >= (2.0 ** lvl) ** 2            # residual sigma >= 1 level-l px
            fits &= min(self.width, self.height) >= 2 ** (lvl + 3)
            levels[fits] = lvl
        return levels

    def _build_forward(self) -> tuple[list[sparse.csr_matrix], np.ndarray]:
        """Per pyramid level, the row-normalised Gaussian weights of the rings read there."""
        ring_level = self.ring_levels
        valid = np.zeros(self.cortex_shape, bool)
        index = np.arange(self.wedges) * self.rings
        matrices = []
        width, height = self.width, self.height
        for lvl in range(int(ring_level.max()) + 1):
            scale = 2.0 ** lvl
            rows, cols, vals = [], [], []
            for i in np.flatnonzero(ring_level == lvl):
                sigma = math.sqrt(self.rf_sigmas[i] ** 2 - (4.0 ** lvl - 1.0) / 3.0) / scale
                reach = self.truncate * sigma
                span = np.arange(-math.ceil(reach), math.ceil(reach) + 2)
                oy, ox = (a.ravel() for a in np.meshgrid(span, span, indexing='ij'))
                cx, cy = self.rf_centers[:, i, 0] / scale, self.rf_centers[:, i, 1] / scale
                px = np.floor(cx)[:, None] + ox[None, :]
                py = np.floor(cy)[:, None] + oy[None, :]
                d2 = (px - cx[:, None]) ** 2 + (py - cy[:, None]) ** 2
                weight = np.where(d2 <= reach * reach, np.exp(-0.5 * d2 / sigma ** 2), 0.0)
                inside = (px >= 0) & (px < width) & (py >= 0) & (py < height) & (weight > 0)
                kept = np.where(inside, weight, 0.0).sum(axis=1)
                ok = kept >= 0.5 * weight.sum(axis=1)
                valid[:, i] = ok
                keep = inside & ok[:, None]
                wedge, _ = np.nonzero(keep)
                rows.append(index[wedge] + i)
                cols.append((py[keep] * width + px[keep]).astype(np.int64))
                vals.append(weight[keep] / kept[wedge])
            empty = np.zeros(0, np.int64)
            matrix = sparse.csr_matrix(
                (np.concatenate(vals or [np.zeros(0)]).astype(np.float32),
                 (np.concatenate(rows or [empty]), np.concatenate(cols or [empty]))),
                shape=(self.wedges * self.rings, width * height))
            matrix.sum_duplicates()
            matrices.append(matrix)
            width, height = (width + 1) // 2, (height + 1) // 2   # cv2.pyrDown's size
        return matrices, valid

    def _build_inverse(self) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
        """Fixed-point remap maps (pixel -> (ring, wedge)) and the mask of pixels within rho_max.

        Also sets `_fill`: for each RF, the flat index of itself if valid, else of the nearest
        valid RF on the same wedge (0 if the wedge has none).
        """
        y, x = np.mgrid[0:self.height, 0:self.width]
        ring, wedge = self.cortex_coordinates(x, y)
        inside = np.hypot(x - self.center[0], y - self.center[1]) < self.rho_max
        map_x = np.where(inside, np.clip(ring, 0.0, self.rings - 1), -2.0).astype(np.float32)
        map_y = np.where(inside, wedge, -2.0).astype(np.float32)
        rings = np.arange(self.rings)
        fill = np.zeros(self.cortex_shape, np.int64)
        for j in range(self.wedges):
            good = np.flatnonzero(self.rf_valid[j])
            if good.size:
                nearest = good[np.abs(rings[:, None] - good[None, :]).argmin(axis=1)]
                fill[j] = j * self.rings + nearest
        self._fill = fill.ravel()
        return cv2.convertMaps(map_x, map_y, cv2.CV_16SC2), inside
