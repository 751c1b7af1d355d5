"""Segmentation then fitting (thesis Fig. 4.1 without the pre-attention classifier).

Each cluster is fitted in the table frame (table normal = +z), so the vertical biases of Table 4.1
mean "upright on the table"; results are returned in the cloud's frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from .fitting import Cylinder, FitParams, fit_cylinder, make_directions, rotation_to_z
from .segmentation import Cluster, SegmentParams, segment_tabletop

Array = NDArray[np.float64]


@dataclass
class Detection:
    cylinders: list[Cylinder] = field(default_factory=list)
    clusters: list[Cluster] = field(default_factory=list)       #: the cluster of each cylinder
    rejected: int = 0                                            #: clusters below the Eq. 4.4 threshold
    plane: Array | None = None
    messages: list[str] = field(default_factory=list)


def detect_cylinders(points: Array, seg: SegmentParams | None = None, fit: FitParams | None = None,
                     intrinsics: tuple[float, float, float, float] | None = None,
                     image_size: tuple[int, int] = (640, 480)) -> Detection:
    """Tabletop segmentation (section 4.3.1) and a fit per cluster (section 4.3.3, Eq. 4.4)."""
    fit = fit or FitParams()
    s = segment_tabletop(points, seg, intrinsics, image_size)
    out = Detection(plane=s.plane, messages=list(s.messages))
    if s.plane is None or not s.clusters:
        return out
    rot = rotation_to_z(s.plane[:3])          # cloud frame -> table frame (normal to +z)
    directions = make_directions(fit)
    for cl in s.clusters:
        if len(cl.points) < fit.min_points:
            out.messages.append(f'cluster of {len(cl.points)} points is too small to fit (min_points={fit.min_points})')
            continue
        c = fit_cylinder(cl.points @ rot.T, fit, directions)
        if c is None:
            out.rejected += 1
            continue
        centre = rot.T @ np.array(c.centre)
        axis = rot.T @ np.array(c.axis)
        if axis @ s.plane[:3] < 0:
            axis = -axis
        out.cylinders.append(Cylinder(tuple(map(float, centre)), tuple(map(float, axis)), c.radius, c.height,
                                      c.confidence, c.n_inliers, c.n_points))
        out.clusters.append(cl)
    if out.rejected:
        out.messages.append(f'{out.rejected} cluster(s) below confidence {fit.min_confidence} (Eq. 4.4): not cylinders')
    return out
