"""Task-driven looks: fixate the objects the map has placed but not yet named.

The thesis biases the Sensory Ego-Sphere's choice of the next fixation toward where the task's
objects can be (section 3.4.3, Fig. 3.12: Gaussian-mixture biases). The map knows more than a
prior: it knows where objects *are* (segmented on the table) and which of them still need a
name. So the next look goes to an established, unconfirmed object (the task bias), never to a
confirmed one (inhibition of return), and a look lasts until the fixation has settled and
``dwell_s`` has passed on it, so the recogniser sees the object in its fovea (recognition on a
settled fixation). The eyes aim at a point of the object the camera can see: its centre, or
if another object stands in the way (the camera's ray enters that one's box first, and the
recogniser would name the occluder), the top of it, or one side, whichever is clear; an object
hidden at all of them waits (the head moves, and its turn comes again). An object looked at
``max_looks`` times without being confirmed is given up
(the recogniser cannot name it from here), so the head does not stare at it for ever. Among the
candidates the least-looked-at wins, then the one nearest in angle to the current fixation (short
saccades).

:class:`LookScheduler` is the clock-agnostic state machine; the node feeds it the node's clock
(sim time in the graph) and /gaze/state.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .object_map import MapObject, ObjectMap

FloatArray = NDArray[np.float64]

IDLE = 'idle'            #: nothing to look at (or looks off)
SACCADE = 'saccade'      #: a look was sent; waiting for the eyes to settle on it
DWELL = 'dwell'          #: settled on the object; the recogniser is looking


@dataclass(frozen=True)
class LookConfig:
    dwell_s: float = 1.0          #: time on a settled fixation before the next look [s]
    max_looks: int = 3            #: looks at an object that stays unnamed before giving up
    settle_timeout_s: float = 3.0  #: a look whose saccade never settles is abandoned [s]

    def __post_init__(self) -> None:
        if not (self.dwell_s >= 0 and math.isfinite(self.dwell_s)):
            raise ValueError(f'dwell_s must be a finite number >= 0, got {self.dwell_s}')
        if self.max_looks < 1:
            raise ValueError(f'max_looks must be at least 1, got {self.max_looks}')
        if not (self.settle_timeout_s > 0 and math.isfinite(self.settle_timeout_s)):
            raise ValueError(f'settle_timeout_s must be positive, got {self.settle_timeout_s}')


def angle_between(origin: FloatArray, a: FloatArray, b: FloatArray) -> float:
    """The angle [rad] between the directions from origin to a and to b."""
    u, v = np.asarray(a, float) - origin, np.asarray(b, float) - origin
    nu, nv = float(np.linalg.norm(u)), float(np.linalg.norm(v))
    if nu < 1e-9 or nv < 1e-9:
        return 0.0
    return float(np.arccos(np.clip(u @ v / (nu * nv), -1.0, 1.0)))


def aim_point(object_map: ObjectMap, obj: MapObject, origin: FloatArray) -> FloatArray | None:
    """A point of obj the camera at origin sees unoccluded: its centre, else a point near its
    top, else one near either side (across the line of sight); None when each one's ray enters
    another object's box first (ObjectMap.first_on_ray)."""
    c, size = np.asarray(obj.position, np.float64), np.asarray(obj.size, np.float64)
    sight = c - np.asarray(origin, np.float64)
    across = np.array([-sight[1], sight[0], 0.0])
    norm = float(np.linalg.norm(across))
    across = across / norm if norm > 1e-9 else np.array([0.0, 1.0, 0.0])
    half = 0.3 * float(np.max(size[:2]))
    for aim in (c, c + np.array([0.0, 0.0, 0.35 * size[2]]), c + half * across,
                c - half * across):
        if object_map.first_on_ray(origin, aim, beyond_m=0.02) is obj:
            return aim
    return None


def choose_target(candidates: Sequence[MapObject], looks: dict[int, int], max_looks: int,
                  origin: FloatArray, fixation: FloatArray | None,
                  aim: Callable[[MapObject], FloatArray | None] | None = None
                  ) -> tuple[MapObject, FloatArray] | None:
    """The candidate to look at next and where to aim: looked at fewer than max_looks times and
    visible (aim(obj) not None; default: its centre); the least looked at first, then the
    nearest in angle (seen from origin) to the current fixation."""
    open_ = [o for o in candidates if looks.get(o.id, 0) < max_looks]

    def key(o: MapObject) -> tuple[int, float, int]:
        angle = 0.0 if fixation is None else angle_between(origin, fixation, o.position)
        return looks.get(o.id, 0), angle, o.id

    for obj in sorted(open_, key=key):
        point = aim(obj) if aim is not None else np.asarray(obj.position, np.float64)
        if point is not None:
            return obj, point
    return None


class LookScheduler:
    """When to look where (module docstring). Call :meth:`update` with the time, the gaze
    state and the map; it returns the object to saccade to now, or None."""

    def __init__(self, config: LookConfig | None = None) -> None:
        self.config = config or LookConfig()
        self.state = IDLE
        self.target: int | None = None
        self.looks: dict[int, int] = {}
        self.aim: FloatArray | None = None     # where the last look was sent (map frame)
        self._since = -math.inf          # when the current state began
        self.sent = 0
        self.settled = 0
        self.abandoned = 0

    def forget(self, object_ids: Sequence[int]) -> None:
        for oid in object_ids:
            self.looks.pop(oid, None)

    def update(self, now: float, in_saccade: bool, ours: bool, object_map: ObjectMap,
               origin: FloatArray, fixation: FloatArray | None) -> MapObject | None:
        """Advance the state machine at time now [s]. in_saccade: the gaze controller's
        in_saccade; ours: its active source is this scheduler's (our look is being served).
        Returns the object to send a saccade to now, aimed at self.aim (the scheduler then
        waits for it), or None."""
        cfg = self.config
        if self.state == SACCADE:
            if ours and not in_saccade:
                self.state, self._since = DWELL, now
                self.settled += 1
            elif now - self._since > cfg.settle_timeout_s:
                self.abandoned += 1        # preempted, refused or unreachable: next one
                self.state = IDLE
            else:
                return None
        if self.state == DWELL:
            target = object_map.get(self.target) if self.target is not None else None
            named = target is not None and object_map.is_confirmed(target)
            if not named and ours and now - self._since < cfg.dwell_s:
                return None
            self.state = IDLE
        if in_saccade:
            return None
        chosen = choose_target(object_map.unrecognised(), self.looks, cfg.max_looks, origin,
                               fixation, lambda o: aim_point(object_map, o, origin))
        if chosen is None:
            self.target = None
            return None
        choice, self.aim = chosen
        self.looks[choice.id] = self.looks.get(choice.id, 0) + 1
        self.target, self.state, self._since = choice.id, SACCADE, now
        self.sent += 1
        return choice


__all__ = ['DWELL', 'IDLE', 'LookConfig', 'LookScheduler', 'SACCADE', 'aim_point',
           'angle_between', 'choose_target']
