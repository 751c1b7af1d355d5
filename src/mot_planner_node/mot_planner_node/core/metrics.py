"""CLEAR MOT and identity metrics with py-motmetrics, IoU distances computed here.

py-motmetrics 1.4.0's ``iou_matrix`` calls ``np.asfarray``, which NumPy 2 removed, so the
distance matrix (1 - IoU, NaN where IoU < 0.5: no match allowed) is computed here and handed
to ``MOTAccumulator.update``.

MOTP is reported two ways: ``motp`` as in the thesis (Eq. 5.26: mean overlap of matched
pairs, in percent, higher is better) and ``motp_distance`` as py-motmetrics defines it (mean
1 - IoU, lower is better); ``motp = 100 (1 - motp_distance)``.
"""

from __future__ import annotations

import math
from typing import Any

import motmetrics as mm
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from .detector import box_iou

FloatArray = NDArray[np.float64]

MIN_IOU = 0.5
METRICS = ('mota', 'motp', 'idf1', 'num_frames', 'num_objects', 'num_matches', 'num_misses',
           'num_false_positives', 'num_switches', 'mostly_tracked', 'mostly_lost',
           'num_unique_objects')


def iou_distance(gt_boxes: FloatArray, hyp_boxes: FloatArray,
                 min_iou: float = MIN_IOU) -> FloatArray:
    """(n_gt, n_hyp) 1 - IoU of x, y, w, h boxes; NaN where the IoU is below min_iou."""
    iou = box_iou(gt_boxes, hyp_boxes)
    return np.where(iou >= min_iou, 1.0 - iou, np.nan)


def distractor_matches(hyp_boxes: FloatArray, distractor_boxes: FloatArray,
                       min_iou: float = MIN_IOU) -> NDArray[np.bool_]:
    """Hypotheses (n,) matched one to one (Hungarian on IoU >= min_iou) to distractors:
    the MOTChallenge devkit drops them before scoring."""
    n = np.asarray(hyp_boxes).reshape(-1, 4).shape[0]
    out = np.zeros(n, dtype=bool)
    if n == 0 or np.asarray(distractor_boxes).size == 0:
        return out
    iou = box_iou(hyp_boxes, distractor_boxes)
    rows, cols = linear_sum_assignment(np.where(iou >= min_iou, -iou, 0.0))
    out[rows[iou[rows, cols] >= min_iou]] = True
    return out


class MotEvaluator:
    """Accumulates one sequence frame by frame."""

    def __init__(self) -> None:
        self.acc = mm.MOTAccumulator(auto_id=False)

    def update(self, frame: int, gt_ids: NDArray[np.int64], gt_boxes: FloatArray,
               hyp_ids: NDArray[np.int64], hyp_boxes: FloatArray,
               distractor_boxes: FloatArray | None = None) -> None:
        hyp_boxes = np.asarray(hyp_boxes, dtype=float).reshape(-1, 4)
        hyp_ids = np.asarray(hyp_ids).reshape(-1)
        if distractor_boxes is not None and len(distractor_boxes):
            keep = ~distractor_matches(hyp_boxes, distractor_boxes)
            hyp_ids, hyp_boxes = hyp_ids[keep], hyp_boxes[keep]
        gt_boxes = np.asarray(gt_boxes, dtype=float).reshape(-1, 4)
        self.acc.update([int(i) for i in gt_ids], [int(i) for i in hyp_ids],
                        iou_distance(gt_boxes, hyp_boxes), frameid=int(frame))


def _clean(value: Any) -> float | int | None:
    if isinstance(value, (np.integer, int)):
        return int(value)
    value = float(value)
    return None if math.isnan(value) else value


def summarize(accumulators: dict[str, MotEvaluator]) -> dict[str, dict[str, float | int | None]]:
    """Metrics per sequence and 'OVERALL' (all sequences together), JSON-ready."""
    mh = mm.metrics.create()
    names = list(accumulators)
    frame = mh.compute_many([accumulators[n].acc for n in names], names=names,
                            metrics=list(METRICS), generate_overall=len(names) > 1)
    out: dict[str, dict[str, float | int | None]] = {}
    for name, row in frame.iterrows():
        d = {k: _clean(row[k]) for k in METRICS}
        md = d.pop('motp')
        d['motp_distance'] = md
        d['motp'] = None if md is None else 100.0 * (1.0 - md)
        out['OVERALL' if name == 'OVERALL' else str(name)] = d
    if len(names) == 1:
        out['OVERALL'] = dict(out[names[0]])
    return out
