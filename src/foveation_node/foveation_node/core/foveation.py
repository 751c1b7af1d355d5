"""Smooth artificial foveal vision, thesis section 2.3.1 (Eqs. 2.1-2.3, 2.6, 2.13).

The image I is split into Gaussian levels G_k = I * g_k with sigma_k = 2^(k-1) sigma_1 (Eq. 2.1,
G_0 = I), Laplacian levels L_k = G_k - G_(k+1) (Eq. 2.6), each weighted by an exponential kernel
H_k centred at the fixation (u0, v0) with f_k = 2^k f_0 (Eq. 2.3), F_k = L_k H_k (Eq. 2.13), and
recombined with the coarsest Gaussian level:

    F = G_K + sum_{k=0}^{K-1} H_k L_k

so F = I wherever every H_k = 1 (at the fixation) and F -> G_K far from it. G_K keeps weight 1,
as in the authors' C++ (laplacian_foveation), so the periphery keeps its coarse content.

Two implementations of the same equations:

- `foveate_reference`: direct, full resolution, float64 (the ground truth; slow).
- `Foveator`: the real-time one on a subsampled pyramid (OpenCV pyrDown/pyrUp, the thesis's
  footnote 1): level k holds G_k at 1/2^k resolution, L_k = g_k - pyrUp(g_(k+1)), H_k is applied at
  level k's resolution and the sum is rebuilt coarse to fine with pyrUp.

The subsampled pyramid realises the scale space of Eq. 2.1 only for sigma_1 >= sqrt(8/3) ~ 1.63 px:
the binomial filters of pyrDown and pyrUp each have variance 1 (in the pixels of the finer level),
so the level-k image brought back to full resolution has variance 2(4^k - 1)/3 px^2 without any
extra blur. `Foveator` adds the small extra blur that makes the variance exactly 4^(k-1) sigma_1^2
at every level (for sigma_1 = sqrt(8/3): only level 1, a 3-tap filter), so both implementations
describe the same sigma_k. The thesis's sigma_1 = 1 (used in its information analysis, Fig. 2.6)
needs the full-resolution reference: a 2x subsampled level cannot hold a sigma = 1 px blur
without aliasing.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Final

import cv2
import numpy as np

from vizzy_vision.image_checks import (
    check_fixation,
    check_image,
    check_levels,
    check_positive,
    check_size,
)

#: Smallest sigma_1 (px) the subsampled pyramid realises: pyrDown + pyrUp alone give variance
#: 2(4^k - 1)/3 at level k, which is <= 4^(k-1) * 8/3 for every k.
PYRAMID_SIGMA_1: Final[float] = math.sqrt(8.0 / 3.0)
#: Defaults of the authors' C++ (laplacian_foveation / foveated_yolt) for 640x480 input.
DEFAULT_LEVELS: Final[int] = 5
DEFAULT_F0: Final[float] = 100.0

Fixation = tuple[float, float]
Region = tuple[int, int, int, int]                  # x0, y0, x1, y1 (px; x1, y1 exclusive)


def gaussian_sigmas(sigma_1: float, levels: int) -> np.ndarray:
    """sigma_k for k = 0..K (Eq. 2.1): sigma_0 = 0 (G_0 = I), sigma_k = 2^(k-1) sigma_1."""
    sigma_1 = check_positive('sigma_1', sigma_1)
    levels = check_levels(levels)
    return np.array([0.0] + [2.0 ** (k - 1) * sigma_1 for k in range(1, levels + 1)])


def fovea_sigmas(f0: float, levels: int) -> np.ndarray:
    """f_k = 2^k f_0 for k = 0..K-1 (Eq. 2.3): the fovea's size at each Laplacian level."""
    f0 = check_positive('f0', f0)
    levels = check_levels(levels)
    return f0 * 2.0 ** np.arange(levels)


def fovea_kernel(width: int, height: int, fixation: Fixation, f_k: float) -> np.ndarray:
    """H_k(u, v) = exp(-((u - u0)^2 + (v - v0)^2) / (2 f_k^2)), full grid, float64 (Eq. 2.3)."""
    width, height = check_size(width, height)
    u0, v0 = check_fixation(fixation, width, height)
    f_k = check_positive('f_k', f_k)
    row = np.exp(-0.5 * ((np.arange(width) - u0) / f_k) ** 2)
    col = np.exp(-0.5 * ((np.arange(height) - v0) / f_k) ** 2)
    return np.outer(col, row)


