"""stereo_file: the disparity map of a rectified stereo pair, as one of the three sensors sees it.

    stereo_file LEFT RIGHT [--sensor logpolar|cartesian|full] [--out D.npy]
                [--focal PX --baseline M [--depth-range NEAR FAR]] [--disparity-range MIN MAX]
                [--fixation X Y] [--n-rf 200]

LEFT and RIGHT: a rectified pair (same size, epipolar lines along the rows; any image OpenCV
reads). The disparity is d = x_left - x_right px, so a point's depth is focal * baseline / d.

- `--sensor logpolar` (default): the log-polar retina of n_rf rings x n_rf wedges fixating
  `--fixation` (default the image centre); SGBM at full resolution inside its fovea (where the
  RFs are at least one pixel apart: 31.8 px for 200 x 200 on 640x480) and on pyramid level l
  where they are 2^l px apart, up to `--max-level` (2) for the rest
  (`core.multires.FoveatedSGBM`).
- `--sensor cartesian`: SGBM on the n_rf x n_rf Cartesian sensor's view (area resize).
- `--sensor full`: SGBM on the full-resolution pair (the baseline).

Search range: `--disparity-range MIN MAX` px if given; else from the geometry, d = f b / Z for Z
in `--depth-range` (default 0.3 m to infinity) when `--focal` and `--baseline` are given; else
[0, width / 3). Every sensor first narrows that window on a coarse pyramid level of the whole
pair (the log-polar sensor then narrows it level by level), so a generous window costs little.

Output: one JSON line: `ms` (wall time to compute the disparities: no start-up, no file I/O),
`cpu_ms` (CPU time of this process over the same span), `stages_ms` (wall ms per stage),
`valid_points` (pixels with a disparity), `valid_fraction`, `window` (the searched window),
`searched` (the ranges each stage searched), `fixation`, and for the log-polar sensor
`fovea_radius_px` and `levels`; with --focal and --baseline, `fixation_depth_m` (median depth
within 5 px of the fixation; null if none). `--out D.npy` writes the float32 disparity map at
the input resolution, NaN where unknown. Exit status 2 with one line on stderr for bad input.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn

import cv2
import numpy as np

from .core.multires import (
    MAX_LEVEL,
    DisparityResult,
    DisparityWindow,
    FoveatedSGBM,
    SGBMParams,
    cartesian_disparity,
    coarse_window,
    full_disparity,
    parallel_window,
)

PROG = 'stereo_file'
SENSORS = ('logpolar', 'cartesian', 'full')
DEFAULT_NEAR_M = 0.3
_SGBM_DEFAULTS = SGBMParams()   # frozen: one shared default instance is safe


class _Parser(argparse.ArgumentParser):
    """argparse whose errors are one line `stereo_file: <message>` and exit status 2."""

    def error(self, message: str) -> NoReturn:
        print(f'{PROG}: {message} (see --help)', file=sys.stderr)
        raise SystemExit(2)


class InputError(ValueError):
    """A problem with the user's input: one line, exit status 2."""


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog=PROG, description='Disparity map of a rectified stereo pair (log-polar, '
                'Cartesian or full-resolution SGBM); prints one JSON line.')
    p.add_argument('left', type=Path, help='left image of the rectified pair')
    p.add_argument('right', type=Path, help='right image (same size)')
    p.add_argument('--sensor', choices=SENSORS, default='logpolar',
                   help='what the matcher sees (default logpolar)')
    p.add_argument('--out', type=Path, help='write the float32 disparity map (.npy, input '
                   'resolution, NaN where unknown)')
    p.add_argument('--focal', type=float, metavar='PX', help='focal length [px]')
    p.add_argument('--baseline', type=float, metavar='M', help='baseline [m]')
    p.add_argument('--depth-range', type=float, nargs=2, metavar=('NEAR', 'FAR'),
                   help=f'depths searched [m] (needs --focal and --baseline; default '
                   f'{DEFAULT_NEAR_M} to inf)')
    p.add_argument('--disparity-range', type=float, nargs=2, metavar=('MIN', 'MAX'),
                   help='disparities searched [px], MIN <= d < MAX (overrides the geometry)')
    p.add_argument('--fixation', type=float, nargs=2, metavar=('X', 'Y'),
                   help='fixation point in the left image [px] (default the image centre)')
    p.add_argument('--n-rf', type=int, default=200,
                   help='RFs per side: n x n rings x wedges / grid (default 200)')
    p.add_argument('--max-level', type=int, default=MAX_LEVEL,
                   help=f'logpolar: the coarsest pyramid level matched, in [0, 5] (default '
                   f'{MAX_LEVEL}: 1/{2 ** MAX_LEVEL} resolution in the far periphery; 0 is '
                   f'full resolution everywhere)')
    return p


