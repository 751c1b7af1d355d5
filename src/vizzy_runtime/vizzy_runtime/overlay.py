"""What the nodes' overlay images share: a size-relative drawing scale and the legend that names
every colour (the overlays of foveation_node and cylinder_detector_node)."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

FONT = cv2.FONT_HERSHEY_SIMPLEX
Colour = tuple[int, int, int]


def drawing_scale(image: np.ndarray) -> tuple[float, int]:
    """(text scale factor, line thickness) for an image of this size (960 px short side = 1)."""
    s = max(0.35, min(image.shape[:2]) / 960.0)
    return s, max(1, int(round(2 * s)))


def draw_legend(out: np.ndarray, entries: Sequence[tuple[Colour, str]]) -> None:
    """A key in out's top-left corner, in place: a line of each colour and its meaning, on a
    darkened box so that it reads on any image."""
    s, thick = drawing_scale(out)
    line_h = int(round(18 * s)) + 4
    swatch = int(round(18 * s))
    box_w = max(cv2.getTextSize(t, FONT, 0.45 * s, 1)[0][0] for _, t in entries) + swatch + 20
    box_h = line_h * len(entries) + 6
    region = out[:box_h, :box_w]
    region[:] = (region * 0.35).astype(out.dtype)
    for i, (colour, text) in enumerate(entries):
        y = 4 + line_h * i + line_h // 2
        cv2.line(out, (6, y), (6 + swatch, y), colour, thick + 1)
        cv2.putText(out, text, (12 + swatch, y + int(round(5 * s))), FONT, 0.45 * s,
                    (255, 255, 255), 1, cv2.LINE_AA)


__all__ = ['FONT', 'draw_legend', 'drawing_scale']
