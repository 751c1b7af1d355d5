"""Disparity maps of a rectified pair at the resolution each sensor needs (issue 13, item 3).

Three matchers, all OpenCV StereoSGBM with the same settings (`SGBMParams`), each returning
a float32 disparity map at the input resolution (x_left - x_right, px; NaN where unknown):

- `full_disparity`: SGBM on the full-resolution pair (the baseline).
- `cartesian_disparity`: SGBM on the Cartesian sensor's view (area-resized to its nx x ny RF
  grid, `sensors.cartesian_sensor`), disparities scaled back and upsampled (nearest).
- `FoveatedSGBM`: the log-polar sensor's matcher. The retina's RFs are spaced
  s(r) = r * max(a - 1, 2 pi / wedges) px at eccentricity r (thesis Eq. 1.1 and the RF law of
  section 3.3.2, Eqs. 3.6-3.7; `sensors.fovea_radius`): pixels finer than that carry nothing
  the sensor keeps. So each pyramid level l (cv2.pyrDown, pixel spacing 2^l) is matched only
  where s(r) >= 2^l, i.e. on the annulus fovea_radius * 2^(l-1) <= r < fovea_radius * 2^l
  (fovea_radius = 1 / max(a - 1, 2 pi / wedges): where the RF lattice reaches pixel density;
  level 0, full resolution, is the disc r < fovea_radius). Each level runs SGBM on the
  bounding square of its disc only (a crop of the level image), so every level costs about the
  same and the whole frame a few crops of ~80x80 px instead of the full image. The last level
  (`max_level`, default MAX_LEVEL = 2) takes the rest of the image: the RF law would go on to
  1/8 resolution beyond 4 fovea radii (127 px on 640x480), but SGBM's sub-pixel precision,
  about a quarter of a level pixel, then means 2 px errors (bad-2.0 there 35% against 6% at
  1/4 resolution, on the benchmark's pairs) and 1/4 costs only ~7% more for the whole frame.

The search range is coarse-to-fine: one level coarser than the coarsest level used (the whole
image at 1/2^(L+1)) searches the whole window [lo, hi) (from the geometry, `disparity_window`,
or given) and narrows it for the coarsest level (whole image at 1/2^L); each finer level
searches only what the level above found on its region (the disparities at least 0.5% of its
matches hold, `_narrowed`) widened by two coarse pixels, so the fovea searches tens of
disparities, not the whole window.

Crops are matched with the window's lower end shifted out (the right crop starts lo px further
left, SGBM then searches [0, N)), and the left crop starts N columns before the region, so that
SGBM's invalid left border falls outside it (`sgbm_window`); as in plain SGBM, pixels whose match
could fall outside the right image (x < lo + N) are NaN. `full_disparity` and
`cartesian_disparity` use the same wrapper (`sgbm_window`), so the three differ only in what
resolution they match where.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import cv2
import numpy as np

from .geometry import pixel_rays, project

# widening of a level's range beyond what the coarser level found, in coarser-level pixels
RANGE_MARGIN_COARSE_PX = 2.0
# a finer level searches the coarse disparities held by at least this fraction of its matches
RANGE_SUPPORT = 0.005
# extra level pixels around each crop (SGBM's window and path aggregation need context)
CROP_MARGIN = 8
# a level whose disparities are used keeps at least this many pixels on its short side (SGBM's
# 7 px window and path aggregation need room); a level that only searches the range, this many
MIN_LEVEL_SIDE = 48
MIN_SEARCH_SIDE = 24
# the coarsest level whose disparities FoveatedSGBM uses, by default (see the module docstring)
MAX_LEVEL = 2


@dataclass(frozen=True)
class SGBMParams:
    """cv2.StereoSGBM settings (defaults of foveated_stereo_ros: 80 disparities, window 7, P1 768,
    P2 1536). min_disparity -40 centres the 80 disparities on the fixation of verging eyes
    (points beyond it have negative disparity); a parallel rectified rig needs >= 0."""

    num_disparities: int = 80
    block_size: int = 7
    p1: int = 768
    p2: int = 1536
    min_disparity: int = -40
    uniqueness_ratio: int = 10
    disp12_max_diff: int = 1

    def __post_init__(self) -> None:
        if self.num_disparities <= 0 or self.num_disparities % 16:
            raise ValueError(f'num_disparities must be a positive multiple of 16, got '
                             f'{self.num_disparities}')
        if self.block_size < 1 or self.block_size % 2 == 0:
            raise ValueError(f'block_size must be odd and >= 1, got {self.block_size}')

    def create(self, min_disparity: int | None = None,
               num_disparities: int | None = None) -> cv2.StereoSGBM:
        """The matcher (optionally for another range)."""
        return cv2.StereoSGBM.create(
            minDisparity=self.min_disparity if min_disparity is None else min_disparity,
            numDisparities=self.num_disparities if num_disparities is None else num_disparities,
            blockSize=self.block_size, P1=self.p1, P2=self.p2,
            disp12MaxDiff=self.disp12_max_diff, uniquenessRatio=self.uniqueness_ratio)


def to_gray(image: np.ndarray) -> np.ndarray:
    """uint8 single-channel view of an rgb8/mono8 image (ValueError otherwise)."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim not in (2, 3):
        got = f'{image.dtype} {image.shape}' if isinstance(image, np.ndarray) else type(image)
        raise ValueError(f'expected an 8-bit mono or RGB image, got {got}')
    if image.ndim == 3:
        if image.shape[2] == 1:
            return image[..., 0]
        if image.shape[2] != 3:
            raise ValueError(f'expected 3 channels, got {image.shape[2]}')
        return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    return image


