"""What /foveation/detections_2d (vision_msgs/Detection2DArray) says about a pass-2 detection:
its box as centre and size, and its class hypotheses. ROS-free; the node builds the message.

Box convention (what a consumer back-projecting the box needs): pixel coordinates are those of
sensor_msgs/CameraInfo's K, integer values at pixel centres (u right, v down, in the full
resolution image the node received). A Detection's box (x0, y0, x1, y1) holds the pixels x0..x1
and y0..y1, inclusive, so

    centre = ((x0 + x1) / 2, (y0 + y1) / 2)       the pixel coordinate K maps to the box's ray
    size   = (x1 - x0 + 1, y1 - y0 + 1)           from the left edge of pixel x0 to the right
                                                  edge of pixel x1 (and rows alike)

i.e. the box's edges are centre -+ size / 2 = x0 - 0.5 and x1 + 0.5. It is the box of the custom
/foveation/detections message (x_offset = x0, width = x1 - x0 + 1) and its centre is the point
the node saccades to (Detection.centre). The box is axis-aligned (theta 0).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from foveation_node.core.recognition import Box, Detection


def box_centre_size(box: Box) -> tuple[float, float, float, float]:
    """(centre u, centre v, width, height) px of an inclusive (x0, y0, x1, y1) box (see the
    module docstring). Raises ValueError for a box with x1 < x0 or y1 < y0."""
    x0, y0, x1, y1 = box
    if x1 < x0 or y1 < y0:
        raise ValueError(f'not a box (x0, y0, x1, y1) with x0 <= x1 and y0 <= y1: {box}')
    return ((x0 + x1) / 2.0, (y0 + y1) / 2.0, float(x1 - x0 + 1), float(y1 - y0 + 1))


def ranked_hypotheses(detection: Detection, probs_second: np.ndarray, labels: Sequence[str],
                      top_k: int) -> list[tuple[str, float]]:
    """(label, probability) pairs of a pass-2 detection, at most top_k, best first: the
    detection's own label and score, then the other classes of its row of probs_second (the
    image foveated where it was found) in decreasing probability (the reject class too, if the
    model has one: how likely "no object" was there). Ties keep the label order.

    Raises ValueError for a detection without a pass-2 row, a row outside probs_second, a row
    of another length than labels, or top_k < 1.
    """
    if top_k < 1:
        raise ValueError(f'top_k must be >= 1, got {top_k}')
    row = detection.row
    if row is None:
        raise ValueError(f'{detection.label!r} (pass {detection.pass_index}) has no pass-2 row')
    probs = np.asarray(probs_second)
    if probs.ndim != 2 or not 0 <= row < probs.shape[0]:
        raise ValueError(f'row {row} is not in pass-2 probabilities of shape {probs.shape}')
    if probs.shape[1] != len(labels):
        raise ValueError(f'pass-2 probabilities have {probs.shape[1]} classes but there are '
                         f'{len(labels)} labels')
    out = [(detection.label, float(detection.score))]
    for c in np.argsort(-probs[row], kind='stable'):
        if len(out) >= top_k:
            break
        if int(c) != detection.class_id:
            out.append((labels[int(c)], float(probs[row, c])))
    return out


__all__ = ['box_centre_size', 'ranked_hypotheses']
