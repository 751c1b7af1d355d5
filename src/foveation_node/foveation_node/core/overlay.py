"""The foveated image with what the CNN saw drawn on it (the node's ~/overlay topic).

Boxes with label and score, one colour per recognition pass (pass 1: the whole foveated view;
pass 2: the saccade's re-examination), the fixation point and the fovea (a circle of radius f0, the
size of the full-resolution centre, Eq. 2.3), and a legend in the corner naming every colour.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from vizzy_runtime.overlay import FONT, draw_legend, drawing_scale

# RGB colours (the overlay is rgb8), by FoveatedDetection.pass_index (0: pass 1, 1: pass 2)
PASS_COLOURS: dict[int, tuple[int, int, int]] = {0: (40, 220, 40), 1: (255, 150, 0)}
FIXATION_COLOUR = (0, 200, 255)
LEGEND = ((PASS_COLOURS[0], 'pass 1 detection'), (PASS_COLOURS[1], 'pass 2 (fixating the box)'),
          (FIXATION_COLOUR, 'fixation + fovea (f0)'))


@dataclass(frozen=True)
class Box:
    """A detection to draw: pixel box (x, y, w, h) in the image, label, score in [0, 1], and
    pass_index as FoveatedDetection has it (0: the first pass, 1: the second)."""

    x: float
    y: float
    w: float
    h: float
    label: str
    score: float
    pass_index: int = 0


def draw_overlay(image: np.ndarray, boxes: Sequence[Box], fixation: tuple[float, float] | None,
                 fovea_radius_px: float | None) -> np.ndarray:
    """A copy of image (H x W x 3 rgb8, or mono8, converted) with boxes, fixation, fovea, legend."""
    out = cv2.cvtColor(image, cv2.COLOR_GRAY2RGB) if image.ndim == 2 else image.copy()
    s, thick = drawing_scale(out)
    h, w = out.shape[:2]
    for b in boxes:
        colour = PASS_COLOURS.get(int(b.pass_index), PASS_COLOURS[1])
        x0, y0 = int(round(b.x)), int(round(b.y))
        x1, y1 = int(round(b.x + b.w)), int(round(b.y + b.h))
        cv2.rectangle(out, (x0, y0), (x1, y1), colour, thick)
        text = f'{b.label} {b.score:.2f}'
        (tw, th), base = cv2.getTextSize(text, FONT, 0.5 * s, thick)
        ty = y0 - 4 if y0 - th - 6 >= 0 else min(h - 1, y1 + th + 4)
        cv2.rectangle(out, (x0, ty - th - 2), (min(w - 1, x0 + tw + 4), ty + base), colour, -1)
        cv2.putText(out, text, (x0 + 2, ty), FONT, 0.5 * s, (0, 0, 0), thick, cv2.LINE_AA)
    if fixation is not None and all(np.isfinite(fixation)):
        u, v = int(round(fixation[0])), int(round(fixation[1]))
        arm = int(round(10 * s))
        cv2.line(out, (u - arm, v), (u + arm, v), FIXATION_COLOUR, thick)
        cv2.line(out, (u, v - arm), (u, v + arm), FIXATION_COLOUR, thick)
        if fovea_radius_px is not None and np.isfinite(fovea_radius_px) and fovea_radius_px > 0:
            cv2.circle(out, (u, v), int(round(fovea_radius_px)), FIXATION_COLOUR, thick)
    draw_legend(out, LEGEND)
    return out


__all__ = ['Box', 'FIXATION_COLOUR', 'LEGEND', 'PASS_COLOURS', 'draw_overlay']
