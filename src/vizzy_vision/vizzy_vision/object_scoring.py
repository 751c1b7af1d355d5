"""Scoring an object map against ground truth: recall, precision and false objects.

Shared by bench/active_perception.py and the demo's summary page (vizzy_object_map publishes the
maps; this module only compares labelled points).

A true object is *found* when a map object with its label lies within the radius of its centre;
map objects and true objects are paired one to one (the Hungarian assignment on distance among
the pairs with equal labels within the radius), so two map objects on one true object count
once. Precision is the share of the map's objects paired so; a *false object* is a map object
with no true object of any label within false_radius (something reported where nothing is),
whereas a misnamed object on a real one lowers precision only.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment


@dataclass(frozen=True)
class Labelled:
    """A labelled point: a map object or a true object, in one frame."""

    label: str
    position: tuple[float, float, float]


@dataclass(frozen=True)
class Score:
    """Counts and rates of one map against one ground truth at one radius."""

    radius_m: float
    truths: int
    reported: int
    found: int                 #: true objects paired with a same-label map object
    false_objects: int         #: map objects with no true object within false_radius
    misnamed: int              #: map objects near a true object but of another label

    @property
    def recall(self) -> float:
        return self.found / self.truths if self.truths else 1.0

    @property
    def precision(self) -> float:
        return self.found / self.reported if self.reported else 1.0

    def as_dict(self) -> dict[str, float | int]:
        return {'radius_m': self.radius_m, 'truths': self.truths, 'reported': self.reported,
                'found': self.found, 'false_objects': self.false_objects,
                'misnamed': self.misnamed, 'recall': self.recall, 'precision': self.precision}


def _positions(items: Sequence[Labelled]) -> np.ndarray:
    return np.array([i.position for i in items], np.float64).reshape(-1, 3)


def score(reported: Sequence[Labelled], truths: Sequence[Labelled], radius_m: float = 0.05,
          false_radius_m: float = 0.10) -> Score:
    """Score reported objects against truths (module docstring)."""
    r, t = _positions(reported), _positions(truths)
    found = 0
    if len(r) and len(t):
        d = np.linalg.norm(r[:, None] - t[None], axis=2)
        same = np.array([[a.label == b.label for b in truths] for a in reported])
        ok = same & (d <= radius_m)
        rows, cols = linear_sum_assignment(np.where(ok, d, 1e6))
        found = int(np.count_nonzero(ok[rows, cols]))
        near = (d <= false_radius_m).any(axis=1)
    else:
        near = np.zeros(len(r), bool)
    false_objects = int(np.count_nonzero(~near))
    return Score(radius_m, len(truths), len(reported), found, false_objects,
                 len(reported) - found - false_objects)


__all__ = ['Labelled', 'Score', 'score']
