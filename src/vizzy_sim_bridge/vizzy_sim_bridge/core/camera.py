"""Pinhole camera model of the simulated eyes (sensor_msgs/CameraInfo conventions)."""

from __future__ import annotations

import math

import numpy as np


def camera_matrix(width: int, height: int, hfov_deg: float) -> np.ndarray:
    """Intrinsic matrix K (3x3) of a square-pixel pinhole camera with horizontal FOV hfov_deg.

    fx = fy = (width / 2) / tan(hfov / 2); the principal point is the image centre in the
    ROS pixel convention (pixel centres at integer coordinates).
    """
    if width <= 0 or height <= 0:
        raise ValueError(f'image size must be positive, got {width}x{height}')
    if not 0.0 < hfov_deg < 180.0:
        raise ValueError(f'horizontal FOV must be in (0, 180) degrees, got {hfov_deg}')
    f = 0.5 * width / math.tan(math.radians(hfov_deg) / 2.0)
    return np.array([[f, 0.0, (width - 1) / 2.0],
                     [0.0, f, (height - 1) / 2.0],
                     [0.0, 0.0, 1.0]])


def projection_matrix(k: np.ndarray, baseline_m: float = 0.0) -> np.ndarray:
    """Projection matrix P (3x4) = [K | (Tx, 0, 0)] with Tx = -fx * baseline_m.

    baseline_m is 0 for the left (reference) camera and the stereo baseline for the right one,
    as in sensor_msgs/CameraInfo.
    """
    p = np.zeros((3, 4))
    p[:, :3] = k
    p[0, 3] = -k[0, 0] * baseline_m
    return p
