"""Synthetic cylinders for tests, experiments and benchmarks (thesis section 4.4.1, Fig. 4.4)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .fitting import rotation_to_z

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SyntheticCylinder:
    points: Array        #: (N, 3) scene points
    n_surface: int       #: cylinder surface points (the first n_surface rows)
    centre: Array
    axis: Array
    radius: float
    height: float

    @property
    def outlier_fraction(self) -> float:
        """Eq. 4.5: 1 - cylinder surface points / total scene points."""
        return 1.0 - self.n_surface / len(self.points)


def random_axis(rng: np.random.Generator) -> Array:
    v = rng.standard_normal(3)
    return v / np.linalg.norm(v)


def make_cylinder(rng: np.random.Generator, radius: float, height: float, n_surface: int = 900,
                  cap_ratio: float = 0.0, noise_std: float = 0.0, axis: Array | None = None,
                  centre: Array | None = None) -> SyntheticCylinder:
    """Uniform points on a cylinder's side, plus planar caps (lids) holding cap_ratio * n_surface
    points split between top and bottom, plus isotropic Gaussian noise of std noise_std (m)."""
    axis = (np.array([0.0, 0.0, 1.0]) if axis is None
            else np.asarray(axis, float) / np.linalg.norm(axis))
    centre = np.zeros(3) if centre is None else np.asarray(centre, float)
    th = rng.uniform(0, 2 * np.pi, n_surface)
    side = np.column_stack([radius * np.cos(th), radius * np.sin(th),
                            rng.uniform(-height / 2, height / 2, n_surface)])
    n_cap = int(round(cap_ratio * n_surface))
    rr = radius * np.sqrt(rng.uniform(0, 1, n_cap))
    tc = rng.uniform(0, 2 * np.pi, n_cap)
    zc = np.where(np.arange(n_cap) % 2 == 0, height / 2, -height / 2)
    caps = np.column_stack([rr * np.cos(tc), rr * np.sin(tc), zc])
    local = np.vstack([side, caps])
    rot = rotation_to_z(axis).T   # maps +z to axis
    pts = local @ rot.T + centre
    if noise_std > 0:
        pts = pts + rng.normal(0, noise_std, pts.shape)
    return SyntheticCylinder(pts, n_surface, centre, axis, float(radius), float(height))


def axis_angle_deg(a: Array, b: Array) -> float:
    """Angle between two axes (orientation-free: 0..90 degrees)."""
    c = float(abs(float(np.dot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b))))
    return float(np.degrees(np.arccos(min(1.0, c))))


def axis_distance(point: Array, centre: Array, axis: Array) -> float:
    """Distance from a point to the line through centre along axis (position error)."""
    d = np.asarray(point, float) - np.asarray(centre, float)
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    return float(np.linalg.norm(d - (d @ a) * a))
