"""Input checks shared by the foveation and log-polar cores: one clear ValueError per problem."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: Pixel types the cores accept (OpenCV's pyramid and remap functions support all four).
SUPPORTED_DTYPES: tuple[type[np.generic], ...] = (np.uint8, np.uint16, np.float32, np.float64)
#: Channel counts the cores accept: grey, RGB/BGR, RGBA/BGRA.
SUPPORTED_CHANNELS: tuple[int, ...] = (1, 3, 4)


def check_image(image: Any, name: str = 'image') -> tuple[int, int, int]:
    """Check an (H, W) or (H, W, C) image and return (height, width, channels).

    Raises ValueError naming the problem: not an array, zero size, wrong number of dimensions,
    an unsupported channel count or pixel type.
    """
    if not isinstance(image, np.ndarray):
        raise ValueError(f'{name} must be a numpy array, got {type(image).__name__}')
    if image.ndim not in (2, 3):
        raise ValueError(f'{name} must be (H, W) or (H, W, C), got shape {image.shape}')
    if image.size == 0:
        raise ValueError(f'{name} is empty (shape {image.shape})')
    channels = 1 if image.ndim == 2 else image.shape[2]
    if channels not in SUPPORTED_CHANNELS:
        raise ValueError(f'{name} has {channels} channels; supported: '
                         f'{", ".join(map(str, SUPPORTED_CHANNELS))}')
    if image.dtype.type not in SUPPORTED_DTYPES:
        raise ValueError(f'{name} has dtype {image.dtype}; supported: '
                         f'{", ".join(np.dtype(t).name for t in SUPPORTED_DTYPES)}')
    return image.shape[0], image.shape[1], channels


def check_count(name: str, value: Any) -> int:
    """Check a positive integer (not bool) and return it as int."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f'{name} must be a positive integer, got {value!r}')
    return int(value)


def check_size(width: Any, height: Any) -> tuple[int, int]:
    """Check an image size (positive integers) and return it as (width, height)."""
    return check_count('width', width), check_count('height', height)


def check_fixation(fixation: Any, width: int, height: int) -> tuple[float, float]:
    """Check a fixation (u0, v0) = (column, row) in pixels; it must lie on the image.

    The image's pixel centres span [0, width - 1] x [0, height - 1]; a fixation outside that
    rectangle, non-finite, or not a pair of numbers raises ValueError.
    """
    try:
        u0, v0 = (float(c) for c in fixation)
    except (TypeError, ValueError):
        raise ValueError(f'fixation must be a pair (u0, v0) of numbers, got {fixation!r}') from None
    if not (math.isfinite(u0) and math.isfinite(v0)):
        raise ValueError(f'fixation must be finite, got ({u0}, {v0})')
    if not (0.0 <= u0 <= width - 1 and 0.0 <= v0 <= height - 1):
        raise ValueError(f'fixation ({u0:g}, {v0:g}) is outside the {width}x{height} image '
                         f'(u0 in [0, {width - 1}], v0 in [0, {height - 1}])')
    return u0, v0


def check_positive(name: str, value: Any) -> float:
    """Check a finite, strictly positive number and return it as float."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be a number, got {value!r}') from None
    if not (math.isfinite(number) and number > 0.0):
        raise ValueError(f'{name} must be finite and > 0, got {value!r}')
    return number


def check_levels(levels: Any, max_levels: int = 12) -> int:
    """Check a pyramid level count K (an integer in [1, max_levels])."""
    if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)) \
            or not 1 <= levels <= max_levels:
        raise ValueError(f'levels must be an integer in [1, {max_levels}], got {levels!r}')
    return int(levels)
