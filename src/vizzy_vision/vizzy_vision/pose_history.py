"""Recent poses of a frame in a world-fixed frame, by time stamp, interpolated in between.

interpolate_poses is the one pose interpolation of the project (spherical linear for the
orientation, linear for the position): PoseHistory answers with it, and so does
vizzy_runtime.tf.TransformBuffer for each /tf edge at a lookup's stamp.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def interpolate_poses(weights: NDArray[np.float64] | list[float], first: FloatArray,
                      second: FloatArray) -> FloatArray:
    """Rigid poses (N, 4, 4) the fraction weights[i] (in [0, 1]) of the way from first[i] to
    second[i]: the orientation along the shortest arc at constant angular velocity (scipy's Slerp,
    r0 * exp(w log(r0^-1 r1)), in one vectorized pass over the N pairs), the position linearly.
    """
    from scipy.spatial.transform import Rotation

    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    a = np.asarray(first, dtype=np.float64).reshape(-1, 4, 4)
    b = np.asarray(second, dtype=np.float64).reshape(-1, 4, 4)
    relative = np.einsum('nji,njk->nik', a[:, :3, :3], b[:, :3, :3])       # r0^-1 r1
    step = Rotation.from_matrix(relative).as_rotvec() * w[:, None]
    out = np.zeros_like(a)
    out[:, :3, :3] = a[:, :3, :3] @ Rotation.from_rotvec(step).as_matrix().reshape(-1, 3, 3)
    out[:, :3, 3] = (1.0 - w)[:, None] * a[:, :3, 3] + w[:, None] * b[:, :3, 3]
    out[:, 3, 3] = 1.0
    return out


class PoseHistory:
    """Recent poses of a camera in a world-fixed frame (orientation (3, 3), position (3,)), by
    time stamp.

    Fed from /tf (the simulator publishes the head's transforms at every image's stamp, and at
    100 Hz); :meth:`at` answers the orientation at an image's stamp by spherical linear
    interpolation between the two samples around it (interpolate_poses; :meth:`pose_at`: the
    4x4 pose, position interpolated linearly). A stamp after the newest
    sample by at most ``max_extrapolation_s`` gets the newest one (the transform for this image
    may arrive just after it); older than the oldest sample, or further ahead: None.
    """

    def __init__(self, max_age_s: float = 2.0, max_extrapolation_s: float = 0.05) -> None:
        self.max_age_s = float(max_age_s)
        self.max_extrapolation_s = float(max_extrapolation_s)
        self._t: list[float] = []
        self._r: list[FloatArray] = []
        self._p: list[FloatArray] = []

    def __len__(self) -> int:
        return len(self._t)

    @property
    def newest(self) -> float | None:
        """The newest sample's time [s], or None when empty."""
        return self._t[-1] if self._t else None

    def clear(self) -> None:
        self._t.clear()
        self._r.clear()
        self._p.clear()

    def add(self, t: float, r: FloatArray, position: FloatArray | None = None) -> None:
        """A sample at time t [s]; out-of-order samples are inserted, duplicates replaced."""
        r = np.asarray(r, dtype=float).reshape(3, 3)
        p = np.zeros(3) if position is None else np.asarray(position, dtype=float).reshape(3)
        i = int(np.searchsorted(self._t, t))
        if i < len(self._t) and self._t[i] == t:
            self._r[i], self._p[i] = r, p
        else:
            self._t.insert(i, float(t))
            self._r.insert(i, r)
            self._p.insert(i, p)
        cut = int(np.searchsorted(self._t, self._t[-1] - self.max_age_s))
        del self._t[:cut], self._r[:cut], self._p[:cut]

    def pose_at(self, t: float) -> FloatArray | None:
        """The 4x4 pose at time t, or None when the history does not cover t."""
        if not self._t or t < self._t[0]:
            return None
        pose = np.eye(4)
        if t >= self._t[-1]:
            if t - self._t[-1] > self.max_extrapolation_s:
                return None
            pose[:3, :3], pose[:3, 3] = self._r[-1], self._p[-1]
            return pose
        i = int(np.searchsorted(self._t, t, side='right'))   # t_(i-1) <= t < t_i
        ends = np.tile(np.eye(4), (2, 1, 1))
        ends[0, :3, :3], ends[0, :3, 3] = self._r[i - 1], self._p[i - 1]
        ends[1, :3, :3], ends[1, :3, 3] = self._r[i], self._p[i]
        w = (t - self._t[i - 1]) / (self._t[i] - self._t[i - 1])
        return interpolate_poses([w], ends[:1], ends[1:])[0]

    def at(self, t: float) -> FloatArray | None:
        """The orientation (3, 3) at time t, or None when the history does not cover t."""
        pose = self.pose_at(t)
        return None if pose is None else pose[:3, :3]


__all__ = ['PoseHistory', 'interpolate_poses']
