"""Detector plug-in: one small interface, applied only inside the chosen regions.

A detector is any object with

- ``geometry``: a :class:`DetectorGeometry` (smallest window, stride, scale step) from which
  the observation model (Eqs. 5.8-5.15) is built;
- ``box_shrink``: a :class:`BoxShrink` turning its window boxes into object boxes;
- ``detect(image, regions=None) -> Detections``: window boxes (x, y, w, h in image pixels)
  and scores; ``regions`` is None for the whole frame, else an (m, 6) array of
  ``[x0, y0, x1, y1, s_lo, s_hi]`` rows (see :mod:`.regions`): scan only those rectangles,
  at scales from s_lo (a detector may ignore the scale range). Boxes come back in full-image
  coordinates, duplicates across overlapping regions removed.

The default is OpenCV's HOG people detector (Dalal-Triggs, 64x128 window, 8-pixel stride,
scale step 1.05): a sliding-window detector like the thesis's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Protocol, cast, runtime_checkable

import cv2
import numpy as np
from numpy.typing import NDArray

from .observation import DetectorGeometry
from .regions import S_LO, X0, X1, Y0, Y1, read_scale

FloatArray = NDArray[np.float64]


class Detections(NamedTuple):
    """boxes (n, 4) float x, y, w, h of detector windows in image pixels; scores (n,)."""

    boxes: FloatArray
    scores: FloatArray

    @staticmethod
    def empty() -> Detections:
        return Detections(np.zeros((0, 4)), np.zeros(0))


@dataclass(frozen=True)
class BoxShrink:
    """Window box -> object box: same centre x, centre y moved by ``dy * h``, size scaled.

    A person detector's window holds a margin around the person (the INRIA training windows
    of HOG's default model put a 96-pixel person in a 128-pixel window), so scoring windows
    against tight ground-truth boxes would understate the overlap. See docs/mot_planner.md
    for how the HOG values were derived.
    """

    width: float = 1.0
    height: float = 1.0
    dy: float = 0.0

    def apply(self, boxes: FloatArray) -> FloatArray:
        """Object boxes (n, 4) x, y, w, h from window boxes (n, 4)."""
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        cx = boxes[:, 0] + boxes[:, 2] / 2.0
        cy = boxes[:, 1] + boxes[:, 3] / 2.0 + self.dy * boxes[:, 3]
        w, h = boxes[:, 2] * self.width, boxes[:, 3] * self.height
        return np.stack([cx - w / 2.0, cy - h / 2.0, w, h], axis=1)

    def invert(self, boxes: FloatArray) -> FloatArray:
        """Window boxes (n, 4) from object boxes (n, 4)."""
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        w, h = boxes[:, 2] / self.width, boxes[:, 3] / self.height
        cx = boxes[:, 0] + boxes[:, 2] / 2.0
        cy = boxes[:, 1] + boxes[:, 3] / 2.0 - self.dy * h
        return np.stack([cx - w / 2.0, cy - h / 2.0, w, h], axis=1)


#: HOG's default people model: the INRIA windows put a 96 px person in 128 px (height 0.75);
#: fitted on MOT17-mini (90 HOG detections matched to ground truth, docs/mot_planner.md,
#: "Box shrink"): height 0.76 (IQR 0.71-0.81), width 0.535 (IQR 0.49-0.61), centre offset 0.
HOG_SHRINK = BoxShrink(width=0.535, height=0.76, dy=0.0)


@runtime_checkable
class Detector(Protocol):
    """What the tracker needs from a detector (see the module docstring)."""

    geometry: DetectorGeometry
    box_shrink: BoxShrink

    def detect(self, image: NDArray[np.uint8], regions: FloatArray | None = None) -> Detections:
        ...


def box_intersection(a: FloatArray, b: FloatArray) -> FloatArray:
    """Intersection areas (n, m) of x, y, w, h boxes a (n, 4) and b (m, 4)."""
    a = np.asarray(a, dtype=float).reshape(-1, 4)
    b = np.asarray(b, dtype=float).reshape(-1, 4)
    ax1, ay1 = a[:, 0] + a[:, 2], a[:, 1] + a[:, 3]
    bx1, by1 = b[:, 0] + b[:, 2], b[:, 1] + b[:, 3]
    iw = np.clip(np.minimum(ax1[:, None], bx1[None]) - np.maximum(a[:, None, 0], b[None, :, 0]),
                 0, None)
    ih = np.clip(np.minimum(ay1[:, None], by1[None]) - np.maximum(a[:, None, 1], b[None, :, 1]),
                 0, None)
    return iw * ih


def box_iou(a: FloatArray, b: FloatArray) -> FloatArray:
    """IoU matrix (n, m) of x, y, w, h boxes."""
    a = np.asarray(a, dtype=float).reshape(-1, 4)
    b = np.asarray(b, dtype=float).reshape(-1, 4)
    inter = box_intersection(a, b)
    union = (a[:, 2] * a[:, 3])[:, None] + (b[:, 2] * b[:, 3])[None] - inter
    return np.where(union > 0, inter / np.maximum(union, 1e-12), 0.0)


def nms(boxes: FloatArray, scores: FloatArray, iou_threshold: float = 0.5) -> NDArray[np.int64]:
    """Indices kept by greedy non-maximum suppression, best score first."""
    order = np.argsort(-np.asarray(scores), kind='stable')
    if order.size <= 1:
        return order
    iou = box_iou(boxes, boxes)
    keep: list[int] = []
    suppressed = np.zeros(order.size, dtype=bool)
    for i in order:                                  # loop over detections, not pixels
        if suppressed[i]:
            continue
        keep.append(int(i))
        suppressed |= iou[i] > iou_threshold
    return np.array(keep, dtype=np.int64)


def check_image(image: object) -> NDArray[np.uint8]:
    """The image as an (H, W) or (H, W, 3) uint8 array, or ValueError saying what is wrong."""
    if not isinstance(image, np.ndarray):
        raise ValueError(f'image must be a numpy array, got {type(image).__name__}')
    if image.dtype != np.uint8:
        raise ValueError(f'image must be uint8, got {image.dtype}')
    if image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] not in (1, 3)):
        raise ValueError(f'image must be HxW or HxWx3, got shape {image.shape}')
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f'image is empty (shape {image.shape})')
    return image


class HogDetector:
    """OpenCV's HOG + linear SVM people detector behind the :class:`Detector` interface.

    The observation model's constants come from the descriptor itself: window
    ``winSize`` (64x128), stride ``win_stride`` (a multiple of the block stride) and the
    pyramid's ``scale`` step. In a region the crop is shrunk by 1/s_lo first, so the scan
    starts at the region's smallest plausible scale instead of the detector's smallest, and
    is scanned without HOG's border padding (the crop already extends half a window beyond
    the centres it must cover; full frames keep ``padding``).

    ``region_hit_threshold`` (None: ``hit_threshold``) is the SVM threshold inside the regions
    only: a region is where a tracked person is predicted to be, so a weaker window there is
    more likely that person than on a full frame (ByteTrack's use of low-score detections);
    the tracker births only from detections above its own ``birth_score``.

    ``upsample`` (>= 1): a region's crop is read at ``upsample`` times its smallest scale and
    enlarged back before the scan, so the detector reads ``upsample**2`` fewer pixels there;
    full frames are read whole.

    ``full_frame_scale`` (None: ``scale``): the pyramid's scale step on whole frames only (the
    births' scans, most of the detector's time; regions keep ``scale``, which the observation
    model is built from). A step of 1.1 scans 14 pyramid levels of a 640x480 frame instead of
    27, about half the time.
    """

    def __init__(self, win_stride: int = 8, scale: float = 1.05, hit_threshold: float = 0.0,
                 region_hit_threshold: float | None = None, upsample: float = 1.0,
                 score_threshold: float = 0.0, group_threshold: int = 2,
                 padding: int = 8, box_shrink: BoxShrink = HOG_SHRINK,
                 svm: NDArray[np.float32] | None = None,
                 full_frame_scale: float | None = None) -> None:
        self.hog = cv2.HOGDescriptor()
        self.hog.setSVMDetector(np.asarray(cv2.HOGDescriptor.getDefaultPeopleDetector()
                                           if svm is None else svm, dtype=np.float32))
        block_stride = self.hog.blockStride[0]
        if win_stride <= 0 or win_stride % block_stride:
            raise ValueError(f'win_stride must be a positive multiple of the block stride '
                             f'{block_stride}, got {win_stride}')
        for name, step in (('scale', scale), ('full_frame_scale', full_frame_scale)):
            if step is not None and not step > 1.0:
                raise ValueError(f'{name} must be > 1, got {step}')
        self.win_stride = int(win_stride)
        self.scale = float(scale)
        self.full_frame_scale = self.scale if full_frame_scale is None else float(full_frame_scale)
        self.hit_threshold = float(hit_threshold)
        self.region_hit_threshold = (self.hit_threshold if region_hit_threshold is None
                                     else float(region_hit_threshold))
        self.score_threshold = float(score_threshold)
        self.group_threshold = int(group_threshold)
        self.padding = int(padding)
        self.box_shrink = box_shrink
        w, h = self.hog.winSize
        self.geometry = DetectorGeometry(window_w=float(w), window_h=float(h),
                                         stride=float(win_stride), scale_step=self.scale,
                                         min_scale=1.0, upsample=float(upsample))

    def _run(self, image: NDArray[np.uint8], padding: int | None = None,
             hit_threshold: float | None = None, scale: float | None = None) -> Detections:
        w, h = self.hog.winSize
        if image.shape[0] < h or image.shape[1] < w:
            return Detections.empty()
        pad = self.padding if padding is None else padding
        hit = self.hit_threshold if hit_threshold is None else hit_threshold
        rects, weights = self.hog.detectMultiScale(
            image, hitThreshold=hit, winStride=(self.win_stride,) * 2,
            padding=(pad, pad), scale=self.scale if scale is None else scale,
            groupThreshold=self.group_threshold)
        if len(rects) == 0:
            return Detections.empty()
        boxes = np.asarray(rects, dtype=float).reshape(-1, 4)
        scores = np.asarray(weights, dtype=float).reshape(-1)
        keep = scores >= self.score_threshold
        return Detections(boxes[keep], scores[keep])

    def detect(self, image: NDArray[np.uint8], regions: FloatArray | None = None) -> Detections:
        image = check_image(image)
        if regions is None:
            return self._run(image, scale=self.full_frame_scale)
        regions = np.asarray(regions, dtype=float).reshape(-1, 6)
        height, width = image.shape[:2]
        all_boxes, all_scores = [], []
        for reg in regions:                              # a few regions per frame
            x0, y0 = int(max(np.floor(reg[X0]), 0)), int(max(np.floor(reg[Y0]), 0))
            x1, y1 = int(min(np.ceil(reg[X1]), width)), int(min(np.ceil(reg[Y1]), height))
            if x1 <= x0 or y1 <= y0:
                continue
            crop = image[y0:y1, x0:x1]
            s_lo = max(float(reg[S_LO]) if np.isfinite(reg[S_LO]) else 1.0, 1.0)
            s_read = float(read_scale(reg, self.geometry.upsample))
            if s_read > s_lo:                            # read coarser, then enlarge
                small = (max(int(round((x1 - x0) / s_read)), 1),
                         max(int(round((y1 - y0) / s_read)), 1))
                crop = cast(NDArray[np.uint8],
                            cv2.resize(crop, small, interpolation=cv2.INTER_AREA))
            if s_lo > 1.0 or s_read > s_lo:
                size = (max(int(round((x1 - x0) / s_lo)), 1), max(int(round((y1 - y0) / s_lo)), 1))
                crop = cast(NDArray[np.uint8],   # uint8 in, uint8 out
                            cv2.resize(crop, size, interpolation=cv2.INTER_AREA
                                       if s_read <= s_lo else cv2.INTER_LINEAR))
                f = (x1 - x0) / size[0], (y1 - y0) / size[1]
            else:
                f = 1.0, 1.0
            det = self._run(np.ascontiguousarray(crop), padding=0,   # crops carry their margin
                            hit_threshold=self.region_hit_threshold)
            if len(det.scores):
                b = det.boxes.copy()
                b[:, [0, 2]] *= f[0]
                b[:, [1, 3]] *= f[1]
                b[:, 0] += x0
                b[:, 1] += y0
                all_boxes.append(b)
                all_scores.append(det.scores)
        if not all_boxes:
            return Detections.empty()
        boxes, scores = np.concatenate(all_boxes), np.concatenate(all_scores)
        keep = nms(boxes, scores, 0.5)
        return Detections(boxes[keep], scores[keep])
