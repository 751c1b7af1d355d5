"""Left/right image pairing by stamp (ROS-free: the messages are opaque, their stamps [s] come from
a function the caller gives). The newest pair wins: pairing drops every older waiting image."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

EYES = ('left', 'right')
# Images of one eye kept waiting for the other eye's image with the same stamp.
UNPAIRED_KEPT = 3


@dataclass
class Pair:
    """A left and a right image with the same stamp (within max_stamp_skew_s); stamp: the left
    image's [s]."""

    left: Any
    right: Any
    stamp: float


class StereoPairer:
    """Images of each eye waiting for their partner (not thread-safe: the caller locks)."""

    def __init__(self, stamp_of: Callable[[Any], float], kept: int = UNPAIRED_KEPT) -> None:
        self._stamp_of = stamp_of
        self._kept = kept
        self.unpaired: dict[str, list[Any]] = {e: [] for e in EYES}   # waiting, oldest first

    def add(self, eye: str, msg: Any, skew: float) -> tuple[Pair | None, dict[str, list[Any]]]:
        """(the pair msg completes or None, the images dropped unpaired per eye)."""
        stamp_of = self._stamp_of
        other_eye = 'right' if eye == 'left' else 'left'
        t = stamp_of(msg)
        mine, others = self.unpaired[eye], self.unpaired[other_eye]
        match = next((m for m in others if abs(stamp_of(m) - t) <= skew), None)
        if match is None:
            # wait for the partner (the eyes' images may arrive interleaved); the oldest
            # waiting image goes when too many wait: its partner was lost
            mine.append(msg)
            unpaired = {eye: mine[:-self._kept]}
            del mine[:-self._kept]
            return None, unpaired
        # pair; older images of either eye can no longer win (newest pair wins)
        t_other = stamp_of(match)
        unpaired = {eye: list(mine), other_eye: [m for m in others if stamp_of(m) < t_other]}
        others[:] = [m for m in others if stamp_of(m) > t_other]
        mine.clear()
        left_msg, right_msg = (msg, match) if eye == 'left' else (match, msg)
        return Pair(left_msg, right_msg, stamp_of(left_msg)), unpaired