def round_up16(n: float) -> int:
    """The smallest positive multiple of 16 >= n (SGBM's numDisparities)."""
    return max(16, 16 * int(math.ceil(n / 16.0)))


@dataclass(frozen=True)
class DisparityWindow:
    """A disparity search range [lo, hi) in full-resolution px."""

    lo: float
    hi: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lo) and math.isfinite(self.hi)) or self.hi <= self.lo:
            raise ValueError(f'disparity window [{self.lo:g}, {self.hi:g}) is empty or not '
                             f'finite')

    @classmethod
    def from_sgbm(cls, params: SGBMParams) -> DisparityWindow:
        return cls(float(params.min_disparity),
                   float(params.min_disparity + params.num_disparities))

    def scaled(self, scale: float) -> tuple[int, int]:
        """(minDisparity, numDisparities) covering this window on an image scaled by 1/scale,
        from one pixel below it: `sgbm_window` drops matches at the first disparity searched
        (SGBM's answer for textureless patches), which must not be the window's own first."""
        lo = int(math.floor(self.lo / scale)) - 1
        return lo, round_up16(math.ceil(self.hi / scale) - lo)

    def to_json(self) -> list[float]:
        return [round(float(self.lo), 3), round(float(self.hi), 3)]


def parallel_window(focal_px: float, baseline_m: float, near_m: float,
                    far_m: float = math.inf) -> DisparityWindow:
    """Window of a rectified parallel rig: d = f b / Z for Z in [near, far] (Eq. 3.8's inverse)."""
    if not (focal_px > 0 and baseline_m > 0 and 0 < near_m < far_m):
        raise ValueError('parallel_window needs focal > 0, baseline > 0 and 0 < near < far')
    return DisparityWindow(math.floor(focal_px * baseline_m / far_m + 1e-6),
                           math.ceil(focal_px * baseline_m / near_m - 1e-6) + 1)


