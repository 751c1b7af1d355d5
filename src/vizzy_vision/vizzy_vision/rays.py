"""Rays through pixels: the pinhole back-projection every node that turns a pixel into a gaze
target uses (the foveation node's saccades, the tracker's fixations)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def pixel_rays(u: np.ndarray | float, v: np.ndarray | float, k: Sequence[float] | np.ndarray
               ) -> np.ndarray:
    """Unit rays (..., 3) through pixels (u, v) in the camera's optical frame (x right, y down,
    z forward), for a camera matrix k (3x3, or row-major 9 as CameraInfo.k)."""
    kk = np.asarray(k, dtype=np.float64).reshape(-1)
    fx, cx, fy, cy = kk[0], kk[2], kk[4], kk[5]
    u_arr, v_arr = np.broadcast_arrays(np.asarray(u, np.float64), np.asarray(v, np.float64))
    rays = np.stack([(u_arr - cx) / fx, (v_arr - cy) / fy, np.ones_like(u_arr)], axis=-1)
    return rays / np.linalg.norm(rays, axis=-1, keepdims=True)


def back_project(u: float, v: float, k: Sequence[float] | np.ndarray,
                 distance: float) -> tuple[float, float, float]:
    """The point at distance [m] along the ray of pixel (u, v), in the camera's optical frame."""
    p = distance * pixel_rays(u, v, k)
    return (float(p[0]), float(p[1]), float(p[2]))


__all__ = ['back_project', 'pixel_rays']
