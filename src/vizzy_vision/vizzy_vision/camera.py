"""Pinhole camera model of the simulated eyes and RGB-D sensor (sensor_msgs/CameraInfo conventions).

ROS pixel convention: pixel centres at integer coordinates, so the centre of a W x H image is
((W - 1) / 2, (H - 1) / 2). MuJoCo renders an ideal pinhole camera whose optical axis passes
through the image centre and whose vertical field of view is the camera's fovy, with square
pixels; fovy_deg() gives the fovy that makes the horizontal field of view hfov_deg.
"""

from __future__ import annotations

import math

import numpy as np

# The robot's eye cameras (PointGrey Dragonfly2 on Vizzy): 640x480 at 30 Hz, horizontal FOV
# 85.4 deg (1.4912 rad; vizzy_description head.gazebo.xacro / issue 3), no distortion.
EYE_WIDTH, EYE_HEIGHT, EYE_HFOV_DEG, EYE_RATE_HZ = 640, 480, 85.4, 30.0
# Asus Xtion PRO Live-like RGB-D sensor: 640x480, 58 deg horizontal FOV (45 deg vertical),
# 30 Hz (ASUS Xtion PRO Live specification).
RGBD_WIDTH, RGBD_HEIGHT, RGBD_HFOV_DEG = 640, 480, 58.0


def focal_length(width: int, hfov_deg: float) -> float:
    """fx = fy [px] of a square-pixel camera width px wide with horizontal FOV hfov_deg."""
    return 0.5 * width / math.tan(math.radians(hfov_deg) / 2.0)


def fovy_deg(width: int, height: int, hfov_deg: float) -> float:
    """MuJoCo's camera fovy [deg] (vertical FOV) giving horizontal FOV hfov_deg at width x
    height."""
    return math.degrees(2.0 * math.atan(0.5 * height / focal_length(width, hfov_deg)))


def camera_matrix(width: int, height: int, hfov_deg: float) -> np.ndarray:
    """Intrinsic matrix K (3x3) of a square-pixel pinhole camera with horizontal FOV hfov_deg.

    fx = fy = (width / 2) / tan(hfov / 2); the principal point is the image centre in the
    ROS pixel convention (pixel centres at integer coordinates).
    """
    if width <= 0 or height <= 0:
        raise ValueError(f'image size must be positive, got {width}x{height}')
    if not 0.0 < hfov_deg < 180.0:
        raise ValueError(f'horizontal FOV must be in (0, 180) degrees, got {hfov_deg}')
    f = focal_length(width, hfov_deg)
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


def project(k: np.ndarray, camera_pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Pixel coordinates (N x 2) of points (N x 3, in the frame camera_pose is expressed in).

    camera_pose is the 4x4 pose of the optical frame; points behind the camera get NaN.
    """
    pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
    inv = np.linalg.inv(camera_pose)
    cam = pts @ inv[:3, :3].T + inv[:3, 3]
    uvw = cam @ np.asarray(k, dtype=np.float64).T
    with np.errstate(divide='ignore', invalid='ignore'):
        uv = uvw[:, :2] / uvw[:, 2:3]
    uv[cam[:, 2] <= 0.0] = np.nan
    return uv