def _check_levels_fit(width: int, height: int, levels: int) -> None:
    if min(width, height) < 2 ** levels:
        raise ValueError(f'{levels} levels need an image of at least {2 ** levels} px a side '
                         f'(the coarsest level would be under 1 px), got {width}x{height}')


def gaussian_levels_reference(image: np.ndarray, sigma_1: float = PYRAMID_SIGMA_1,
                              levels: int = DEFAULT_LEVELS) -> list[np.ndarray]:
    """G_0..G_K at full resolution (Eq. 2.1), float64, mirrored borders (BORDER_REFLECT_101).

    Each G_k is a direct convolution of I with g_k (truncated at 4 sigma_k), not a cascade.
    """
    height, width, _ = check_image(image)
    sigmas = gaussian_sigmas(sigma_1, levels)
    _check_levels_fit(width, height, levels)
    base = image.astype(np.float64)
    out: list[np.ndarray] = [base]
    for sigma in sigmas[1:]:
        ksize = 2 * math.ceil(4.0 * sigma) + 1
        out.append(cv2.GaussianBlur(base, (ksize, ksize), sigma, sigmaY=sigma,
                                    borderType=cv2.BORDER_REFLECT_101).reshape(base.shape))
    return out


def laplacian_levels_reference(
        image: np.ndarray, sigma_1: float = PYRAMID_SIGMA_1,
        levels: int = DEFAULT_LEVELS) -> tuple[list[np.ndarray], np.ndarray]:
    """(L_0..L_(K-1), G_K) at full resolution: L_k = G_k - G_(k+1) (Eq. 2.6), float64."""
    gaussians = gaussian_levels_reference(image, sigma_1, levels)
    return [gaussians[k] - gaussians[k + 1] for k in range(levels)], gaussians[levels]


def foveate_reference(image: np.ndarray, fixation: Fixation, f0: float = DEFAULT_F0,
                      sigma_1: float = PYRAMID_SIGMA_1,
                      levels: int = DEFAULT_LEVELS) -> np.ndarray:
    """F = G_K + sum_k H_k L_k (Eqs. 2.1, 2.3, 2.6, 2.13) computed directly at full resolution.

    The ground truth for `Foveator`: float64 output, no subsampling, any sigma_1 > 0.
    """
    height, width, _ = check_image(image)
    u0, v0 = check_fixation(fixation, width, height)
    f_ks = fovea_sigmas(f0, levels)
    laplacians, residual = laplacian_levels_reference(image, sigma_1, levels)
    out = residual.copy()
    for lap, f_k in zip(laplacians, f_ks, strict=True):
        kernel = fovea_kernel(width, height, (u0, v0), float(f_k))
        out += lap * (kernel if lap.ndim == 2 else kernel[:, :, None])
    return out


def _variance_kernel(variance: float) -> np.ndarray | None:
    """A symmetric 1-D smoothing kernel with exactly the given variance (px^2), or None if ~0."""
    if variance <= 1e-9:
        return None
    if variance <= 0.5:  # [v/2, 1 - v, v/2] has variance v exactly
        return np.array([variance / 2, 1.0 - variance, variance / 2], np.float32)
    sigma = math.sqrt(variance)  # sampled Gaussian: its variance is sigma^2 to < 1e-4 here
    taps = np.arange(-math.ceil(4 * sigma), math.ceil(4 * sigma) + 1, dtype=np.float64)
    kernel = np.exp(-0.5 * taps ** 2 / variance)
    return (kernel / kernel.sum()).astype(np.float32)


