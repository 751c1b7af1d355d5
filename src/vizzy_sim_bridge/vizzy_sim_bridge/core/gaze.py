"""Validation and arbitration of gaze requests (the ROS-free half of the gaze controller)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum


class GazeStatus(Enum):
    """Outcome of a gaze request; names match active_vision_msgs/GazeState's STATUS_* constants."""

    OK = 'OK'
    IDLE = 'IDLE'
    REJECTED_NAN = 'REJECTED_NAN'
    REJECTED_UNKNOWN_FRAME = 'REJECTED_UNKNOWN_FRAME'
    REJECTED_UNREACHABLE = 'REJECTED_UNREACHABLE'
    REJECTED_INVALID = 'REJECTED_INVALID'
    PREEMPTED = 'PREEMPTED'


Check = tuple[GazeStatus, str]


def check_fixation(point: Sequence[float], frame_id: str, min_distance: float,
                   max_distance: float) -> Check:
    """Is a fixation point usable? The distance is measured from frame_id's origin."""
    if not all(math.isfinite(float(c)) for c in point):
        return GazeStatus.REJECTED_NAN, f'fixation_point {tuple(point)} is not finite'
    if not frame_id:
        return GazeStatus.REJECTED_UNKNOWN_FRAME, 'header.frame_id is empty'
    dist = math.sqrt(sum(float(c) ** 2 for c in point))
    if not min_distance <= dist <= max_distance:
        return (GazeStatus.REJECTED_UNREACHABLE,
                f'fixation_point is {dist:.3f} m from {frame_id!r}, outside '
                f'[{min_distance}, {max_distance}] m')
    return GazeStatus.OK, ''


def check_joint_targets(names: Sequence[str], positions: Sequence[float],
                        limits: Mapping[str, tuple[float, float]]) -> Check:
    """Are joint targets well formed, finite and within limits?"""
    if len(names) != len(positions):
        return (GazeStatus.REJECTED_INVALID,
                f'{len(names)} joint_names but {len(positions)} joint_positions')
    if not names:
        return GazeStatus.REJECTED_INVALID, 'no joint_names given'
    if len(set(names)) != len(names):
        return GazeStatus.REJECTED_INVALID, f'repeated joint names in {list(names)}'
    unknown = [n for n in names if n not in limits]
    if unknown:
        return GazeStatus.REJECTED_INVALID, f'unknown joints {unknown}; known: {sorted(limits)}'
    for name, value in zip(names, positions):
        if not math.isfinite(float(value)):
            return GazeStatus.REJECTED_NAN, f'{name} target {value} is not finite'
        lo, hi = limits[name]
        if not lo <= float(value) <= hi:
            return (GazeStatus.REJECTED_UNREACHABLE,
                    f'{name} target {float(value):.3f} rad outside [{lo}, {hi}] rad')
    return GazeStatus.OK, ''


@dataclass(frozen=True)
class ActiveRequest:
    """The request being executed: who asked, how important, since when [s], held how long [s]."""

    source: str
    priority: int
    since: float
    hold_time: float


def preempts(active: ActiveRequest | None, priority: int, now: float) -> bool:
    """Does a new request of this priority replace the active one at time now [s]?

    Yes when nothing is active, when its priority is at least the active one's, or when the
    active request's hold_time has run out (older requests lose their claim).
    """
    if active is None or priority >= active.priority:
        return True
    return now - active.since >= active.hold_time
