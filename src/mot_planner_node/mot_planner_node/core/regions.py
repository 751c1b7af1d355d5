"""Dynamic search regions and the attention constraints (Eqs. 5.16-5.20 and 5.23's constraints).

A region is the set of detector windows a belief makes plausible (Eqs. 5.18-5.19): centres in
``x_c +- alpha_c sigma_c`` and scales in ``x_s +- alpha_s sigma_s``. The image area the
detector must process for it is the bounding box of those windows: the centre box grown by
half the largest window, clipped to the image. (The sliding-window grid then has a window
within one stride of any centre in the box, which is the quantization of Eq. 5.8.) A region
is stored as one row ``[x0, y0, x1, y1, s_lo, s_hi]`` (pixels, half-open, and the scale
range).

Actions are binary activations of the regions (Eq. 5.20); an action is feasible when it
activates at most K_max regions whose areas add up to at most S_max of the image.

What "area of a region" |u^k| means (section 5.3.4) is a choice, :data:`AREA_MODES`:

- ``'pixels'``: the image rectangle the detector reads (window-inclusive, what
  :func:`search_regions` returns). A hard bound on pixels processed; a person's window alone
  must fit in S_max (at 640x480 and S_max = 0.1, people up to about 150 px tall).
- ``'centres'`` (default): the area of the centre box ``2 alpha_c sigma_u x 2 alpha_c
  sigma_v`` of Eq. 5.18, the region of the state space the thesis defines: the share of the
  image's window positions (per scale) the detector evaluates. The pixels read extend half a
  window beyond it, which the constraint does not see (the detector time shows it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .observation import DetectorGeometry

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Column indices of a region row.
X0, Y0, X1, Y1, S_LO, S_HI = range(6)


def search_regions(x: FloatArray, P: FloatArray, geometry: DetectorGeometry, alpha_c: float,
                   alpha_s: float, image_size: tuple[int, int]) -> FloatArray:
    """Search regions (..., 6) of beliefs with means x (..., 6) and covariances P (..., 6, 6).

    Eqs. 5.17-5.19: ``u = [x_c - a_c s_c, x_c + a_c s_c] x [x_s - a_s s_s, x_s + a_s s_s]``,
    then mapped to the image rectangle the detector scans for it. ``image_size`` is
    (width, height). Broadcasts: x may be (K, 6) with P (K, n, 6, 6) if x is given as
    (K, 1, 6).
    """
    width, height = image_size
    su = np.sqrt(np.maximum(P[..., 0, 0], 0.0))
    sv = np.sqrt(np.maximum(P[..., 1, 1], 0.0))
    ss = np.sqrt(np.maximum(P[..., 2, 2], 0.0))
    u, v, s = x[..., 0], x[..., 1], x[..., 2]
    s_lo = np.maximum(s - alpha_s * ss, geometry.min_scale)
    s_hi = np.maximum(s + alpha_s * ss, s_lo)
    half_w = s_hi * geometry.window_w / 2.0
    half_h = s_hi * geometry.window_h / 2.0
    x0 = np.clip(u - alpha_c * su - half_w, 0.0, width)
    x1 = np.clip(u + alpha_c * su + half_w, 0.0, width)
    y0 = np.clip(v - alpha_c * sv - half_h, 0.0, height)
    y1 = np.clip(v + alpha_c * sv + half_h, 0.0, height)
    return np.stack(np.broadcast_arrays(x0, y0, x1, y1, s_lo, s_hi), axis=-1)


AREA_MODES = ('pixels', 'centres')


def centre_areas(x: FloatArray, P: FloatArray, alpha_c: float,
                 image_size: tuple[int, int]) -> FloatArray:
    """Area of the centre box of Eq. 5.18, ``[u +- a_c s_u] x [v +- a_c s_v]`` clipped to the
    image (...,)."""
    width, height = image_size
    su = np.sqrt(np.maximum(P[..., 0, 0], 0.0))
    sv = np.sqrt(np.maximum(P[..., 1, 1], 0.0))
    u, v = x[..., 0], x[..., 1]
    w = np.clip(u + alpha_c * su, 0, width) - np.clip(u - alpha_c * su, 0, width)
    h = np.clip(v + alpha_c * sv, 0, height) - np.clip(v - alpha_c * sv, 0, height)
    return w * h


def constraint_areas(x: FloatArray, P: FloatArray, regions: FloatArray, mode: str,
                     alpha_c: float, image_size: tuple[int, int]) -> FloatArray:
    """|u^k| as the S_max constraint counts it (see :data:`AREA_MODES`)."""
    if mode == 'pixels':
        return region_areas(regions)
    if mode == 'centres':
        return centre_areas(x, P, alpha_c, image_size)
    raise ValueError(f'area mode must be one of {AREA_MODES}, got {mode!r}')


def region_areas(regions: FloatArray) -> FloatArray:
    """|u^k|: pixel area of each region's image rectangle (...,)."""
    return (np.maximum(regions[..., X1] - regions[..., X0], 0.0)
            * np.maximum(regions[..., Y1] - regions[..., Y0], 0.0))


def full_frame_region(image_size: tuple[int, int], geometry: DetectorGeometry) -> FloatArray:
    """The whole image as one region (1, 6), all scales from the smallest."""
    width, height = image_size
    return np.array([[0.0, 0.0, float(width), float(height), geometry.min_scale, np.inf]])


def action_cost(action: BoolArray, areas: FloatArray) -> tuple[int, float]:
    """(number of active regions, total active area) of a binary action (Eq. 5.20)."""
    action = np.asarray(action, dtype=bool)
    return int(action.sum()), float(np.sum(np.where(action, areas, 0.0)))


def is_feasible(action: BoolArray, areas: FloatArray, k_max: int, s_max: float,
                image_area: float) -> bool:
    """The constraints of the resource-constrained POMDP (section 5.3.4):
    ``sum a_k <= K_max`` and ``sum a_k |u_k| <= S_max A_p``."""
    count, area = action_cost(action, areas)
    return count <= k_max and area <= s_max * image_area * (1.0 + 1e-9)


def check_action(action: BoolArray, areas: FloatArray, k_max: int, s_max: float,
                 image_area: float) -> None:
    """Raise ValueError naming the violated constraint if the action is infeasible."""
    count, area = action_cost(action, areas)
    if count > k_max:
        raise ValueError(f'action activates {count} regions, more than K_max = {k_max}')
    if area > s_max * image_area * (1.0 + 1e-9):
        raise ValueError(f'action covers {area:.0f} px, more than S_max * A_p = '
                         f'{s_max * image_area:.0f} px')
