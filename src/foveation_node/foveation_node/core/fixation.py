"""Where the foveation node fixates: the fixation for an image size (negative: the centre), and
the uniform-resolution sensor that ignores it."""

from __future__ import annotations

import numpy as np

from vizzy_vision.image_checks import check_fixation


def fixation_for(width: int, height: int, u: float, v: float) -> tuple[float, float]:
    """The fixation (u0, v0) for a width x height image: a negative coordinate is the centre.

    Raises ValueError if the result lies outside the image.
    """
    u0 = (width - 1) / 2.0 if u < 0 else float(u)
    v0 = (height - 1) / 2.0 if v < 0 else float(v)
    return check_fixation((u0, v0), width, height)


def unfoveated(image: np.ndarray, fixation: tuple[float, float]) -> np.ndarray:
    """The uniform-resolution sensor: the frame as it is, wherever the fixation."""
    return image
