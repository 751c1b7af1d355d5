"""Camera calibration files as ROS 2 cameras keep them, and `vizzy_camera_calibration`.

A camera driver finds its calibration at its `camera_info_url` (camera_info_manager): a
`file:///absolute/path.yaml` or `package://<package>/<path in its share directory>` URL, where
`${NAME}` stands for the camera's name and `${ROS_HOME}` for $ROS_HOME (default ~/.ros). The file
is camera_calibration_parsers' YAML, what the `cameracalibrator` GUI saves:

    image_width: 640
    image_height: 480
    camera_name: vizzy_left
    camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
    distortion_model: plumb_bob
    distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, t1, t2, k3]}
    rectification_matrix: {rows: 3, cols: 3, data: [...]}
    projection_matrix: {rows: 3, cols: 4, data: [fx', 0, cx', Tx, 0, fy', cy', 0, 0, 0, 1, 0]}

The sim computes each camera's calibration from MuJoCo (sim_calibration); with a camera's
`<camera>_camera_info_url` set it publishes the file's instead (load_calibration), so a real
head's calibration has a place to live. This tool writes the sim's own as such a file:

    vizzy_camera_calibration left                  # the left eye's, to stdout
    vizzy_camera_calibration right -o right.yaml   # the right eye's (P carries the baseline)
    vizzy_camera_calibration rgbd --width 320 --height 240
    vizzy_camera_calibration --check file:///path/left.yaml --width 640 --height 480

(`python -m vizzy_sim_bridge.camera_calibration` where the console script is not installed.)
ROS-free: PyYAML and numpy only.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from vizzy_vision.camera import camera_matrix, projection_matrix

# Coefficients each distortion model of sensor_msgs/distortion_models.h takes; other models
# (a driver's own) are passed through with whatever count the file gives.
DISTORTION_COEFFICIENTS = {'plumb_bob': 5, 'rational_polynomial': 8, 'equidistant': 4}
# The focal lengths every consumer accepts (vizzy_runtime.convert.camera_k): a file outside them
# would be refused by every node downstream, so it is refused here, at the source.
MIN_FOCAL_PX = 1.0
MAX_FOCAL_PX = 1e6
# What the sim's cameras are called in their files (camera_info_manager: letters, digits, _).
CAMERA_NAMES = {'left': 'vizzy_left', 'right': 'vizzy_right', 'rgbd': 'vizzy_rgbd'}


class CalibrationError(ValueError):
    """A calibration URL or file that cannot be used; str() is one line saying why."""


@dataclass(frozen=True)
class Calibration:
    """One camera's calibration: sensor_msgs/CameraInfo's fields, matrices row-major."""

    camera_name: str
    width: int
    height: int
    k: tuple[float, ...]            # 3x3
    distortion_model: str
    d: tuple[float, ...]
    r: tuple[float, ...]            # 3x3
    p: tuple[float, ...]            # 3x4


def sim_calibration(camera_name: str, width: int, height: int, hfov_deg: float,
                    baseline_m: float = 0.0) -> Calibration:
    """The sim's ideal pinhole: K from the field of view (square pixels, centred), no
    distortion, R = I, P = [K | (-fx baseline_m, 0, 0)] (the right eye of a rectified pair)."""
    k = camera_matrix(width, height, hfov_deg)
    return Calibration(camera_name, int(width), int(height), _floats(k), 'plumb_bob',
                       (0.0,) * 5, _floats(np.eye(3)), _floats(projection_matrix(k, baseline_m)))


def _floats(values: Any) -> tuple[float, ...]:
    return tuple(float(v) + 0.0 for v in np.asarray(values, np.float64).reshape(-1))  # no -0.0


# ------------------------------------------------------------------ writing
def _number(v: float) -> str:
    """As short as it reads back exactly: 0, 1, 319.5, 346.78101337..., 1.0e-05 (YAML 1.1
    readers such as PyYAML take an exponent only after a '.')."""
    if v.is_integer() and abs(v) < 1e15:
        return str(int(v))
    text = repr(v)
    mantissa, e, exponent = text.partition('e')
    return f'{mantissa}.0e{exponent}' if e and '.' not in mantissa else text


def _matrix(key: str, rows: int, cols: int, data: Sequence[float]) -> str:
    return (f'{key}:\n  rows: {rows}\n  cols: {cols}\n'
            f'  data: [{", ".join(_number(v) for v in data)}]\n')


def to_yaml(cal: Calibration, comment: str = '') -> str:
    """The calibration in camera_calibration_parsers' layout (its keys, in its order; each
    matrix a rows/cols/data map), after comment lines if given."""
    head = ''.join(f'# {line}\n' for line in comment.splitlines())
    return (head + f'image_width: {cal.width}\nimage_height: {cal.height}\n'
            f'camera_name: {cal.camera_name}\n'
            + _matrix('camera_matrix', 3, 3, cal.k)
            + f'distortion_model: {cal.distortion_model}\n'
            + _matrix('distortion_coefficients', 1, len(cal.d), cal.d)
            + _matrix('rectification_matrix', 3, 3, cal.r)
            + _matrix('projection_matrix', 3, 4, cal.p))


# ------------------------------------------------------------------ reading
def _int(doc: dict[str, Any], key: str) -> int:
    if key not in doc:
        raise CalibrationError(f'no {key}')
    v = doc[key]
    if isinstance(v, bool) or not isinstance(v, int) or not 0 < v <= 1 << 20:
        raise CalibrationError(f'{key} must be a positive integer, got {v!r}')
    return v


def _read_matrix(doc: dict[str, Any], key: str, rows: int | None,
                 cols: int | None) -> tuple[float, ...]:
    """A rows/cols/data map; rows or cols None: any (the distortion coefficients)."""
    if key not in doc:
        raise CalibrationError(f'no {key}')
    m = doc[key]
    if not isinstance(m, dict) or not {'rows', 'cols', 'data'} <= set(m):
        raise CalibrationError(f'{key} must be a map of rows, cols and data')
    r, c, data = m['rows'], m['cols'], m['data']
    if not all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in (r, c)):
        raise CalibrationError(f'{key}: rows and cols must be integers, got {r!r}, {c!r}')
    if (rows is not None and r != rows) or (cols is not None and c != cols):
        raise CalibrationError(f'{key} must be {rows}x{cols}, got {r}x{c}')
    if not isinstance(data, list) or len(data) != r * c:
        n = len(data) if isinstance(data, list) else type(data).__name__
        raise CalibrationError(f'{key}: data must list rows x cols = {r * c} numbers, got {n}')
    values = [_as_float(v) for v in data]
    if not all(v is not None and math.isfinite(v) for v in values):
        raise CalibrationError(f'{key}: data must be finite numbers, got {data}')
    return tuple(v for v in values if v is not None)


def _as_float(v: Any) -> float | None:
    """A number of the file; also 1e-05, which YAML 1.1 (PyYAML) reads as a string and
    yaml-cpp, the C++ parser, as a number."""
    if isinstance(v, bool):
        return None
    if isinstance(v, (int, float)):
        return float(v)
    if isinstance(v, str):
        try:
            return float(v)
        except ValueError:
            return None
    return None


def parse_calibration(text: str) -> Calibration:
    """A Calibration from camera_calibration_parsers' YAML; CalibrationError says what is wrong.
    As that parser: camera_name defaults to 'unknown', distortion_model to plumb_bob."""
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}' if mark is not None else ''
        problem = getattr(exc, 'problem', None) or type(exc).__name__
        raise CalibrationError(f'not YAML{where}: {problem}') from None
    if not isinstance(doc, dict):
        raise CalibrationError(f'not a map of calibration fields (a {type(doc).__name__})')
    width, height = _int(doc, 'image_width'), _int(doc, 'image_height')
    name = str(doc.get('camera_name') or 'unknown')
    model = doc.get('distortion_model', 'plumb_bob')
    if not isinstance(model, str) or not model:
        raise CalibrationError(f'distortion_model must be a name, got {model!r}')
    k = _read_matrix(doc, 'camera_matrix', 3, 3)
    d = _read_matrix(doc, 'distortion_coefficients', None, None)
    r = _read_matrix(doc, 'rectification_matrix', 3, 3)
    p = _read_matrix(doc, 'projection_matrix', 3, 4)
    want = DISTORTION_COEFFICIENTS.get(model)
    if want is not None and len(d) != want:
        raise CalibrationError(f'{model} takes {want} distortion coefficients, got {len(d)}')
    for key, fx, fy in (('camera_matrix', k[0], k[4]), ('projection_matrix', p[0], p[5])):
        if not (MIN_FOCAL_PX <= fx <= MAX_FOCAL_PX and MIN_FOCAL_PX <= fy <= MAX_FOCAL_PX):
            raise CalibrationError(f'{key}: fx, fy must be in [{MIN_FOCAL_PX:g}, '
                                   f'{MAX_FOCAL_PX:g}] px, got {fx:g}, {fy:g}')
    return Calibration(name, width, height, k, model, d, r, p)


def resolve_url(url: str, camera_name: str) -> Path:
    """The file a camera_info_url names, as camera_info_manager resolves it: ${NAME} and
    ${ROS_HOME} substituted, then file:///<absolute path> or package://<package>/<path>."""
    resolved = url.replace('${NAME}', camera_name)
    if '${ROS_HOME}' in resolved:
        ros_home = os.environ.get('ROS_HOME') or str(Path.home() / '.ros')
        resolved = resolved.replace('${ROS_HOME}', ros_home)
    if resolved[:8].lower() == 'file:///':
        return Path(resolved[7:])
    if resolved[:10].lower() == 'package://':
        package, _, rest = resolved[10:].partition('/')
        if not package or not rest:
            raise CalibrationError(f'{url!r}: expected package://<package>/<path>')
        from vizzy_runtime.launcher import LaunchError, share_dir  # ROS's index, else src/
        try:
            return share_dir(package) / rest
        except LaunchError as exc:
            raise CalibrationError(f'{url!r}: {exc}') from None
    raise CalibrationError(f'{url!r} is no calibration URL: expected file:///<absolute path> '
                           'or package://<package>/<path>')


