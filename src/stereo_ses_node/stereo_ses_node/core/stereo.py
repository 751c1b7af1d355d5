"""Stereo correspondences with OpenCV SGBM on the images as each sensor sees them (section 3.4.2).

- Cartesian sensor (`cartesian_sensor`, nx x ny RFs): the image is area-averaged onto the RF grid
  (cv2.resize INTER_AREA), SGBM runs on that nx x ny image, and each RF with a valid disparity
  gives one correspondence (its centre in the left image, the matched sub-pixel position in the
  right), mapped back to full-image pixels.
- Log-polar sensor: the image goes through the foveation package's retina, cortex and back
  (`to_cortex` then `to_retina`, the log-polar then inverse transform of section 3.4.2); SGBM
  runs on the rebuilt images and the disparity is read at the left RF centres.

SGBM defaults (foveated_stereo_ros): 80 disparities, window 7, P1 768, P2 1536. The cameras
verge, so points beyond the fixation have negative disparity: `min_disparity` defaults to -40
(the 80 disparities are centred on the fixation). SGBM assumes horizontal epipolar lines; for
the convergent pair this holds near the fixation only (rectifying the verged pair is future
work). Correspondences become 3D points with UT covariances in `StereoPipeline.process`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from foveation_node.core.logpolar import LogPolarRetina

from .sensors import RFSensor, cartesian_sensor, logpolar_sensor
from .ut import SigmaPointTable, StereoRig, UTParams


@dataclass(frozen=True)
class SGBMParams:
    """cv2.StereoSGBM settings (defaults of foveated_stereo_ros; min_disparity see module doc)."""

    num_disparities: int = 80
    block_size: int = 7
    p1: int = 768
    p2: int = 1536
    min_disparity: int = -40
    uniqueness_ratio: int = 10
    disp12_max_diff: int = 1

    def create(self) -> cv2.StereoSGBM:
        if self.num_disparities <= 0 or self.num_disparities % 16:
            raise ValueError(f'num_disparities must be a positive multiple of 16, got '
                             f'{self.num_disparities}')
        if self.block_size < 1 or self.block_size % 2 == 0:
            raise ValueError(f'block_size must be odd and >= 1, got {self.block_size}')
        return cv2.StereoSGBM.create(minDisparity=self.min_disparity,
                                     numDisparities=self.num_disparities,
                                     blockSize=self.block_size, P1=self.p1, P2=self.p2,
                                     disp12MaxDiff=self.disp12_max_diff,
                                     uniquenessRatio=self.uniqueness_ratio)


def to_gray(image: np.ndarray) -> np.ndarray:
    """uint8 single-channel view of an rgb8/mono8 image (ValueError otherwise)."""
    if image.dtype != np.uint8 or image.ndim not in (2, 3):
        raise ValueError(f'expected an 8-bit mono or RGB image, got {image.dtype} {image.shape}')
    if image.ndim == 3:
        if image.shape[2] != 3:
            raise ValueError(f'expected 3 channels, got {image.shape[2]}')
        return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    return image


def compute_disparity(left: np.ndarray, right: np.ndarray,
                      matcher: cv2.StereoSGBM, min_disparity: int) -> np.ndarray:
    """SGBM disparity (float32 px, x_left - x_right); NaN where SGBM found no match."""
    if left.shape != right.shape:
        raise ValueError(f'left and right images differ in size: {left.shape} vs {right.shape}')
    raw = matcher.compute(left, right)
    disp = raw.astype(np.float32) / 16.0
    disp[raw < min_disparity * 16] = np.nan      # SGBM marks misses with (minDisparity - 1) * 16
    return disp


@dataclass
class StereoFrame:
    """Correspondences and their 3D Gaussians (cyclopean/reference frame of the rig)."""

    uv_left: np.ndarray        # (N, 2) px
    uv_right: np.ndarray       # (N, 2) px
    means: np.ndarray          # (N, 3) m, Eq. 3.17
    covs: np.ndarray           # (N, 3, 3) m^2, Eq. 3.18
    colors: np.ndarray         # (N, 3) uint8, the left sensor's view at the RF
    rejected: dict[str, int]


class StereoPipeline:
    """Two images -> correspondences (SGBM on the sensor's view) -> UT points (Eqs. 3.8-3.18).

    n_rf = (nx, ny) RFs for the Cartesian sensor, (rings, wedges) for the log-polar one.
    """

    def __init__(self, width: int, height: int, sensor: str = 'cartesian',
                 n_rf: tuple[int, int] = (200, 200), sgbm: SGBMParams = SGBMParams(),
                 ut: UTParams = UTParams(), retina_kwargs: dict | None = None) -> None:
        self.width, self.height, self.kind = int(width), int(height), sensor
        self.sgbm = sgbm
        self.matcher = sgbm.create()
        self.retina: LogPolarRetina | None = None
        if sensor == 'cartesian':
            self.grid = (int(n_rf[0]), int(n_rf[1]))
            self.sensor: RFSensor = cartesian_sensor(width, height, *self.grid)
            self.rf_ok = np.ones(self.sensor.n_rf, bool)
        elif sensor == 'logpolar':
            self.retina = LogPolarRetina(width, height, rings=n_rf[0], wedges=n_rf[1],
                                         **(retina_kwargs or {}))
            self.sensor = logpolar_sensor(self.retina)
            self.rf_ok = self.retina.rf_valid.reshape(-1).astype(bool)
        else:
            raise ValueError(f"sensor must be 'cartesian' or 'logpolar', got {sensor!r}")
        self.table = SigmaPointTable(self.sensor, self.sensor, ut)

    def view(self, image: np.ndarray) -> np.ndarray:
        """The image as the sensor sees it (Cartesian: the nx x ny grid; log-polar: rebuilt)."""
        if image.shape[:2] != (self.height, self.width):
            raise ValueError(f'image is {image.shape[1]}x{image.shape[0]}, pipeline expects '
                             f'{self.width}x{self.height}')
        if self.retina is None:
            return cv2.resize(image, self.grid, interpolation=cv2.INTER_AREA)
        rebuilt = self.retina.to_retina(self.retina.to_cortex(image))
        return np.clip(np.rint(rebuilt), 0, 255).astype(np.uint8)

    def correspondences(self, left: np.ndarray, right: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """(uv_left, uv_right, left RF index, colours, NaN count) in full-image pixels.

        One candidate per (valid) left RF: its centre, and the centre shifted by the disparity.
        """
        if left.shape != right.shape:
            raise ValueError(f'left and right images differ: {left.shape} vs {right.shape}')
        vl, vr = self.view(left), self.view(right)
        disp = compute_disparity(to_gray(vl), to_gray(vr), self.matcher, self.sgbm.min_disparity)
        idx = np.nonzero(self.rf_ok)[0]
        if self.retina is None:
            d = disp.reshape(-1)[idx] * (self.width / self.grid[0])   # grid px -> image px
            colors = vl.reshape(disp.size, -1)[idx]
        else:
            c = self.sensor.centers[idx]
            xi = np.clip(np.rint(c[:, 0]), 0, self.width - 1).astype(np.int64)
            yi = np.clip(np.rint(c[:, 1]), 0, self.height - 1).astype(np.int64)
            d = disp[yi, xi]
            colors = vl[yi, xi].reshape(idx.size, -1)
        ok = np.isfinite(d)
        uv_l = self.sensor.centers[idx[ok]]
        uv_r = uv_l.copy()
        uv_r[:, 0] -= d[ok]
        colors = colors[ok]
        if colors.shape[1] == 1:
            colors = np.repeat(colors, 3, axis=1)
        return uv_l, uv_r, idx[ok], colors.astype(np.uint8), int(np.sum(~ok))

    def process(self, left: np.ndarray, right: np.ndarray, rig: StereoRig) -> StereoFrame:
        """Images -> UT 3D Gaussians in the rig's reference frame; bad points are counted.

        Points whose sigma points do not all triangulate (parallel rays, behind a camera) are
        dropped and counted under 'degenerate geometry'.
        """
        uv_l, uv_r, il, colors, n_nan = self.correspondences(left, right)
        ir = self.sensor.rf_index(uv_r[:, 0], uv_r[:, 1])
        mean, cov, valid = self.table.transform(rig, uv_l, uv_r, il, ir)
        rejected = {'nan disparity': n_nan, 'degenerate geometry': int(np.sum(~valid))}
        return StereoFrame(uv_l[valid], uv_r[valid], mean[valid], cov[valid], colors[valid],
                           rejected)
