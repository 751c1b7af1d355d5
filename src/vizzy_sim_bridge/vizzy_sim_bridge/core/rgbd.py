"""The simulated RGB-D sensor: depth noise model and organized x y z rgb point clouds.

Depth noise (Asus Xtion / Kinect v1 structured light): the axial error grows with the square of
the range, sigma_z = 1.425e-3 z^2 [m] (Khoshelham & Elberink 2012, "Accuracy and resolution of
Kinect depth data for indoor mapping applications", Sensors 12(2):1437-1454): 1.4 mm at 1 m,
2.3 cm at 4 m. Outside the working range (default
0.5-3.5 m: ASUS gives 0.8-3.5 m, OpenNI devices return depth from about 0.5 m) or where nothing
was hit, depth is NaN, as the OpenNI driver reports.

The point cloud is organized (height x width, one point per pixel, NaN x y z where depth is
invalid), in the sensor's optical frame, with the PCL/ROS packed colour: rgb is a float32 whose
bits are 0x00RRGGBB.
"""

from __future__ import annotations

import numpy as np

from vizzy_vision.pointcloud import pack_rgb

XTION_SIGMA_COEFFICIENT = 1.425e-3   # [1/m]: sigma_z = c z^2 (Khoshelham & Elberink 2012)
XTION_MIN_RANGE, XTION_MAX_RANGE = 0.5, 3.5   # [m]

CLOUD_DTYPE = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('rgb', '<f4')])


def depth_sigma(z: np.ndarray | float, coefficient: float = XTION_SIGMA_COEFFICIENT) -> np.ndarray:
    """Standard deviation [m] of the depth error at range z [m]."""
    z = np.asarray(z, dtype=np.float64)
    return coefficient * z * z


def noisy_depth(depth: np.ndarray, rng: np.random.Generator | None,
                coefficient: float = XTION_SIGMA_COEFFICIENT, min_range: float = XTION_MIN_RANGE,
                max_range: float = XTION_MAX_RANGE) -> np.ndarray:
    """depth [m] (float32, H x W) with range-dependent Gaussian noise; NaN where nothing was hit
    or the (noisy) depth is outside [min_range, max_range].

    rng None (or coefficient 0) adds no noise; the range limits still apply.
    """
    z = np.array(depth, dtype=np.float32)
    hit = np.isfinite(z)
    if rng is not None and coefficient > 0.0:
        zv = z[hit]
        # zv + (c zv zv) n, in one temporary (same operations and order: the same bits)
        noise = coefficient * zv
        noise *= zv
        noise *= rng.standard_normal(zv.shape, dtype=np.float32)
        noise += zv
        z[hit] = noise
    z[~hit | (z < min_range) | (z > max_range)] = np.nan   # the sensor's range, after the noise
    return z


class DepthProjector:
    """Back-projects depth images of one pinhole camera (K) into organized point clouds."""

    def __init__(self, k: np.ndarray, width: int, height: int) -> None:
        k = np.asarray(k, dtype=np.float64)
        self.width, self.height = int(width), int(height)
        u = np.arange(self.width, dtype=np.float64)
        v = np.arange(self.height, dtype=np.float64)
        self._rx = ((u - k[0, 2]) / k[0, 0]).astype(np.float32)[None, :]
        self._ry = ((v - k[1, 2]) / k[1, 1]).astype(np.float32)[:, None]

    def cloud(self, depth: np.ndarray, rgb: np.ndarray) -> np.ndarray:
        """Organized H x W structured array (CLOUD_DTYPE): x = (u - cx) z / fx,
        y = (v - cy) z / fy, z = depth (NaN stays NaN), rgb packed."""
        if depth.shape != (self.height, self.width) or rgb.shape[:2] != depth.shape:
            raise ValueError(f'depth {depth.shape} / rgb {rgb.shape} do not match the sensor '
                             f'{self.height}x{self.width}')
        z = np.asarray(depth, dtype=np.float32)
        out = np.empty(z.shape, dtype=CLOUD_DTYPE)
        out['x'] = z * self._rx
        out['y'] = z * self._ry
        out['z'] = z
        out['rgb'] = pack_rgb(rgb)
        return out


__all__ = ['CLOUD_DTYPE', 'DepthProjector', 'XTION_MAX_RANGE', 'XTION_MIN_RANGE',
           'XTION_SIGMA_COEFFICIENT', 'depth_sigma', 'noisy_depth']
