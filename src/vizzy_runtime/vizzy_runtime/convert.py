"""numpy <-> sensor_msgs conversions without per-element Python work.

They work on the bundled runtime's messages (data is a numpy array) and on real rclpy's
(data is array.array / bytes): both expose the buffer protocol, read here with np.frombuffer.
"""

from __future__ import annotations

import array
import math
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

from .ros import USING_REAL_ROS, message

# encoding -> (dtype, channels); the subset of sensor_msgs/image_encodings the graph uses.
IMAGE_ENCODINGS: dict[str, tuple[str, int]] = {
    'rgb8': ('u1', 3), 'bgr8': ('u1', 3), 'rgba8': ('u1', 4), 'bgra8': ('u1', 4),
    'mono8': ('u1', 1), 'mono16': ('u2', 1), '8UC1': ('u1', 1), '8UC3': ('u1', 3),
    '16UC1': ('u2', 1), '32FC1': ('f4', 1), '64FC1': ('f8', 1),
}

# sensor_msgs/PointField datatypes
_POINTFIELD_DTYPES = {1: 'i1', 2: 'u1', 3: 'i2', 4: 'u2', 5: 'i4', 6: 'u4', 7: 'f4', 8: 'f8'}
_DTYPE_POINTFIELD = {np.dtype(v).str[1:]: k for k, v in _POINTFIELD_DTYPES.items()}


class ConversionError(ValueError):
    """A message that cannot be viewed as the requested array (encoding, size, layout)."""


def stamp_seconds(stamp: Any) -> float:
    """A builtin_interfaces/Time (a header's stamp) in seconds."""
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


def stamp_msg(t: float) -> Any:
    """builtin_interfaces/Time of t [s] (stamp_seconds' inverse)."""
    sec = math.floor(t)
    return message('builtin_interfaces/msg/Time')(
        sec=int(sec), nanosec=min(int(round((t - sec) * 1e9)), 999_999_999))


# A focal length [px] outside these is no camera: 1e-300 passed a "> 0" check and put a saccade
# 0.024 m from the eyes (issue 28 item 8); the widest lens at 1 px wide or 1e6 px (a 0.06 deg
# field at VGA) bound what a real camera_info can say.
MIN_FOCAL_PX = 1.0
MAX_FOCAL_PX = 1e6


def camera_k(msg: Any) -> np.ndarray | None:
    """K (3x3, float64) of a sensor_msgs/CameraInfo if usable, else None: 9 finite values, fx and
    fy in [MIN_FOCAL_PX, MAX_FOCAL_PX], the principal point within MAX_FOCAL_PX of the origin."""
    k = np.asarray([float(v) for v in msg.k], np.float64)
    if k.size != 9 or not np.isfinite(k).all():
        return None
    if not (MIN_FOCAL_PX <= k[0] <= MAX_FOCAL_PX and MIN_FOCAL_PX <= k[4] <= MAX_FOCAL_PX):
        return None
    if abs(k[2]) > MAX_FOCAL_PX or abs(k[5]) > MAX_FOCAL_PX:
        return None
    return k.reshape(3, 3)


def _byte_view(data: Any) -> np.ndarray:
    return (np.frombuffer(data, dtype=np.uint8) if not isinstance(data, np.ndarray)
            else data.view(np.uint8))


def _set_bytes(msg: Any, field: str, buf: np.ndarray) -> None:
    """Assign a uint8 buffer the way each runtime's generated setter accepts without a Python
    loop."""
    if USING_REAL_ROS:
        setattr(msg, field, array.array('B', buf.tobytes()))
    else:
        setattr(msg, field, buf)