def disparity_window(k_left: np.ndarray, k_right: np.ndarray, pose_left: np.ndarray,
                     pose_right: np.ndarray, width: int, height: int, near_m: float,
                     far_m: float, samples: int = 9) -> DisparityWindow:
    """Horizontal disparities (u_left - u_right) of any rig, verged or parallel, for points
    between near_m and far_m along the left camera's rays (a samples x samples grid of pixels
    over the image): the window a matcher must search. far_m may be inf (points at infinity)."""
    if not (0 < near_m < far_m):
        raise ValueError(f'depth range must satisfy 0 < near < far, got [{near_m}, {far_m}]')
    u, v = np.meshgrid(np.linspace(0, width - 1, samples), np.linspace(0, height - 1, samples))
    rays = pixel_rays(np.stack([u, v], axis=-1).reshape(-1, 2), k_left, pose_left)
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    c = pose_left[:3, 3]
    # depth along the left optical axis: points c + t ray with (R^T (t ray))_z = depth
    axis = pose_left[:3, 2]
    cos = rays @ axis
    ok = cos > 1e-6
    rays, cos = rays[ok], cos[ok]
    found = []
    for depth in (near_m, far_m):
        # depth inf: a point at infinity, the right camera sees the direction
        pts = c + rays * 1e9 if math.isinf(depth) else c + rays * (depth / cos)[:, None]
        ul = project(pts, k_left, pose_left)[:, 0]
        ur = project(pts, k_right, pose_right)[:, 0]
        found.append(ul - ur)
    d = np.concatenate(found)
    d = d[np.isfinite(d)]
    if d.size == 0:
        raise ValueError('no point of the depth range is seen by both cameras')
    # (1e-6: a disparity of exactly 50 must not become 51 by rounding error)
    return DisparityWindow(math.floor(float(d.min()) + 1e-6), math.ceil(float(d.max()) - 1e-6) + 1)


def sgbm_window(left: np.ndarray, right: np.ndarray, lo: int, num: int, params: SGBMParams,
                x0: int = 0, x1: int | None = None, border: float | None = None) -> np.ndarray:
    """SGBM of the columns [x0, x1) of left against right for disparities [lo, lo + num).

    left, right: (h, w) uint8 rows of the two images (all their columns). The left crop starts
    num columns before x0 and the right crop lo columns further left,
    so SGBM searches [0, num) and its invalid left border falls before x0 (columns beyond the
    image repeat its edge). Returns float32
    (h, x1 - x0) disparities in these images' px; NaN where SGBM found no match (or stopped at
    the window's first or last disparity: textureless patches), where the
    match could fall left of the right image (x < lo + num, which plain SGBM also refuses) or
    falls right of it. `border` (default lo + num): the largest disparity that can occur (the
    window's end before rounding num up to a multiple of 16); columns x < border are NaN.
    """
    h, w = left.shape
    x1 = w if x1 is None else x1

    def crop(img: np.ndarray, start: int) -> np.ndarray:
        if start >= 0 and start + x1 - x0 + num <= w:
            return img[:, start:start + x1 - x0 + num]
        # beyond the image: its edge column repeated (zeros would make an edge to match)
        return img[:, np.clip(np.arange(start, start + x1 - x0 + num), 0, w - 1)]

    pl, pr = crop(left, x0 - num), crop(right, x0 - num - lo)
    raw = params.create(0, num).compute(pl, pr)[:, num:]
    disp = raw.astype(np.float32) * (1.0 / 16.0) + lo
    # raw 0 / (num - 1) * 16: the window's first / last disparity with no sub-pixel fit, SGBM's
    # answer for a textureless patch (all costs tie), not a match
    disp[(raw <= 0) | (raw >= 16 * (num - 1))] = np.nan
    x = np.arange(x0, x1, dtype=np.float32)[None, :]
    border = lo + num if border is None else min(border, lo + num)
    disp[~((x >= border) & (x - disp <= w - 1))] = np.nan      # NaN compares False
    return disp


def sgbm_work(shape: tuple[int, ...], num: int) -> int:
    """Cost-volume cells of one `sgbm_window` call that returned shape: its crop is num columns
    wider than the result, each pixel scores num disparities (SGBM's time is about linear in
    this)."""
    return int(shape[0] * (shape[1] + num) * num)


