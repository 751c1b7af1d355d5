"""Ground-plane plausibility of person boxes: does a box stand on the floor at a person's size?

A sliding-window person detector fires on anything with a person-like gradient pattern; on the
simulator's tabletop HOG fires persistently on objects on the table, which then pass the
track-age and hit-count gates like a standing person would. A calibrated camera with a known
pose rules most of them out: a person stands on the floor, so the ray through the bottom
centre of their box meets the floor plane where their feet are, and that distance turns the
box's pixel height into a metric height. A can on a table 0.72 m up gives a foot ray that meets
the floor far behind the can (or not at all) and an implied height that is no person's; as
the head moves, the implied foot point and height of such a box also wander, while a person's
stay put. The thesis (chapter 5) tracked with a static, uncalibrated camera and had no such
check; this is an extension.

Geometry (all vectorized over boxes). For a box (x, y, w, h) with bottom centre
``(u, v_b) = (x + w/2, y + h)`` and top ``v_t = y``, the camera's optical frame at pose
``(R, c)`` in a world frame with z up, and the floor at ``z = z_f``:

- foot ray ``d = R K^-1 [u, v_b, 1]^T`` (optical z component 1, so the ray parameter is the
  depth along the optical axis); it meets the floor at ``lambda = (z_f - c_z) / d_z`` if
  ``d_z < 0`` (below the horizon), else never;
- the person is a vertical segment ``F + H e_z`` on the foot point ``F = c + lambda d``; its
  top projects onto row ``v_t`` when, with ``g = K R^T e_z`` (the image of the world's up
  direction), ``v_t (lambda + H g_3) = lambda v_b + H g_2``, i.e.

      H = lambda (v_b - v_t) / (v_t g_3 - g_2).

For a level camera ``g = (0, -f_y, 0)`` and this is the pinhole ``H = h lambda / f_y``; for a
tilted one it is exact where the pinhole formula is off by about the cosine of the tilt (and
more towards the image's edges). A non-positive denominator (the top row at or beyond the
vanishing point of verticals), or a solution whose top lies behind the camera
(``lambda + H g_3 <= 0``), means no standing segment fits: the height is infinite.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class ImpliedSize(NamedTuple):
    """height (n,) metric height [m] of a person standing on the floor at each box (inf where
    none fits, NaN where the foot ray does not meet the floor in front of the camera);
    depth (n,) the foot point's depth along the optical axis [m] (NaN likewise)."""

    height: FloatArray
    depth: FloatArray


def implied_size(boxes: FloatArray, k: FloatArray, camera_pose: FloatArray,
                 floor_z: float) -> ImpliedSize:
    """Metric height and foot depth of a person standing on the floor at each box.

    boxes: (n, 4) x, y, w, h object boxes (the person's extent, not the detector's window) in
    pixels; k: (3, 3) intrinsics; camera_pose: (4, 4) the optical frame (z forward, y down) in
    a world frame whose z axis points up; floor_z: the floor's height in that frame.
    """
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
    k = np.asarray(k, dtype=float).reshape(3, 3)
    pose = np.asarray(camera_pose, dtype=float).reshape(4, 4)
    rot, centre = pose[:3, :3], pose[:3, 3]
    u = boxes[:, 0] + boxes[:, 2] / 2.0
    v_top = boxes[:, 1]
    v_bottom = boxes[:, 1] + boxes[:, 3]
    pixels = np.stack([u, v_bottom, np.ones_like(u)], axis=1)           # (n, 3)
    rays = np.linalg.solve(k, pixels.T).T @ rot.T                       # world directions
    drop = floor_z - centre[2]
    with np.errstate(divide='ignore', invalid='ignore'):
        depth = np.where(rays[:, 2] < 0.0, drop / rays[:, 2], np.nan)
        depth = np.where(depth > 0.0, depth, np.nan)                    # floor below the camera
        g = k @ rot.T @ np.array([0.0, 0.0, 1.0])                       # image of world up
        denom = v_top * g[2] - g[1]
        height = np.where(denom > 0.0, depth * (v_bottom - v_top) / denom, np.inf)
        # the top must be in front of the camera too (else the row is hit from behind)
        height = np.where(depth + height * g[2] > 0.0, height, np.inf)
    height = np.where(np.isnan(depth), np.nan, height)
    return ImpliedSize(height=height, depth=depth)


def plausible_height(height: FloatArray, height_range: tuple[float, float]) -> BoolArray:
    """Mask of implied heights inside [lo, hi] (NaN and inf are not)."""
    h = np.asarray(height, dtype=float)
    lo, hi = height_range
    with np.errstate(invalid='ignore'):
        return np.isfinite(h) & (h >= lo) & (h <= hi)


class ConsistencyGate:
    """Per-track memory of the implied heights: a track is plausible while, over its last
    ``frames`` checks (all of them while it has had fewer), every implied height was in
    ``height_range`` and the largest was at most ``max_ratio`` times the smallest.

    One in-range frame is not enough: while the head moves, the implied foot point of an
    object above the floor slides along its ray and its implied height sweeps through the
    person range (on the tabletop, e.g. 1.36, 1.42, 2.42, 2.45, 4.94 m over five frames); a
    person's stays put up to the detector's noise (the sim's walkers: max/min over five
    frames 1.03 median, 1.18 at the 99th percentile).
    """

    def __init__(self, height_range: tuple[float, float], frames: int = 5,
                 max_ratio: float = 1.3) -> None:
        if frames < 1:
            raise ValueError(f'frames must be >= 1, got {frames}')
        if not max_ratio >= 1.0:
            raise ValueError(f'max_ratio must be >= 1, got {max_ratio}')
        self.height_range = (float(height_range[0]), float(height_range[1]))
        self.frames = int(frames)
        self.max_ratio = float(max_ratio)
        self._heights: dict[int, list[float]] = {}     # id -> its last `frames` heights

    def update(self, ids: NDArray[np.int64], heights: FloatArray) -> BoolArray:
        """Record this frame's implied heights of the tracks ids; forget tracks not listed;
        return the plausibility (n,) of each."""
        ids_list = [int(i) for i in np.asarray(ids).ravel()]
        values = np.asarray(heights, dtype=float).ravel()
        if len(ids_list) != values.size:
            raise ValueError(f'{len(ids_list)} ids but {values.size} heights')
        alive = set(ids_list)
        for tid in [t for t in self._heights if t not in alive]:
            del self._heights[tid]
        for tid, h in zip(ids_list, values.tolist(), strict=True):
            self._heights.setdefault(tid, []).append(h)
            del self._heights[tid][:-self.frames]
        return self.plausible(ids_list)

    def plausible(self, ids: list[int] | NDArray[np.int64]) -> BoolArray:
        """Plausibility of tracks ids from the checks so far (True for an unchecked track)."""
        out = np.ones(len(np.asarray(ids).ravel()), dtype=bool)
        for k, tid in enumerate(np.asarray(ids).ravel().tolist()):
            recent = np.array(self._heights.get(int(tid), [])[-self.frames:])
            if recent.size:
                ok = plausible_height(recent, self.height_range)
                out[k] = bool(ok.all()) and recent.max() <= self.max_ratio * recent.min()
        return out

    def clear(self) -> None:
        self._heights.clear()
