"""Fixations on no object, for the recognition CNN's background (reject) class.

The node's classifier sees the whole left-eye image foveated at a fixation and must be able to
say "nothing here" when the fovea rests on a wall, the floor, the table top or a gap between
objects. A background view is a render of a simulator scene (training.tabletop_views:
tabletop or visual_search) foveated at a fixation at least `margin` px from every object's box
(`TableView.extents`: the projected boxes of the objects' geoms, conservative for round
shapes), labelled BACKGROUND_LABEL.

Head poses: `random_joints` (over the table, as the tabletop object views) and `away_joints`
(anywhere within the joint limits: walls, floor, ceiling, the table from its edge, looking up
and away as the demo did).

The margin is the fovea's own size f_0 (at least MARGIN_PX): the network sees the whole image
squashed to 227x227 px, where only the coarse pyramid levels survive, and those keep their
detail over Gaussians of 2 f_0 to 4 f_0 px (Eq. 2.3, f_k = 2^k f_0): an object within about
f_0 of the fixation looks as sharp as one under it, so a view fixated there is, to the network,
an object view (whose fixations lie within about 12 px of an object's centre), and labelling it
background would teach it to reject objects seen slightly off-centre (pass 2 fixates saliency
box centres, which need not fall on the object's centre). Fixations "near the objects" (table
top, gaps, the wall just above them) are drawn from the ring [f_0, 2 f_0) around the boxes.

Needs mujoco and vizzy_sim_bridge (training and experiments); the node does not import it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from foveation_node.core.recognition import BACKGROUND_LABEL

MARGIN_PX = 40.0            # least distance from a background fixation to any object's box
AWAY_LIMIT_FRACTION = 0.9   # away poses: within this fraction of each joint's range

Box = tuple[int, int, int, int]


def away_joints(rng: np.random.Generator) -> tuple[float, ...]:
    """A head pose anywhere within the joint limits (shrunk to AWAY_LIMIT_FRACTION of each
    range about its middle), both eyes at the same version: walls, floor, ceiling, up and away.
    JOINT_NAMES order (neck pan, neck tilt, eyes tilt, left eye, right eye)."""
    from vizzy_vision.kinematics import JOINT_LIMITS, JOINT_NAMES

    out = []
    for name in JOINT_NAMES[:4]:
        lo, hi = JOINT_LIMITS[name]
        mid, half = (lo + hi) / 2, AWAY_LIMIT_FRACTION * (hi - lo) / 2
        out.append(float(rng.uniform(mid - half, mid + half)))
    return (*out, out[3])


def box_distance(box: Box, u: float, v: float) -> float:
    """Distance [px] from (u, v) to box (x0, y0, x1, y1) inclusive; 0 inside."""
    dx = max(box[0] - u, 0.0, u - box[2])
    dy = max(box[1] - v, 0.0, v - box[3])
    return math.hypot(dx, dy)


def object_distance(boxes: Sequence[Box], u: float, v: float) -> float:
    """Distance [px] from (u, v) to the nearest box; inf without boxes."""
    return min((box_distance(b, u, v) for b in boxes), default=math.inf)


def margin_for(f0: float) -> float:
    """Least distance [px] from a background fixation to any object's box, for fovea size f0
    (see the module docstring): f0, at least MARGIN_PX."""
    return max(float(f0), MARGIN_PX)


def background_fixations(boxes: Sequence[Box], width: int, height: int,
                         rng: np.random.Generator, n: int, margin: float = MARGIN_PX,
                         within: float = math.inf, tries: int = 400
                         ) -> list[tuple[float, float]]:
    """Up to n fixations (u, v), uniform over the width x height image, whose distance to the
    nearest box is in [margin, within) (within < inf: near the objects; no boxes then gives
    none). Rejection sampling: fewer than n when the image is crowded (tries draws in all)."""
    out: list[tuple[float, float]] = []
    if within < math.inf and not boxes:
        return out
    for _ in range(tries):
        if len(out) == n:
            break
        u, v = float(rng.uniform(0, width - 1)), float(rng.uniform(0, height - 1))
        d = object_distance(boxes, u, v)                  # inf: no object in the image
        if d >= margin and (within == math.inf or d < within):
            out.append((u, v))
    return out


__all__ = ['AWAY_LIMIT_FRACTION', 'BACKGROUND_LABEL', 'MARGIN_PX', 'away_joints',
           'background_fixations', 'box_distance', 'margin_for', 'object_distance']