def read_image(path: Path) -> np.ndarray:
    """RGB uint8 (H, W, 3); InputError naming the file otherwise."""
    if not path.is_file():
        raise InputError(f'{path}: no such file')
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise InputError(f'{path}: not an image OpenCV can read')
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def search_window(args: argparse.Namespace, width: int) -> DisparityWindow:
    """The window to search, from the arguments (see the module docstring)."""
    if (args.focal is None) != (args.baseline is None):
        raise InputError('--focal and --baseline go together')
    for name in ('focal', 'baseline'):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f'--{name} must be a positive number, got {value:g}')
    if args.depth_range is not None and args.focal is None:
        raise InputError('--depth-range needs --focal and --baseline')
    if args.disparity_range is not None:
        lo, hi = args.disparity_range
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise InputError(f'--disparity-range needs finite MIN < MAX, got {lo:g} {hi:g}')
        if hi - lo > 4 * width:
            raise InputError(f'--disparity-range {lo:g} {hi:g} is wider than 4 image widths')
        return DisparityWindow(lo, hi)
    if args.focal is not None:
        near, far = args.depth_range or (DEFAULT_NEAR_M, math.inf)
        if not (near > 0 and far > near and not math.isnan(far)):
            raise InputError(f'--depth-range needs 0 < NEAR < FAR, got {near:g} {far:g}')
        win = parallel_window(args.focal, args.baseline, near, far)
        # a disparity beyond the image width cannot be matched
        return DisparityWindow(win.lo, max(win.lo + 1, min(win.hi, width)))
    return DisparityWindow(0, max(16, width // 3))


def compute(left: np.ndarray, right: np.ndarray, sensor: str, window: DisparityWindow,
            fixation: tuple[float, float], n_rf: int, params: SGBMParams = _SGBM_DEFAULTS,
            max_level: int = MAX_LEVEL) -> tuple[DisparityResult, dict]:
    """(result, extra JSON fields); the set-up (retina geometry, level maps) is not timed."""
    h, w = left.shape[:2]
    extra: dict = {}
    if sensor == 'logpolar':
        from vizzy_vision.logpolar import LogPolarRetina

        from .core.sensors import fovea_radius
        retina = LogPolarRetina(w, h, rings=n_rf, wedges=n_rf, center=fixation)
        matcher = FoveatedSGBM(w, h, fovea_radius(retina), fixation, max_level, params)
        extra = {'fovea_radius_px': round(matcher.fovea_radius, 2), 'levels': matcher.n_levels}

        def run() -> DisparityResult:
            return matcher.compute(left, right, window)
    else:
        def run() -> DisparityResult:
            t0 = time.perf_counter()
            narrowed = coarse_window(left, right, window, params)
            ms = 1e3 * (time.perf_counter() - t0)
            if sensor == 'full':
                res = full_disparity(left, right, narrowed, params)
            else:
                res = cartesian_disparity(left, right, narrowed, (n_rf, n_rf), params)
            res.stages_ms = {'range search': round(ms, 3), **res.stages_ms}
            res.ranges = {'search': narrowed.to_json(), **res.ranges}
            return res
    return _timed(run), extra


def _timed(run: Callable[[], DisparityResult]) -> DisparityResult:
    c0, t0 = time.process_time(), time.perf_counter()
    res = run()
    res.stages_ms = {'total': 1e3 * (time.perf_counter() - t0),
                     'cpu_total': 1e3 * (time.process_time() - c0), **res.stages_ms}
    return res


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if not 16 <= args.n_rf <= 1024:
            raise InputError(f'--n-rf must be in [16, 1024], got {args.n_rf}')
        if not 0 <= args.max_level <= 5:
            raise InputError(f'--max-level must be in [0, 5], got {args.max_level}')
        left, right = read_image(args.left), read_image(args.right)
        if left.shape != right.shape:
            raise InputError(f'{args.right}: {right.shape[1]}x{right.shape[0]} differs from '
                             f'{args.left}: {left.shape[1]}x{left.shape[0]}')
        h, w = left.shape[:2]
        if min(w, h) < 32:
            raise InputError(f'{args.left}: {w}x{h} is too small (at least 32x32)')
        fixation = ((w - 1) / 2.0, (h - 1) / 2.0) if args.fixation is None else \
            tuple(args.fixation)
        if not all(math.isfinite(v) for v in fixation) or not (
                0 <= fixation[0] <= w - 1 and 0 <= fixation[1] <= h - 1):
            raise InputError(f'--fixation {fixation[0]:g} {fixation[1]:g} is outside the '
                             f'{w}x{h} image')
        window = search_window(args, w)
        if args.out is not None and args.out.is_dir():
            raise InputError(f'{args.out}: is a folder (--out names the .npy file)')
        if args.out is not None and not args.out.parent.is_dir():
            raise InputError(f'{args.out}: its folder does not exist')
    except InputError as exc:
        print(f'{PROG}: {exc}', file=sys.stderr)
        return 2
    res, extra = compute(left, right, args.sensor, window, fixation, args.n_rf,
                         max_level=args.max_level)
    stages = dict(res.stages_ms)
    ms, cpu_ms = stages.pop('total'), stages.pop('cpu_total')
    disp = res.disparity
    out = {'left': str(args.left), 'right': str(args.right), 'sensor': args.sensor,
           'width': w, 'height': h, 'ms': round(ms, 2), 'cpu_ms': round(cpu_ms, 2),
           'stages_ms': {k: round(v, 2) for k, v in stages.items()},
           'valid_points': res.valid_points,
           'valid_fraction': round(res.valid_points / disp.size, 4),
           'window': window.to_json(), 'searched': res.ranges,
           'fixation': [round(float(v), 2) for v in fixation], **extra}
    if args.focal is not None:
        ys, xs = np.mgrid[0:h, 0:w]
        near = np.hypot(xs - fixation[0], ys - fixation[1]) <= 5.0
        d = disp[near]
        d = d[np.isfinite(d) & (d > 0)]
        out['fixation_depth_m'] = (round(float(args.focal * args.baseline / np.median(d)), 4)
                                   if d.size else None)
    if args.out is not None:
        try:
            with open(args.out, 'wb') as f:         # exactly this name (np.save adds .npy)
                np.save(f, disp.astype(np.float32))
        except OSError as exc:
            print(f'{PROG}: {args.out}: cannot write: {exc.strerror or exc}', file=sys.stderr)
            return 2
    print(json.dumps(out, allow_nan=False))
    return 0


if __name__ == '__main__':
    sys.exit(main())