def image_to_numpy(msg: Any) -> np.ndarray:
    """H x W (x C) view of a sensor_msgs/Image; raises ConversionError naming the problem."""
    if msg.encoding not in IMAGE_ENCODINGS:
        raise ConversionError(f'unsupported image encoding {msg.encoding!r} '
                              f'(supported: {", ".join(sorted(IMAGE_ENCODINGS))})')
    if msg.height == 0 or msg.width == 0:
        raise ConversionError(f'empty image ({msg.width}x{msg.height})')
    kind, channels = IMAGE_ENCODINGS[msg.encoding]
    dtype = np.dtype(kind).newbyteorder('>' if msg.is_bigendian else '<')
    row = msg.width * channels * dtype.itemsize
    if msg.step < row:
        raise ConversionError(f'step {msg.step} is smaller than a row of {row} bytes')
    raw = _byte_view(msg.data)
    if raw.size < msg.step * msg.height:
        raise ConversionError(f'image data has {raw.size} bytes, expected {msg.step * msg.height} '
                              f'({msg.width}x{msg.height} {msg.encoding}, step {msg.step})')
    rows = raw[:msg.step * msg.height].reshape(msg.height, msg.step)[:, :row]
    arr = np.ascontiguousarray(rows).view(dtype) if msg.step != row else rows.view(dtype)
    shape = (msg.height, msg.width, channels) if channels > 1 else (msg.height, msg.width)
    return arr.reshape(shape)


# Why an input image is refused: short, stable reasons (InputHealth counter keys).
UNSUPPORTED_ENCODING = 'unsupported encoding'
EMPTY_IMAGE = 'empty image'
TOO_LARGE = 'too large'
SHORT_STEP = 'step shorter than a row'
SHORT_DATA = 'size inconsistent with data'
UNCONVERTIBLE = 'unconvertible image'
IMAGE_REASONS = (UNSUPPORTED_ENCODING, EMPTY_IMAGE, TOO_LARGE, SHORT_STEP, SHORT_DATA,
                 UNCONVERTIBLE)


def image_refusal(msg: Any, bytes_per_pixel: dict[str, int], *,
                  max_size: tuple[int, int] | None = None,
                  convert: Callable[[Any], Any] = image_to_numpy) -> tuple[str, str] | None:
    """(reason, detail) of why a sensor_msgs/Image cannot be used, or None if it can.

    bytes_per_pixel: the encodings accepted and their pixel sizes; max_size: the largest
    (width, height) accepted; convert: the conversion the caller will make (its ValueError, e.g.
    ConversionError, is UNCONVERTIBLE). reason is one of IMAGE_REASONS, detail names the values."""
    pixel = bytes_per_pixel.get(msg.encoding)
    if pixel is None:
        return UNSUPPORTED_ENCODING, f'{msg.encoding!r} is not one of {", ".join(bytes_per_pixel)}'
    if msg.width == 0 or msg.height == 0:
        return EMPTY_IMAGE, f'{msg.width}x{msg.height}'
    if max_size is not None and (msg.width > max_size[0] or msg.height > max_size[1]):
        return TOO_LARGE, (f'{msg.width}x{msg.height} exceeds max_width x max_height '
                           f'{max_size[0]}x{max_size[1]}')
    row = pixel * msg.width
    if msg.step < row:
        return SHORT_STEP, f'step {msg.step} < {row} bytes for {msg.width} px of {msg.encoding}'
    size = len(msg.data)
    if size < msg.step * msg.height:
        return SHORT_DATA, (f'{size} data bytes, height {msg.height} x step {msg.step} = '
                            f'{msg.step * msg.height} expected')
    try:
        convert(msg)
    except ValueError as exc:
        return UNCONVERTIBLE, str(exc)
    return None


def numpy_to_image(arr: np.ndarray, encoding: str, header: Any = None) -> Any:
    """sensor_msgs/Image holding arr (copied once into the message buffer)."""
    if encoding not in IMAGE_ENCODINGS:
        raise ConversionError(f'unsupported image encoding {encoding!r}')
    kind, channels = IMAGE_ENCODINGS[encoding]
    want = (arr.ndim == 2 and channels == 1) or (arr.ndim == 3 and arr.shape[2] == channels)
    if not want:
        raise ConversionError(f'array of shape {arr.shape} does not fit encoding {encoding}')
    arr = np.ascontiguousarray(arr, dtype=np.dtype(kind))
    msg = message('sensor_msgs/msg/Image')()
    if header is not None:
        msg.header = header
    msg.height, msg.width = int(arr.shape[0]), int(arr.shape[1])
    msg.encoding = encoding
    msg.is_bigendian = int(sys.byteorder == 'big' and arr.dtype.itemsize > 1)
    msg.step = int(arr.shape[1] * channels * arr.dtype.itemsize)
    _set_bytes(msg, 'data', arr.reshape(-1).view(np.uint8))
    return msg


