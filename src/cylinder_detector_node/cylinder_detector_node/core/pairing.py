"""Pairing a cloud with what it needs from other inputs, ROS-free: the colour image nearest in
time (the last few images kept, thread-safe) and "up" in the cloud's frame from a transform
lookup."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np


class ImageBuffer:
    """The last `size` images (any objects with a stamp), safe to use from several threads."""

    def __init__(self, size: int, stamp_of: Callable[[Any], float]) -> None:
        self._size = size
        self._stamp_of = stamp_of
        self._lock = threading.Lock()
        self._images: list[Any] = []

    def add(self, image: Any) -> None:
        with self._lock:
            self._images.append(image)
            del self._images[:-self._size]

    def nearest(self, t: float) -> tuple[Any, float] | None:
        """(the image nearest in time to t, how far [s]), or None while none was added."""
        with self._lock:
            images = list(self._images)
        if not images:
            return None
        best = min(images, key=lambda m: abs(self._stamp_of(m) - t))
        return best, abs(self._stamp_of(best) - t)


class TransformLookup(Protocol):
    def lookup_transform(self, target_frame: str, source_frame: str) -> np.ndarray: ...


def up_in_frame(buffer: TransformLookup, up_frame: str,
                cloud_frame: str) -> tuple[float, float, float]:
    """+z of up_frame expressed in cloud_frame (the latest transform); LookupError if tf has no
    chain between the two frames."""
    rot = buffer.lookup_transform(up_frame, cloud_frame)[:3, :3]   # cloud -> up_frame
    up = rot.T @ np.array([0.0, 0.0, 1.0])
    return tuple(float(v) for v in up / np.linalg.norm(up))       # type: ignore[return-value]
