"""The node's bookkeeping: when each track was born and how many consecutive frames it has gone
unmatched (from the tracker's hit counts frame after frame), the measured frame period, and the
gaze's fixation point. ROS-free."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from vizzy_vision.rays import back_project


class TrackBook:
    """Ages (frames since birth) and frames_lost of every track, tentative ones included."""

    def __init__(self) -> None:
        self.born: dict[int, int] = {}          # track id -> frame index it was born
        self.hits: dict[int, int] = {}          # track id -> hits seen last frame
        self.lost: dict[int, int] = {}          # track id -> consecutive frames unmatched

    def clear(self) -> None:
        self.born.clear()
        self.hits.clear()
        self.lost.clear()

    def update(self, ids: Iterable[int], hits: Iterable[int], frame: int) -> None:
        """The tracker's live tracks (ids, their hit counts) at frame index frame."""
        alive = set()
        for tid, h in zip(ids, hits, strict=True):
            alive.add(tid)
            if tid not in self.born:
                self.born[tid] = frame
                self.lost[tid] = 0
            else:
                self.lost[tid] = 0 if h > self.hits.get(tid, 0) else self.lost[tid] + 1
            self.hits[tid] = h
        for d in (self.born, self.hits, self.lost):
            for tid in [k for k in d if k not in alive]:
                del d[tid]

    def age(self, tid: int, frame: int) -> int:
        """Frames since tid was born (0 for an unknown track)."""
        return frame - self.born.get(tid, frame)

    def frames_lost(self, tid: int) -> int:
        return self.lost.get(tid, 0)

    def established(self, ids: Iterable[int], hits: np.ndarray, frame: int, min_hits: int,
                    min_age: int) -> np.ndarray:
        """Mask of the tracks detected at least min_hits times and at least min_age frames old."""
        ages = np.array([self.age(int(i), frame) for i in ids], dtype=np.int64)
        return (hits >= min_hits) & (ages >= min_age)


class FramePeriod:
    """The frame period [s] measured from the images' stamps (nominal until two arrived)."""

    def __init__(self, nominal_s: float) -> None:
        self.period_s = nominal_s
        self._last_stamp: float | None = None

    def update(self, t: float) -> None:
        """A processed frame's stamp t [s] (0: unstamped)."""
        if self._last_stamp is not None and t > self._last_stamp:
            dt = t - self._last_stamp
            if dt < 5.0:                      # a pause (a bag restarted) is not a frame period
                self.period_s += 0.2 * (dt - self.period_s)
        self._last_stamp = t if t > 0 else None


def gaze_point(boxes: np.ndarray, k: Sequence[float], depth_m: float,
               pose: np.ndarray | None) -> tuple[float, float, float]:
    """The point depth_m along the ray through the boxes' (x, y, w, h) mean centre: in the
    camera's optical frame, or through pose (4x4, the camera in the world) in the world."""
    u, v = (boxes[:, :2] + boxes[:, 2:] / 2.0).mean(axis=0)
    p = back_project(float(u), float(v), k, depth_m)
    if pose is not None:
        q = pose[:3, :3] @ np.asarray(p) + pose[:3, 3]
        p = float(q[0]), float(q[1]), float(q[2])
    return p