def load_calibration(url: str, camera_name: str, width: int, height: int) -> Calibration:
    """The calibration at url for a width x height camera; CalibrationError (one line) when the
    URL, the file or its contents cannot be used, or its image size is not width x height."""
    path = resolve_url(url, camera_name)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise CalibrationError(f'cannot read {path}: {why}') from None
    try:
        cal = parse_calibration(text)
    except CalibrationError as exc:
        raise CalibrationError(f'{path}: {exc}') from None
    if (cal.width, cal.height) != (width, height):
        raise CalibrationError(f'{path} is for {cal.width}x{cal.height} images, the camera '
                               f'gives {width}x{height}')
    return cal


# ------------------------------------------------------------------ the tool
def choose_calibration(param: str, url: str, computed: Calibration,
                       log: Any) -> tuple[Calibration, str]:
    """(calibration, source) a node publishes for parameter param = url: the file at url if one
    is set and usable, source url; else computed, source 'computed' (with one error line on log
    saying why the file is not used)."""
    if not url:
        return computed, 'computed'
    try:
        cal = load_calibration(url, computed.camera_name, computed.width, computed.height)
    except CalibrationError as exc:
        log.error(f'{param}: {exc}; publishing the calibration computed '
                  f'from MuJoCo (fx {computed.k[0]:.3f} px)')
        return computed, 'computed'
    if cal.camera_name != computed.camera_name:   # as camera_info_manager: a warning
        log.warning(f'{param}: the file is for camera {cal.camera_name!r}, '
                    f'this is {computed.camera_name!r}; using it')
    log.info(f'{param}: {cal.camera_name} calibration from {url} (fx '
             f'{cal.k[0]:.3f} px; images rendered with fx '
             f'{computed.k[0]:.3f} px)')
    return cal, url


