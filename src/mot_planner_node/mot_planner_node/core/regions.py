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
- ``'centres'`` (default of :class:`PlannerConfig`, the thesis protocol): the area of the
  centre box ``2 alpha_c sigma_u x 2 alpha_c sigma_v`` of Eq. 5.18, the region of the state
  space the thesis defines: the share of the image's window positions (per scale) the detector
  evaluates. The pixels read extend half a window beyond it, which the constraint does not see.
- ``'scaled'``: the pixels the detector is handed for the region at the resolution it reads
  them (HOG shrinks a region's crop by its smallest scale ``s_lo`` first): the rectangle's
  area over ``s_lo^2``.

What the detector actually read in a frame is :func:`read_area`: the union of the integer
rectangles it crops (``floor(x0)..ceil(x1)``, as :class:`.detector.HogDetector` does),
overlaps counted once (for ``'scaled'``, each pixel at the finest resolution a region reads it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .observation import DetectorGeometry

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Column indices of a region row.
X0, Y0, X1, Y1, S_LO, S_HI = range(6)


def search_regions(x: FloatArray, P: FloatArray, geometry: DetectorGeometry,
                   alpha_c: float | FloatArray, alpha_s: float | FloatArray,
                   image_size: tuple[int, int]) -> FloatArray:
    """Search regions (..., 6) of beliefs with means x (..., 6) and covariances P (..., 6, 6).

    Eqs. 5.17-5.19: ``u = [x_c - a_c s_c, x_c + a_c s_c] x [x_s - a_s s_s, x_s + a_s s_s]``,
    then mapped to the image rectangle the detector scans for it. ``image_size`` is
    (width, height). Broadcasts: x may be (K, 6) with P (K, n, 6, 6) if x is given as
    (K, 1, 6). alpha_c, alpha_s may be arrays broadcasting like the targets (per-target
    widths).
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


AREA_MODES = ('pixels', 'centres', 'scaled')
#: Modes whose constraint area is what the detector reads (S_max binds the pixels read).
READ_MODES = ('pixels', 'scaled')


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
                     alpha_c: float, image_size: tuple[int, int],
                     upsample: float = 1.0) -> FloatArray:
    """|u^k| as the S_max constraint counts it (see :data:`AREA_MODES`)."""
    if mode in READ_MODES:
        return read_areas(regions, mode, image_size, upsample)
    if mode == 'centres':
        return centre_areas(x, P, alpha_c, image_size)
    raise ValueError(f'area mode must be one of {AREA_MODES}, got {mode!r}')


def region_areas(regions: FloatArray) -> FloatArray:
    """|u^k|: pixel area of each region's image rectangle (...,)."""
    return (np.maximum(regions[..., X1] - regions[..., X0], 0.0)
            * np.maximum(regions[..., Y1] - regions[..., Y0], 0.0))


def pixel_rects(regions: FloatArray, image_size: tuple[int, int]) -> NDArray[np.int64]:
    """The integer rectangles (..., 4) x0, y0, x1, y1 the detector crops for regions (..., 6):
    outward-rounded and clipped to the image (empty where x1 <= x0 or y1 <= y0)."""
    width, height = image_size
    regions = np.asarray(regions, dtype=float)
    x0 = np.clip(np.floor(regions[..., X0]), 0, width)
    y0 = np.clip(np.floor(regions[..., Y0]), 0, height)
    x1 = np.clip(np.ceil(regions[..., X1]), 0, width)
    y1 = np.clip(np.ceil(regions[..., Y1]), 0, height)
    return np.stack([x0, y0, np.maximum(x1, x0), np.maximum(y1, y0)], axis=-1).astype(np.int64)


def read_scale(regions: FloatArray, upsample: float = 1.0) -> FloatArray:
    """The factor by which the detector shrinks each region's crop when it reads it: its s_lo
    times the detector's ``upsample`` (:class:`.observation.DetectorGeometry`), at least 1."""
    s_lo = np.asarray(regions, dtype=float)[..., S_LO]
    return np.where(np.isfinite(s_lo), np.maximum(s_lo * upsample, 1.0), 1.0)


def read_areas(regions: FloatArray, mode: str, image_size: tuple[int, int],
               upsample: float = 1.0) -> FloatArray:
    """Pixels the detector reads for each region on its own (...,): the integer crop's area
    (``'pixels'``), or that over its :func:`read_scale` squared (``'scaled'``: read at the
    crop's resolution)."""
    r = pixel_rects(regions, image_size)
    area = ((r[..., 2] - r[..., 0]) * (r[..., 3] - r[..., 1])).astype(float)
    if mode == 'scaled':
        return area / read_scale(regions, upsample) ** 2
    if mode == 'pixels':
        return area
    raise ValueError(f'read mode must be one of {READ_MODES}, got {mode!r}')


def read_area(regions: FloatArray, image_size: tuple[int, int], mode: str = 'pixels',
              upsample: float = 1.0) -> float:
    """Pixels the detector reads for all the regions (m, 6) together: the union of their
    integer crops, overlaps counted once (``'scaled'``: each pixel at the finest resolution
    a region covering it reads it). Exact, by coordinate compression of the rectangles."""
    if mode not in READ_MODES:
        raise ValueError(f'read mode must be one of {READ_MODES}, got {mode!r}')
    regions = np.asarray(regions, dtype=float).reshape(-1, 6)
    r = pixel_rects(regions, image_size)
    keep = (r[:, 2] > r[:, 0]) & (r[:, 3] > r[:, 1])
    r = r[keep]
    if not len(r):
        return 0.0
    weight = (np.ones(len(r)) if mode == 'pixels'
              else 1.0 / read_scale(regions[keep], upsample) ** 2)
    xs, ys = np.unique(r[:, [0, 2]]), np.unique(r[:, [1, 3]])
    cx, cy = xs[:-1], ys[:-1]                              # cell lower corners
    in_x = (r[:, None, 0] <= cx) & (cx < r[:, None, 2])   # (m, nx)
    in_y = (r[:, None, 1] <= cy) & (cy < r[:, None, 3])   # (m, ny)
    inside = in_y[:, :, None] & in_x[:, None, :]           # (m, ny, nx)
    density = np.max(np.where(inside, weight[:, None, None], 0.0), axis=0)   # (ny, nx)
    return float((density * np.diff(ys)[:, None] * np.diff(xs)[None, :]).sum())


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
