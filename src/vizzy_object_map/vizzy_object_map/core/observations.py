"""What the map's inputs become in its frame: boxes and cylinders as GeometryObservations.

Each function takes the sensor's pose (4x4, the sensor frame in the map frame) at the input's
stamp, so a head that moved since is no problem; covariances are isotropic, sized for what each
input can know (section "Observations" of docs/vizzy_object_map.md).
"""

from __future__ import annotations

import math
from collections.abc import Reversible

import numpy as np
from numpy.typing import NDArray

from .object_map import CLUSTER, CYLINDER, CameraView, GeometryObservation

FloatArray = NDArray[np.float64]

#: a cluster's centre: the visible part of an object; sigma = CLUSTER_SIGMA_M + share x extent
CLUSTER_SIGMA_M = 0.01
CLUSTER_SIGMA_SHARE = 0.1
#: a fitted cylinder's centre lies on its axis whatever side was seen
CYLINDER_SIGMA_M = 0.006


def transform_point(pose: FloatArray, point: FloatArray) -> FloatArray:
    """A point (3,) of the pose's child frame in its parent frame."""
    pose = np.asarray(pose, np.float64)
    return pose[:3, :3] @ np.asarray(point, np.float64) + pose[:3, 3]


def box_extents(rotation: FloatArray, size: FloatArray) -> FloatArray:
    """Axis-aligned extents (3,) of a box of full size (3,) turned by rotation (3, 3)."""
    return np.abs(np.asarray(rotation, np.float64)) @ np.asarray(size, np.float64)


def cylinder_extents(axis: FloatArray, radius: float, height: float) -> FloatArray:
    """Axis-aligned extents (3,) of a cylinder with unit axis, radius and height."""
    a = np.asarray(axis, np.float64)
    a = a / max(float(np.linalg.norm(a)), 1e-12)
    return height * np.abs(a) + 2.0 * radius * np.sqrt(np.clip(1.0 - a * a, 0.0, 1.0))


def cluster_observation(sensor_pose: FloatArray, centre: FloatArray, rotation: FloatArray,
                        size: FloatArray, stamp: float) -> GeometryObservation:
    """A segmented object's box (centre (3,), rotation (3, 3) and full size (3,) in the sensor
    frame) in the map frame."""
    pose = np.asarray(sensor_pose, np.float64)
    extents = box_extents(pose[:3, :3] @ np.asarray(rotation, np.float64), size)
    sigma = CLUSTER_SIGMA_M + CLUSTER_SIGMA_SHARE * float(np.max(extents))
    return GeometryObservation(transform_point(pose, centre), np.eye(3) * sigma ** 2, extents,
                               float(stamp), CLUSTER)


def cylinder_observation(sensor_pose: FloatArray, centre: FloatArray, axis: FloatArray,
                         radius: float, height: float, stamp: float) -> GeometryObservation:
    """A fitted cylinder (centre, unit axis in the sensor frame; radius, height [m]) in the map
    frame."""
    pose = np.asarray(sensor_pose, np.float64)
    axis_map = pose[:3, :3] @ np.asarray(axis, np.float64)
    return GeometryObservation(transform_point(pose, centre),
                               np.eye(3) * CYLINDER_SIGMA_M ** 2,
                               cylinder_extents(axis_map, radius, height), float(stamp), CYLINDER)




def surface_point_at(view: CameraView, u: float, v: float, points: FloatArray,
                     radius_px: float = 6.0, min_points: int = 5,
                     thickness_m: float = 0.03) -> tuple[FloatArray, FloatArray] | None:
    """The surface a depth sensor saw at pixel (u, v) of view: (point (3,), covariance (3, 3))
    in the map frame, from points (N, 3) (map frame) projecting within radius_px of the pixel;
    None with fewer than min_points there. The front surface wins (what the camera sees at that
    pixel): the points within thickness_m behind the 10th percentile of their depths."""
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    if len(pts) < min_points:
        return None
    uv, z = view.project(pts)
    with np.errstate(invalid='ignore'):
        near = (z > 0) & ((uv[:, 0] - u) ** 2 + (uv[:, 1] - v) ** 2 <= radius_px ** 2)
    if np.count_nonzero(near) < min_points:
        return None
    depth = z[near]
    front = depth <= np.percentile(depth, 10) + thickness_m
    if np.count_nonzero(front) < min_points:
        return None
    chosen = pts[near][front]
    point = np.median(chosen, axis=0)
    spread = float(np.mean(np.std(chosen, axis=0)))
    sigma = max(0.01, spread) + 0.01 * float(np.median(depth[front]))
    return point, np.eye(3) * sigma ** 2


def fixation_at(states: Reversible[tuple[float, FloatArray | None, bool]], t: float,
                max_age_s: float) -> FloatArray | None:
    """Where both optical axes met at time t (depth from vergence), from gaze states (stamp,
    fixation point or None, eyes moving) oldest first: the latest state at or before t, if the
    eyes were still and it is at most max_age_s old; else None."""
    for stamp, point, moving in reversed(states):
        if stamp <= t + 1e-3:
            ok = point is not None and not moving and t - stamp <= max_age_s
            return point if ok else None
    return None


__all__ = ['CLUSTER_SIGMA_M', 'CLUSTER_SIGMA_SHARE', 'CYLINDER_SIGMA_M', 'box_extents',
           'cluster_observation', 'cylinder_extents', 'cylinder_observation', 'fixation_at',
           'surface_point_at', 'transform_point']


def finite_points(cloud: NDArray[np.void], max_points: int) -> FloatArray:
    """The finite (x, y, z) of a structured cloud as (N, 3), evenly thinned to at most
    max_points (an even thinning keeps the surfaces)."""
    xyz = np.stack([cloud['x'], cloud['y'], cloud['z']], axis=1).astype(np.float64)
    xyz = xyz[np.isfinite(xyz).all(axis=1)]
    if len(xyz) > max_points:
        xyz = xyz[:: int(math.ceil(len(xyz) / max_points))]
    return xyz