def _gray_pair(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if left.shape != right.shape:
        raise ValueError(f'left and right images differ in size: {left.shape} vs {right.shape}')
    return to_gray(left), to_gray(right)


@dataclass
class DisparityResult:
    """A float32 disparity map at input resolution (NaN = unknown) and how it was made."""

    disparity: np.ndarray
    stages_ms: dict[str, float] = field(default_factory=dict)      # wall ms per stage
    ranges: dict[str, list[float]] = field(default_factory=dict)   # searched [lo, hi) px
    work: int = 0      # SGBM cost-volume cells evaluated (pixels x disparities, all calls)

    @property
    def valid_points(self) -> int:
        return int(np.count_nonzero(np.isfinite(self.disparity)))


class _Stages:
    def __init__(self) -> None:
        self.ms: dict[str, float] = {}
        self._t = time.perf_counter()

    def lap(self, name: str) -> None:
        t = time.perf_counter()
        self.ms[name] = round(self.ms.get(name, 0.0) + 1e3 * (t - self._t), 3)
        self._t = t


def full_disparity(left: np.ndarray, right: np.ndarray, window: DisparityWindow,
                   params: SGBMParams = SGBMParams()) -> DisparityResult:
    """SGBM at full resolution over the whole window."""
    st = _Stages()
    gl, gr = _gray_pair(left, right)
    st.lap('gray')
    lo, num = window.scaled(1.0)
    disp = sgbm_window(gl, gr, lo, num, params, border=window.hi)
    st.lap('sgbm')
    return DisparityResult(disp, st.ms, {'full': [lo, lo + num]}, sgbm_work(disp.shape, num))


def coarse_window(left: np.ndarray, right: np.ndarray, window: DisparityWindow,
                  params: SGBMParams = SGBMParams(), level: int | None = None
                  ) -> DisparityWindow:
    """The window narrowed to what SGBM finds on a coarse pyramid level of the whole pair
    (`_narrowed`); the window itself if nothing matched."""
    gl, gr = _gray_pair(left, right)
    if level is None:
        level = coarsest_level(gl.shape[1], gl.shape[0], min_side=MIN_SEARCH_SIDE)
    for _ in range(level):
        gl, gr = cv2.pyrDown(gl), cv2.pyrDown(gr)
    scale = 2.0 ** level
    lo, num = window.scaled(scale)
    d = sgbm_window(gl, gr, lo, num, params, border=window.hi / scale) * scale
    return _narrowed(d, window, scale)


def _narrowed(d: np.ndarray, window: DisparityWindow, scale: float) -> DisparityWindow:
    """The part of window that the coarse disparities d (full-res px, found at 1/scale) support:
    histogram bins of one coarse pixel holding at least RANGE_SUPPORT of the matches (and 3),
    so scattered mismatches do not widen it, widened by RANGE_MARGIN_COARSE_PX coarse px."""
    v = d[np.isfinite(d)]
    if v.size < 16:
        return window
    edges = np.arange(math.floor(v.min() / scale), math.ceil(v.max() / scale) + 2) * scale
    counts, _ = np.histogram(v, edges)
    held = np.nonzero(counts >= max(3.0, RANGE_SUPPORT * v.size))[0]
    if held.size == 0:
        return window
    m = RANGE_MARGIN_COARSE_PX * scale
    lo = max(window.lo, math.floor(edges[held[0]] - m))
    hi = min(window.hi, math.ceil(edges[held[-1] + 1] + m))
    return DisparityWindow(lo, hi) if hi > lo else window


def coarsest_level(width: int, height: int, max_level: int = 5,
                   min_side: int = MIN_LEVEL_SIDE) -> int:
    """The coarsest pyramid level (<= max_level) whose image keeps min_side px on its short
    side."""
    level = 0
    while level < max_level and min(width, height) / 2 ** (level + 1) >= min_side:
        level += 1
    return level


def cartesian_disparity(left: np.ndarray, right: np.ndarray, window: DisparityWindow,
                        grid: tuple[int, int] = (200, 200),
                        params: SGBMParams = SGBMParams()) -> DisparityResult:
    """SGBM on the Cartesian sensor's view (area resize to the nx x ny RF grid), upsampled."""
    st = _Stages()
    gl, gr = _gray_pair(left, right)
    h, w = gl.shape
    nx, ny = int(grid[0]), int(grid[1])
    st.lap('gray')
    vl = cv2.resize(gl, (nx, ny), interpolation=cv2.INTER_AREA)
    vr = cv2.resize(gr, (nx, ny), interpolation=cv2.INTER_AREA)
    st.lap('view')
    sx = w / nx
    lo, num = window.scaled(sx)
    d = sgbm_window(vl, vr, lo, num, params, border=window.hi / sx) * np.float32(sx)
    st.lap('sgbm')
    out = cv2.resize(d, (w, h), interpolation=cv2.INTER_NEAREST)
    st.lap('compose')
    return DisparityResult(out, st.ms, {'grid': [lo * sx, (lo + num) * sx]},
                           sgbm_work(d.shape, num))


@dataclass(frozen=True)
class _Level:
    level: int
    r_outer: float                       # the disc this level covers (inf: the whole image)
    box: tuple[int, int, int, int]       # x0, y0, x1, y1 in level px (the crop matched)
    dst: np.ndarray                      # flat full-res indices this level fills
    src: np.ndarray                      # flat indices into the box's disparity map


class FoveatedSGBM:
    """The log-polar sensor's matcher: SGBM per pyramid level on the crop its annulus needs.

    width x height images, fixation `center` (x, y) px (default the image centre),
    `fovea_radius` px (full resolution inside; `sensors.fovea_radius` of the retina), levels
    up to `max_level` (default MAX_LEVEL; fewer when the disc of level l already covers the
    image, or the level image gets smaller than MIN_LEVEL_SIDE).
    """

    def __init__(self, width: int, height: int, fovea_radius: float,
                 center: tuple[float, float] | None = None, max_level: int = MAX_LEVEL,
                 params: SGBMParams = SGBMParams(), coarse_to_fine: bool = True) -> None:
        if width < 16 or height < 16:
            raise ValueError(f'images must be at least 16x16, got {width}x{height}')
        if not (fovea_radius > 0 and math.isfinite(fovea_radius)):
            raise ValueError(f'fovea_radius must be positive, got {fovea_radius}')
        self.width, self.height = int(width), int(height)
        if center is None:
            center = ((width - 1) / 2.0, (height - 1) / 2.0)
        cx, cy = float(center[0]), float(center[1])
        if not (0 <= cx <= width - 1 and 0 <= cy <= height - 1):
            raise ValueError(f'fixation ({cx:g}, {cy:g}) is outside the {width}x{height} image')
        self.center, self.fovea_radius = (cx, cy), float(fovea_radius)
        self.params, self.coarse_to_fine = params, coarse_to_fine
        top = min(int(max_level), coarsest_level(width, height, max_level))
        ys, xs = np.mgrid[0:height, 0:width]
        ecc = np.hypot(xs - cx, ys - cy).ravel()      # `eccentricity`, from the grid at hand
        self.levels: list[_Level] = []
        inner, lvl = 0.0, 0
        while True:
            s = 2 ** lvl
            lw, lh = (width + s - 1) // s, (height + s - 1) // s   # pyrDown sizes
            outer = self.fovea_radius * s
            lcx, lcy = cx / s, cy / s                 # pyrDown: level px i sits on s * i
            half = outer / s + CROP_MARGIN
            box = (max(0, int(math.floor(lcx - half))), max(0, int(math.floor(lcy - half))),
                   min(lw, int(math.ceil(lcx + half)) + 1),
                   min(lh, int(math.ceil(lcy + half)) + 1))
            last = lvl == top or box == (0, 0, lw, lh)
            if last:                                 # the rest of the image, all of this level
                outer, box = math.inf, (0, 0, lw, lh)
            # int64 (intp) indices: int32 would halve their 5 MB but numpy converts them to intp
            # at every use (+0.7 ms a pair)
            dst = np.nonzero((ecc >= inner) & (ecc < outer))[0]
            ix = np.clip(np.rint(xs.ravel()[dst] / s).astype(np.int64), box[0], box[2] - 1)
            iy = np.clip(np.rint(ys.ravel()[dst] / s).astype(np.int64), box[1], box[3] - 1)
            src = (iy - box[1]) * (box[2] - box[0]) + (ix - box[0])
            self.levels.append(_Level(lvl, outer, box, dst, src))
            if last:
                break
            inner, lvl = outer, lvl + 1
        self.n_levels = len(self.levels)
        # the level that searches the whole window for the range (one coarser than the last)
        self.range_level = min(self.n_levels,
                               coarsest_level(width, height, 8, min_side=MIN_SEARCH_SIDE))

    @property
    def eccentricity(self) -> np.ndarray:
        """(height, width) float64: each pixel's distance [px] from the fixation (computed when
        asked: the node never needs it after construction)."""
        ys, xs = np.mgrid[0:self.height, 0:self.width]
        return np.hypot(xs - self.center[0], ys - self.center[1])

    def level_map(self) -> np.ndarray:
        """(height, width) int: the pyramid level each pixel's disparity comes from."""
        out = np.empty(self.width * self.height, np.int8)
        for lv in self.levels:
            out[lv.dst] = lv.level
        return out.reshape(self.height, self.width)

    def compute(self, left: np.ndarray, right: np.ndarray,
                window: DisparityWindow) -> DisparityResult:
        """Disparity map (full resolution, NaN unknown) of a rectified pair."""
        st = _Stages()
        gl, gr = _gray_pair(left, right)
        if gl.shape != (self.height, self.width):
            raise ValueError(f'images are {gl.shape[1]}x{gl.shape[0]}, the matcher is for '
                             f'{self.width}x{self.height}')
        st.lap('gray')
        pyr = [(gl, gr)]
        for _ in range(1, max(self.n_levels, self.range_level + 1)):
            pyr.append((cv2.pyrDown(pyr[-1][0]), cv2.pyrDown(pyr[-1][1])))
        st.lap('pyramid')
        out = np.full(self.width * self.height, np.nan, np.float32)
        ranges: dict[str, list[float]] = {}
        parent: tuple[np.ndarray, tuple[int, int, int, int]] | None = None
        work = 0
        if self.coarse_to_fine:       # the range search: the whole window, one level coarser
            s = 2 ** self.range_level
            lo, num = window.scaled(s)
            l_img, r_img = pyr[self.range_level]
            d = sgbm_window(l_img, r_img, lo, num, self.params,
                            border=window.hi / s) * np.float32(s)
            window = _narrowed(d, window, s)
            work += sgbm_work(d.shape, num)
            ranges['search'] = [lo * s, (lo + num) * s]
            st.lap('range search')
        for lv in reversed(self.levels):
            s = 2 ** lv.level
            win = window
            if parent is not None and self.coarse_to_fine:
                pd, pbox = parent
                x0, y0, x1, y1 = lv.box
                sub = pd[max(0, y0 // 2 - pbox[1]):max(0, (y1 + 2) // 2 - pbox[1]),
                         max(0, x0 // 2 - pbox[0]):max(0, (x1 + 2) // 2 - pbox[0])]
                win = _narrowed(sub, window, 2.0 * s)
            lo, num = win.scaled(s)
            x0, y0, x1, y1 = lv.box
            l_img, r_img = pyr[lv.level]
            d = sgbm_window(l_img[y0:y1], r_img[y0:y1], lo, num, self.params, x0, x1,
                            win.hi / s) * np.float32(s)
            out[lv.dst] = d.ravel()[lv.src]
            work += sgbm_work(d.shape, num)
            parent = (d, lv.box)
            ranges[f'level{lv.level}'] = [lo * s, (lo + num) * s]
            st.lap(f'level{lv.level}')
        return DisparityResult(out.reshape(self.height, self.width), st.ms, ranges, work)


def bad_fraction(disparity: np.ndarray, truth: np.ndarray, threshold: float = 2.0,
                 mask: np.ndarray | None = None) -> tuple[float | None, float | None]:
    """(bad, density) over the pixels where the truth is finite (and mask): bad = fraction whose
    estimate is missing (NaN) or off by more than threshold px (Middlebury's bad-2.0 with
    invalid pixels counted bad); density = fraction with an estimate. None when no pixel."""
    sel = np.isfinite(truth)
    if mask is not None:
        sel &= mask
    n = int(np.count_nonzero(sel))
    if n == 0:
        return None, None
    est, gt = disparity[sel], truth[sel]
    good = np.abs(est - gt) <= threshold          # NaN: False
    return float(1.0 - np.count_nonzero(good) / n), float(np.count_nonzero(np.isfinite(est)) / n)