def _sim_defaults() -> dict[str, Any]:
    from vizzy_sim_bridge.sim_node import PARAMETERS  # the sim's own defaults (imports MuJoCo)
    return {p.name: p.default for p in PARAMETERS}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='vizzy_camera_calibration',
        description="Write the simulated head's camera calibration as a camera_info_url file "
        "(camera_calibration_parsers YAML), or check such a file.")
    parser.add_argument('camera', nargs='?', choices=tuple(CAMERA_NAMES), default='left',
                        help='which camera (default: left)')
    parser.add_argument('-o', '--output', type=Path, help='write to this file, not stdout')
    parser.add_argument('--width', type=int, help="image width [px] (default: the sim's)")
    parser.add_argument('--height', type=int, help="image height [px] (default: the sim's)")
    parser.add_argument('--horizontal-fov-deg', type=float,
                        help="horizontal field of view [deg] (default: the sim's)")
    parser.add_argument('--check', metavar='URL',
                        help='instead: load this camera_info_url for the camera as the sim '
                        'would and print its K, or why it cannot be used')
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    defaults = _sim_defaults()
    prefix = 'rgbd_' if args.camera == 'rgbd' else ''
    width = args.width or int(defaults[f'{prefix}width'])
    height = args.height or int(defaults[f'{prefix}height'])
    name = CAMERA_NAMES[args.camera]
    prog = 'vizzy_camera_calibration'
    if args.check is not None:
        try:
            cal = load_calibration(args.check, name, width, height)
        except CalibrationError as exc:
            print(f'{prog}: {exc}', file=sys.stderr)
            return 1
        print(f'{args.check}: {cal.camera_name} {cal.width}x{cal.height}, fx {cal.k[0]:g}, '
              f'fy {cal.k[4]:g}, cx {cal.k[2]:g}, cy {cal.k[5]:g}, {cal.distortion_model} '
              f'{list(cal.d)}')
        return 0
    hfov = args.horizontal_fov_deg or float(defaults[f'{prefix}horizontal_fov_deg'])
    if args.camera == 'right':
        from vizzy_vision.kinematics import BASELINE
        baseline = BASELINE
    else:
        baseline = 0.0
    try:
        cal = sim_calibration(name, width, height, hfov, baseline)
    except ValueError as exc:
        print(f'{prog}: {exc}', file=sys.stderr)
        return 2
    text = to_yaml(cal, f"The simulated Vizzy head's {args.camera} camera: {width}x{height}, "
                        f'{hfov:g} deg horizontal FOV (written by {prog}).\n'
                        f'A real camera\'s file has the same keys; the sim reads it from '
                        f'{args.camera}_camera_info_url.')
    if args.output is None:
        sys.stdout.write(text)
        return 0
    try:
        args.output.write_text(text)
    except OSError as exc:
        print(f'{prog}: cannot write {args.output}: {exc.strerror or exc}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