class Foveator:
    """Real-time foveation of width x height images on a subsampled pyramid (section 2.3.1).

    Build once per image size and parameters; `foveate(image, fixation)` then costs the pyramid
    (pyrDown/pyrUp) plus one multiply per level. H_0, the only full-resolution kernel, is
    precomputed on a (2h - 1) x (2w - 1) canvas and a window of it is cut at each whole-pixel
    fixation. The coarser H_k (and H_0 for sub-pixel fixations) are separable (Eq. 2.3), so they
    cost two 1-D profiles (w_k + h_k samples) and their outer product. Level-k pixel j sits at
    full-resolution coordinate 2^k j (OpenCV's pyramid convention), so H_k is evaluated exactly
    there, for any fixation.

    Parameters: `levels` K (number of Laplacian levels), `f0` (fovea size f_0, px, Eq. 2.3),
    `sigma_1` (px, Eq. 2.1; at least PYRAMID_SIGMA_1). Accepts (H, W), (H, W, 1), (H, W, 3) and
    (H, W, 4) images of uint8, uint16, float32 or float64 and returns the same shape and dtype
    (integer outputs rounded and saturated). Computation is float32.
    """

    def __init__(self, width: int, height: int, levels: int = DEFAULT_LEVELS,
                 f0: float = DEFAULT_F0, sigma_1: float = PYRAMID_SIGMA_1) -> None:
        self.width, self.height = check_size(width, height)
        self.levels = check_levels(levels)
        self.f0 = check_positive('f0', f0)
        self.sigma_1 = check_positive('sigma_1', sigma_1)
        if self.sigma_1 < PYRAMID_SIGMA_1 - 1e-9:
            raise ValueError(f'sigma_1 = {self.sigma_1:g} px is below what a subsampled pyramid '
                             f'realises ({PYRAMID_SIGMA_1:.4f} px); use foveate_reference')
        _check_levels_fit(self.width, self.height, self.levels)
        sizes = [(self.width, self.height)]
        for _ in range(self.levels):
            w, h = sizes[-1]
            sizes.append(((w + 1) // 2, (h + 1) // 2))  # cv2.pyrDown's default size
        self.level_sizes: tuple[tuple[int, int], ...] = tuple(sizes)
        # full-resolution coordinates of each level's pixel centres, for H_k
        self._cols = [np.arange(w, dtype=np.float32) * 2 ** k for k, (w, _) in enumerate(sizes)]
        self._rows = [np.arange(h, dtype=np.float32) * 2 ** k for k, (_, h) in enumerate(sizes)]
        self.f_k = fovea_sigmas(self.f0, self.levels)
        # extra blur after each pyrDown so the level-k variance is 4^(k-1) sigma_1^2 (module doc):
        # the variance missing before decimation, in level-(k-1) px^2, is sigma_1^2 - 2 for k = 1
        # and 3 sigma_1^2 / 4 - 2 after; added after decimation it is a quarter of that.
        s2 = self.sigma_1 ** 2
        self._extra = [_variance_kernel(((s2 - 2.0) if k == 1 else (0.75 * s2 - 2.0)) / 4.0)
                       for k in range(1, self.levels + 1)]
        self._work: dict[int, _Buffers] = {}

    def kernels(self, fixation: Fixation) -> list[np.ndarray]:
        """H_k sampled on each level's own grid (k = 0..K-1), float32 (Eq. 2.3)."""
        u0, v0 = check_fixation(fixation, self.width, self.height)
        return [np.outer(col, row) for col, row in self._profiles(u0, v0)]

    def gaussian_pyramid(self, image: np.ndarray) -> list[np.ndarray]:
        """g_0..g_K: G_k of Eq. 2.1 sampled every 2^k px, float32 copies, 2-D or (h, w, C)."""
        height, width, channels = check_image(image)
        self._check_shape(width, height)
        levels = self._pyramid(self._plane(image), self._buffers(channels))
        return [level.copy() for level in levels]

    def foveate(self, image: np.ndarray, fixation: Fixation,
                out: np.ndarray | None = None) -> np.ndarray:
        """The foveated image F (Eq. 2.13 summed with G_K), same shape and dtype as `image`.

        `out`, if given, must be an array of that shape and dtype; it is filled and returned.
        Not reentrant: use one Foveator per thread (it keeps its work buffers).
        """
        height, width, channels = check_image(image)
        self._check_shape(width, height)
        u0, v0 = check_fixation(fixation, width, height)
        if out is None:
            out = np.empty_like(image)
        elif out.shape != image.shape or out.dtype != image.dtype:
            raise ValueError(f'out must be {image.shape} {image.dtype}, '
                             f'got {out.shape} {out.dtype}')
        buf = self._buffers(channels)
        kernels = self._fixation_kernels(buf, channels, u0, v0)
        pyramid = self._pyramid(self._plane(image), buf)
        top = self.levels - 1
        acc = pyramid[-1]
        for k in range(top, -1, -1):
            size = self.level_sizes[k]
            expanded = cv2.pyrUp(pyramid[k + 1], dst=buf.expanded[k], dstsize=size)
            lap = cv2.subtract(pyramid[k], expanded, dst=buf.lap[k])             # L_k, Eq. 2.6
            lap = cv2.multiply(lap, kernels[k], dst=lap)                        # F_k, Eq. 2.13
            # coarse to fine: F^(k) = pyrUp(F^(k+1)) + F_k, and pyrUp(g_K) is `expanded` at K-1;
            # below the top, expanded (g_(k+1) brought up) is spent: pyrUp(F^(k+1)) goes there
            base = expanded if k == top else cv2.pyrUp(acc, dst=expanded, dstsize=size)
            if k > 0:
                acc = cv2.add(base, lap, dst=base)
        plane = out.reshape(image.shape[:2]) if channels == 1 else out
        result = cv2.add(base, lap, dst=plane, dtype=_CV_DEPTH[image.dtype.type])
        if result is not plane:  # never expected: OpenCV reallocates only on a shape mismatch
            np.copyto(plane, result)
        return out

    def foveate_many(self, image: np.ndarray, fixations: list[Fixation],
                     regions: list[Region] | None = None) -> list[np.ndarray]:
        """[foveate(image, f) for f in fixations], the same images, with the Gaussian pyramid
        and the Laplacian levels built once: they do not depend on the fixation, only the
        kernels H_k and the coarse-to-fine sum do (about half of a foveation's cost).

        regions: one (x0, y0, x1, y1) per fixation (px, x1 and y1 exclusive; clipped to the
        image): only that rectangle of each image is computed, bit-identical to foveate's, and
        the rest is 0. The coarse-to-fine sum then runs on each level's part that the rectangle
        depends on (pyrUp reads a pixel's neighbours: a margin of 2 px a level), e.g. the
        window a window model classifies: a 160 px square is a twelfth of a 640x480 frame."""
        height, width, channels = check_image(image)
        self._check_shape(width, height)
        points = [check_fixation(f, width, height) for f in fixations]
        if regions is not None and len(regions) != len(points):
            raise ValueError(f'{len(regions)} regions for {len(points)} fixations')
        if not points:
            return []
        buf = self._buffers(channels)
        pyramid = self._pyramid(self._plane(image), buf)
        depth = _CV_DEPTH[image.dtype.type]
        if regions is not None:     # its own kernels: foveate's stay cached for the next frame
            return [self._foveate_region(image, pyramid, point, region, depth, channels)
                    for point, region in zip(points, regions, strict=True)]
        buf.kernels_for = None                  # _kernels below overwrites foveate's
        top = self.levels - 1
        expanded_top = cv2.pyrUp(pyramid[top + 1], dstsize=self.level_sizes[top])
        laps = [cv2.subtract(pyramid[k], expanded_top if k == top else cv2.pyrUp(
            pyramid[k + 1], dstsize=self.level_sizes[k])) for k in range(self.levels)]
        out = []
        for u0, v0 in points:
            kernels = self._kernels(buf, channels, u0, v0)
            acc = expanded_top
            for k in range(top, -1, -1):
                lap = cv2.multiply(laps[k], kernels[k], dst=buf.lap[k])         # F_k, Eq. 2.13
                base = expanded_top if k == top else cv2.pyrUp(
                    acc, dst=buf.up[k], dstsize=self.level_sizes[k])
                if k > 0:
                    acc = cv2.add(base, lap, dst=buf.expanded[k] if k == top else base)
            result = cv2.add(base, lap, dtype=depth)
            out.append(result.reshape(image.shape))
        return out

    def _level_regions(self, region: Region) -> list[tuple[int, int, int, int]] | None:
        """The part (x0, y0, x1, y1) of each level 0..K that the level-0 rectangle's foveated
        values depend on through pyrUp (None: the rectangle misses the image). pyrUp's output
        pixel j reads input pixels j // 2 - 1 .. j // 2 + 1; one more pixel each side is margin."""
        x0, y0 = max(int(region[0]), 0), max(int(region[1]), 0)
        x1, y1 = min(int(region[2]), self.width), min(int(region[3]), self.height)
        if x0 >= x1 or y0 >= y1:
            return None
        out = [(x0, y0, x1, y1)]
        for k in range(1, self.levels + 1):
            w, h = self.level_sizes[k]
            x0, y0, x1, y1 = out[-1]
            out.append((max(x0 // 2 - 2, 0), max(y0 // 2 - 2, 0),
                        min((x1 - 1) // 2 + 3, w), min((y1 - 1) // 2 + 3, h)))
        return out

    def _up_part(self, coarse: np.ndarray, parts: list[tuple[int, int, int, int]],
                 k: int) -> np.ndarray:
        """pyrUp of level k + 1's part (coarse: its values there) on level k's part."""
        ax0, ay0, ax1, ay1 = parts[k + 1]
        x0, y0, x1, y1 = parts[k]
        w, h = self.level_sizes[k]
        # the expansion covers level k from 2 * (ax0, ay0); it ends one pixel short of twice
        # the part's size where level k ends at an odd size
        up = cv2.pyrUp(coarse, dstsize=(2 * (ax1 - ax0) - (2 * ax1 > w),
                                        2 * (ay1 - ay0) - (2 * ay1 > h)))
        return up[y0 - 2 * ay0:y1 - 2 * ay0, x0 - 2 * ax0:x1 - 2 * ax0]

    def _foveate_region(self, image: np.ndarray, pyramid: list[np.ndarray],
                        fixation: tuple[float, float], region: Region, depth: int,
                        channels: int) -> np.ndarray:
        """foveate(image, fixation) on region only (foveate_many's regions), 0 elsewhere: the
        Laplacians and the coarse-to-fine sum on each level's part only."""
        out = np.zeros_like(image)
        parts = self._level_regions(region)
        if parts is None:
            return out
        profiles = self._profiles(*fixation)
        top = self.levels - 1
        acc = pyramid[-1]
        for k in range(top, -1, -1):
            x0, y0, x1, y1 = parts[k]
            gx0, gy0, gx1, gy1 = parts[k + 1]
            expanded = self._up_part(pyramid[k + 1][gy0:gy1, gx0:gx1], parts, k)
            lap = cv2.subtract(pyramid[k][y0:y1, x0:x1], expanded)              # L_k, Eq. 2.6
            col, row = profiles[k]
            plane = np.multiply(col[y0:y1, None], row[None, x0:x1])
            lap = cv2.multiply(lap, plane if channels == 1 else cv2.merge([plane] * channels))
            base = expanded if k == top else self._up_part(acc, parts, k)
            if k > 0:
                acc = cv2.add(base, lap)
        x0, y0, x1, y1 = parts[0]
        result = cv2.add(base, lap, dtype=depth)
        out[y0:y1, x0:x1] = result.reshape(out[y0:y1, x0:x1].shape)
        return out

    def _fixation_kernels(self, buf: _Buffers, channels: int, u0: float,
                          v0: float) -> list[np.ndarray]:
        """_kernels, kept for the next frame: a node's fixation rarely moves between frames."""
        if buf.kernels_for != (u0, v0):
            buf.kernels = self._kernels(buf, channels, u0, v0)
            buf.kernels_for = (u0, v0)
        return buf.kernels

    def _kernels(self, buf: _Buffers, channels: int, u0: float, v0: float) -> list[np.ndarray]:
        """H_k on each level's grid (Eq. 2.3), in buf's kernel arrays, for the fixation."""
        kernels = []
        for k, (col, row) in enumerate(self._profiles(u0, v0)):
            if k == 0 and u0.is_integer() and v0.is_integer():
                kernels.append(self._level0_window(buf, channels, int(u0), int(v0)))
            elif channels == 1:
                kernels.append(np.multiply(col[:, None], row[None, :], out=buf.kernel[k]))
            else:
                plane = np.multiply(col[:, None], row[None, :], out=buf.kernel_plane[k])
                kernels.append(cv2.merge([plane] * channels, dst=buf.kernel[k]))
        return kernels

    def _level0_window(self, buf: _Buffers, channels: int, u0: int, v0: int) -> np.ndarray:
        """H_0 for a whole-pixel fixation: a window of a kernel precomputed on a 2x canvas."""
        w, h = self.width, self.height
        if buf.canvas is None:
            inv = np.float32(1.0 / self.f_k[0])
            row = np.exp(np.float32(-0.5) * np.square(np.arange(1 - w, w, dtype=np.float32) * inv))
            col = np.exp(np.float32(-0.5) * np.square(np.arange(1 - h, h, dtype=np.float32) * inv))
            if channels > 1:
                row = np.repeat(row, channels)
            buf.canvas = np.multiply(col[:, None], row[None, :])
        left = (w - 1 - u0) * channels
        window = buf.canvas[h - 1 - v0:2 * h - 1 - v0, left:left + w * channels]
        return window if channels == 1 else window.reshape(h, w, channels)

    def _check_shape(self, width: int, height: int) -> None:
        if (width, height) != (self.width, self.height):
            raise ValueError(f'image is {width}x{height}, this Foveator is for '
                             f'{self.width}x{self.height}')

    def _profiles(self, u0: float, v0: float) -> list[tuple[np.ndarray, np.ndarray]]:
        """The separable factors (column, row) of H_k on level k's grid, for k = 0..K-1."""
        out = []
        for k in range(self.levels):
            inv = np.float32(1.0 / self.f_k[k])
            row = np.exp(np.float32(-0.5) * np.square((self._cols[k] - np.float32(u0)) * inv))
            col = np.exp(np.float32(-0.5) * np.square((self._rows[k] - np.float32(v0)) * inv))
            out.append((col, row))
        return out

    @staticmethod
    def _plane(image: np.ndarray) -> np.ndarray:
        return image.reshape(image.shape[:2]) if image.ndim == 3 and image.shape[2] == 1 else image

    def _pyramid(self, plane: np.ndarray, buf: _Buffers) -> list[np.ndarray]:
        """Fill and return buf.gauss: g_0 (float32 view or converted copy) .. g_K."""
        if plane.dtype == np.float32 and plane.flags.c_contiguous:
            base = plane
        else:
            base = buf.gauss[0]
            np.copyto(base, plane, casting='unsafe')
        levels = [base]
        for k, extra in enumerate(self._extra, start=1):
            if extra is None:
                levels.append(cv2.pyrDown(levels[-1], dst=buf.gauss[k]))
            else:
                down = cv2.pyrDown(levels[-1], dst=buf.scratch[k])
                levels.append(cv2.sepFilter2D(down, -1, extra, extra, dst=buf.gauss[k],
                                              borderType=cv2.BORDER_REFLECT_101))
        return levels

    def _buffers(self, channels: int) -> _Buffers:
        if channels not in self._work:
            self._work[channels] = _Buffers(self.level_sizes, channels)
        return self._work[channels]


class _Buffers:
    """Preallocated float32 work arrays of one Foveator for one channel count.

    Fresh multi-megabyte arrays every frame cost more in page faults than the arithmetic.
    """

    def __init__(self, sizes: tuple[tuple[int, int], ...], channels: int) -> None:
        def level(k: int) -> np.ndarray:
            w, h = sizes[k]
            return np.empty((h, w) if channels == 1 else (h, w, channels), np.float32)

        count = len(sizes) - 1
        self.gauss = [level(k) for k in range(count + 1)]
        self.scratch = [level(k) for k in range(count + 1)]
        self.expanded = [level(k) for k in range(count)]
        self.lap = [level(k) for k in range(count)]
        self.up = [level(k) for k in range(count)]
        self.kernel = [level(k) for k in range(count)]
        self.kernel_plane = [np.empty(sizes[k][::-1], np.float32) for k in range(count)]
        self.canvas: np.ndarray | None = None   # H_0 on a (2h - 1) x (2w - 1) canvas, built lazily
        self.kernels: list[np.ndarray] = []      # H_k at kernels_for (Foveator._fixation_kernels)
        self.kernels_for: tuple[float, float] | None = None


# cv2.add's dtype argument: integer outputs are rounded and saturated
_CV_DEPTH: Final = {np.uint8: cv2.CV_8U, np.uint16: cv2.CV_16U, np.float32: cv2.CV_32F,
                    np.float64: cv2.CV_64F}


@lru_cache(maxsize=16)
def _cached(width: int, height: int, levels: int, f0: float, sigma_1: float) -> Foveator:
    return Foveator(width, height, levels, f0, sigma_1)


def foveate(image: np.ndarray, fixation: Fixation, f0: float = DEFAULT_F0,
            levels: int = DEFAULT_LEVELS, sigma_1: float = PYRAMID_SIGMA_1) -> np.ndarray:
    """`Foveator(...).foveate(image, fixation)` with Foveators cached per size and parameters.

    Shares the cached Foveators' work buffers: call from one thread, or use your own Foveator.
    """
    height, width, _ = check_image(image)
    return _cached(width, height, check_levels(levels), check_positive('f0', f0),
                   check_positive('sigma_1', sigma_1)).foveate(image, fixation)
