"""Stereo correspondences with OpenCV SGBM on the images as each sensor sees them (section 3.4.2).

- Cartesian sensor (`cartesian_sensor`, nx x ny RFs): the image is area-averaged onto the RF grid
  (cv2.resize INTER_AREA), SGBM runs on that nx x ny image over the window narrowed on a coarse
  pyramid level (`multires.coarse_window`), and each RF with a valid disparity
  gives one correspondence (its centre in the left image, the matched sub-pixel position in the
  right), mapped back to full-image pixels.
- Log-polar sensor: SGBM at the resolution its RFs need (`multires.FoveatedSGBM`: full
  resolution in the fovea, pyramid level l where the RFs are 2^l px apart, each level on the crop
  its annulus needs, the search range narrowed coarse-to-fine); the disparity is read at the left
  RF centres, the colours are the left RF responses (`to_cortex`). Until issue 13 the images were
  rebuilt from the cortex at full resolution and matched there, which cost as much as plain SGBM.

SGBM settings (`multires.SGBMParams`, foveated_stereo_ros): 80 disparities, window 7, P1 768,
P2 1536. The search window is an argument of `process` / `correspondences` (a
`multires.DisparityWindow`, e.g. `multires.disparity_window` of the rig and a depth range);
without one, [min_disparity, min_disparity + num_disparities) of the SGBM parameters, -40 / 80 by
default: the cameras verge, so points beyond the fixation have negative disparity. SGBM assumes
horizontal epipolar lines; for the convergent pair this holds near the fixation only (rectifying
the verged pair is future work). Correspondences become 3D points with UT covariances in
`StereoPipeline.process`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vizzy_vision.logpolar import LogPolarRetina

from .geometry import epipolar_distance
from .multires import (  # noqa: F401 (re-exported)
    DisparityWindow,
    FoveatedSGBM,
    SGBMParams,
    coarse_window,
    sgbm_window,
    to_gray,
)
from .sensors import RFSensor, cartesian_sensor, fovea_radius, logpolar_sensor
from .ut import SigmaPointTable, StereoRig, UTParams

# least distance from the epipolar line (px) at which a match is dropped (see process)
EPIPOLAR_TOLERANCE_PX = 1.0
# the default settings (frozen dataclasses: one shared instance is safe)
_SGBM_DEFAULTS = SGBMParams()
_UT_DEFAULTS = UTParams()


def compute_disparity(left: np.ndarray, right: np.ndarray,
                      matcher: cv2.StereoSGBM, min_disparity: int) -> np.ndarray:
    """Plain SGBM disparity (float32 px, x_left - x_right); NaN where SGBM found no match."""
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
                 n_rf: tuple[int, int] = (200, 200), sgbm: SGBMParams = _SGBM_DEFAULTS,
                 ut: UTParams = _UT_DEFAULTS, retina_kwargs: dict | None = None) -> None:
        self.width, self.height, self.kind = int(width), int(height), sensor
        self.sgbm = sgbm
        self.retina: LogPolarRetina | None = None
        self.matcher: FoveatedSGBM | None = None
        if sensor == 'cartesian':
            self.grid = (int(n_rf[0]), int(n_rf[1]))
            self.sensor: RFSensor = cartesian_sensor(width, height, *self.grid)
            self.rf_ok = np.ones(self.sensor.n_rf, bool)
        elif sensor == 'logpolar':
            self.retina = LogPolarRetina(width, height, rings=n_rf[0], wedges=n_rf[1],
                                         **(retina_kwargs or {}))
            self.sensor = logpolar_sensor(self.retina)
            self.rf_ok = self.retina.rf_valid.reshape(-1).astype(bool)
            self.matcher = FoveatedSGBM(width, height, fovea_radius(self.retina),
                                        self.retina.center, params=sgbm)
            c = self.sensor.centers
            self._rf_pixel = (np.clip(np.rint(c[:, 1]), 0, height - 1).astype(np.int64) * width
                              + np.clip(np.rint(c[:, 0]), 0, width - 1).astype(np.int64))
        else:
            raise ValueError(f"sensor must be 'cartesian' or 'logpolar', got {sensor!r}")
        self.table = SigmaPointTable(self.sensor, self.sensor, ut)
        self.last_ranges: dict[str, list[float]] = {}

    def view(self, image: np.ndarray) -> np.ndarray:
        """The image as the sensor sees it (Cartesian: the nx x ny grid; log-polar: rebuilt)."""
        self._check(image)
        if self.retina is None:
            return cv2.resize(image, self.grid, interpolation=cv2.INTER_AREA)
        rebuilt = self.retina.to_retina(self.retina.to_cortex(image))
        return np.clip(np.rint(rebuilt), 0, 255).astype(np.uint8)

    def _check(self, image: np.ndarray) -> None:
        if image.shape[:2] != (self.height, self.width):
            raise ValueError(f'image is {image.shape[1]}x{image.shape[0]}, pipeline expects '
                             f'{self.width}x{self.height}')

    def correspondences(self, left: np.ndarray, right: np.ndarray,
                        window: DisparityWindow | None = None
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """(uv_left, uv_right, left RF index, colours, NaN count) in full-image pixels.

        One candidate per (valid) left RF: its centre, and the centre shifted by the disparity.
        window: the disparities searched (default: the SGBM parameters' range).
        """
        if left.shape != right.shape:
            raise ValueError(f'left and right images differ: {left.shape} vs {right.shape}')
        self._check(left)
        window = DisparityWindow.from_sgbm(self.sgbm) if window is None else window
        idx = np.nonzero(self.rf_ok)[0]
        if self.retina is None:
            window = coarse_window(left, right, window, self.sgbm)     # the range, searched
            vl, vr = self.view(left), self.view(right)
            sx = self.width / self.grid[0]
            lo, num = window.scaled(sx)
            disp = sgbm_window(to_gray(vl), to_gray(vr), lo, num, self.sgbm,
                               border=window.hi / sx)
            self.last_ranges = {'grid': [lo * sx, (lo + num) * sx]}
            d = disp.reshape(-1)[idx] * sx                             # grid px -> image px
            colors = vl.reshape(disp.size, -1)[idx]
        else:
            assert self.matcher is not None
            result = self.matcher.compute(left, right, window)
            self.last_ranges = result.ranges
            d = result.disparity.reshape(-1)[self._rf_pixel[idx]]
            cortex = self.retina.to_cortex(left)                      # the left RF responses
            colors = np.clip(np.rint(cortex.reshape(self.sensor.n_rf, -1)[idx]), 0, 255)
        ok = np.isfinite(d)
        uv_l = self.sensor.centers[idx[ok]]
        uv_r = uv_l.copy()
        uv_r[:, 0] -= d[ok]
        colors = colors[ok]
        if colors.shape[1] == 1:
            colors = np.repeat(colors, 3, axis=1)
        return uv_l, uv_r, idx[ok], colors.astype(np.uint8), int(np.sum(~ok))

    def process(self, left: np.ndarray, right: np.ndarray, rig: StereoRig,
                window: DisparityWindow | None = None) -> StereoFrame:
        """Images -> UT 3D Gaussians in the rig's reference frame; bad points are counted.

        SGBM matches along image rows; a match farther from the epipolar line of its left point
        than the left RF's spacing (2 sigma, at least EPIPOLAR_TOLERANCE_PX) cannot be a point the
        rig sees (a verged pair's vertical disparity away from the meridians) and is dropped
        ('off the epipolar line'). Points whose sigma points do not all triangulate (parallel
        rays, behind a camera) are dropped and counted under 'degenerate geometry'.
        """
        uv_l, uv_r, il, colors, n_nan = self.correspondences(left, right, window)
        off = epipolar_distance(uv_l, uv_r, rig.k_left, rig.k_right, rig.pose_left,
                                rig.pose_right) > np.maximum(EPIPOLAR_TOLERANCE_PX,
                                                             2.0 * self.sensor.sigmas[il])
        keep = ~off
        uv_l, uv_r, il, colors = uv_l[keep], uv_r[keep], il[keep], colors[keep]
        ir = self.sensor.rf_index(uv_r[:, 0], uv_r[:, 1])
        mean, cov, valid = self.table.transform(rig, uv_l, uv_r, il, ir)
        rejected = {'nan disparity': n_nan, 'off the epipolar line': int(np.sum(off)),
                    'degenerate geometry': int(np.sum(~valid))}
        return StereoFrame(uv_l[valid], uv_r[valid], mean[valid], cov[valid], colors[valid],
                           rejected)