def pointcloud2_dtype(msg: Any) -> np.dtype:
    """Structured dtype of one point, from the PointFields (offsets and point_step honoured)."""
    names, formats, offsets = [], [], []
    for f in msg.fields:
        if f.datatype not in _POINTFIELD_DTYPES:
            raise ConversionError(f'PointField {f.name!r} has unknown datatype {f.datatype}')
        base = np.dtype(_POINTFIELD_DTYPES[f.datatype]).newbyteorder(
            '>' if msg.is_bigendian else '<')
        names.append(f.name)
        formats.append(base if f.count <= 1 else (base, (f.count,)))
        offsets.append(f.offset)
    return np.dtype({'names': names, 'formats': formats, 'offsets': offsets,
                     'itemsize': msg.point_step})


def pointcloud2_to_array(msg: Any) -> np.ndarray:
    """Structured array (height x width) viewing a PointCloud2's data."""
    dtype = pointcloud2_dtype(msg)
    n = msg.width * msg.height
    raw = _byte_view(msg.data)
    if msg.row_step < msg.width * msg.point_step or raw.size < msg.row_step * msg.height:
        raise ConversionError(f'PointCloud2 data has {raw.size} bytes, too few for '
                              f'{msg.width}x{msg.height} points of {msg.point_step} bytes')
    if n == 0:
        return np.zeros((msg.height, msg.width), dtype=dtype)
    rows = raw[:msg.row_step * msg.height].reshape(msg.height,
                                                   msg.row_step)[:, :msg.width * msg.point_step]
    return np.ascontiguousarray(rows).view(dtype).reshape(msg.height, msg.width)


def array_to_pointcloud2(points: np.ndarray, header: Any = None, *,
                         is_dense: bool | None = None) -> Any:
    """PointCloud2 from a structured array (1-D: unorganized, 2-D: organized height x width)."""
    dtype_fields = points.dtype.fields
    if points.dtype.names is None or dtype_fields is None:  # (both None together)
        raise ConversionError('array_to_pointcloud2 needs a structured array (fields x, y, z, ...)')
    grid = points if points.ndim == 2 else points.reshape(1, -1)
    PointField = message('sensor_msgs/msg/PointField')
    msg = message('sensor_msgs/msg/PointCloud2')()
    if header is not None:
        msg.header = header
    fields = []
    for name in points.dtype.names:
        sub, offset = dtype_fields[name][:2]
        base = sub.base if sub.shape else sub
        code = _DTYPE_POINTFIELD.get(base.str[1:])
        if code is None:
            raise ConversionError(f'field {name!r} has dtype {base} with no PointField datatype')
        fields.append(PointField(name=name, offset=int(offset), datatype=code,
                                 count=int(np.prod(sub.shape)) if sub.shape else 1))
    msg.fields = fields
    msg.height, msg.width = int(grid.shape[0]), int(grid.shape[1])
    msg.is_bigendian = sys.byteorder == 'big'
    msg.point_step = int(points.dtype.itemsize)
    msg.row_step = msg.point_step * msg.width
    if is_dense is None:
        is_dense = all(not np.isnan(grid[n]).any() for n in ('x', 'y', 'z')
                       if n in points.dtype.names
                       and points.dtype[n].kind == 'f')
    msg.is_dense = bool(is_dense)
    _set_bytes(msg, 'data', np.ascontiguousarray(grid).reshape(-1).view(np.uint8))
    return msg
