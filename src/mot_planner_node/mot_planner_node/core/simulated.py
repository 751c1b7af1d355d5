"""Synthetic pedestrians and a simulated sliding-window detector, for tests and benchmarks.

:class:`SyntheticScene` walks people (object boxes with a person's aspect ratio) across a
ground plane seen by a static camera: a person's image height grows linearly with how low
their feet are (perspective; the lowest feet stay high enough for the detector window,
which reaches below them, to fit in the image), they walk at constant velocity with a little random
acceleration, and turn back at the image borders, so everyone stays in view.

:class:`SimulatedDetector` implements the :class:`~.detector.Detector` interface with the
error model of section 5.3.2 made literal: a person is found in a region when their window,
at the nearest scale of the detector's ladder (Eq. 5.9), fits inside the region's rectangle
and its scale lies in the region's range (one ladder step of slack); the reported window is
snapped to that scale and to the sliding-window grid of the region (Eq. 5.8), plus a small
Gaussian jitter. Each person is found with probability ``p_detect`` if at least
``min_visible`` of their box is not hidden behind nearer people; false positives arrive as a
Poisson process over the processed area. It never looks at pixels.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from .detector import HOG_SHRINK, BoxShrink, Detections, box_intersection, check_image
from .observation import DetectorGeometry
from .regions import S_HI, S_LO, X0, X1, Y0, Y1

if TYPE_CHECKING:
    from .detector import Detector
    from .tracker import TrackerConfig

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass
class SyntheticFrame:
    """Ground truth of one frame: ids (n,), object boxes (n, 4) x, y, w, h."""

    ids: IntArray
    boxes: FloatArray


class SyntheticScene:
    """People walking in front of a static camera (see the module docstring)."""

    def __init__(self, n_people: int = 8, image_size: tuple[int, int] = (640, 480),
                 horizon: float = 0.25, max_height: float = 170.0, aspect: float = 0.41,
                 speed: float = 1.0, accel_std: float = 0.05, min_height: float = 100.0,
                 seed: int = 0) -> None:
        self.image_size = image_size
        self.aspect = aspect
        width, height = image_size
        self.rng = np.random.default_rng(seed)
        self.horizon_y = horizon * height
        self.foot_max = height - 0.25 * max_height
        # Person height per pixel of feet below the horizon.
        self.k = max_height / (self.foot_max - self.horizon_y)
        self.foot_min = self.horizon_y + min_height / self.k
        n = n_people
        self.ids = np.arange(1, n + 1, dtype=np.int64)
        self.foot = np.stack([self.rng.uniform(0.1 * width, 0.9 * width, n),
                              self.rng.uniform(self.foot_min, self.foot_max, n)], axis=1)
        ang = self.rng.uniform(-np.pi, np.pi, n)
        self.vel = np.stack([np.cos(ang), 0.3 * np.sin(ang)], axis=1) * speed
        self.accel_std = accel_std

    def boxes(self) -> FloatArray:
        """Object boxes (n, 4) of the people now."""
        h = self.k * (self.foot[:, 1] - self.horizon_y)
        w = self.aspect * h
        return np.stack([self.foot[:, 0] - w / 2, self.foot[:, 1] - h, w, h], axis=1)

    def advance(self) -> None:
        """One frame of motion: velocity scaled with apparent size, bounce at the borders."""
        width, _ = self.image_size
        scale = (self.foot[:, 1] - self.horizon_y) / (self.foot_max - self.horizon_y)
        self.vel += self.rng.normal(0.0, self.accel_std, self.vel.shape)
        self.foot += self.vel * scale[:, None]
        w = self.aspect * self.k * (self.foot[:, 1] - self.horizon_y)
        lo_x, hi_x = w / 2, width - w / 2
        flip_x = (self.foot[:, 0] < lo_x) | (self.foot[:, 0] > hi_x)
        self.vel[flip_x, 0] *= -1
        self.foot[:, 0] = np.clip(self.foot[:, 0], lo_x, hi_x)
        flip_y = (self.foot[:, 1] < self.foot_min) | (self.foot[:, 1] > self.foot_max)
        self.vel[flip_y, 1] *= -1
        self.foot[:, 1] = np.clip(self.foot[:, 1], self.foot_min, self.foot_max)

    def frames(self, n_frames: int) -> list[SyntheticFrame]:
        """Ground truth of n_frames consecutive frames (advances the scene)."""
        out = []
        for _ in range(n_frames):
            out.append(SyntheticFrame(self.ids.copy(), self.boxes()))
            self.advance()
        return out


def render(frame: SyntheticFrame, image_size: tuple[int, int], seed: int = 0) -> NDArray[np.uint8]:
    """A textured BGR image with a dark blob per person (for timing an image detector; a
    real person detector is not expected to fire on it)."""
    width, height = image_size
    rng = np.random.default_rng(seed)
    tex = rng.integers(0, 256, (height // 8 + 1, width // 8 + 1, 3), dtype=np.uint8)
    img = cast(NDArray[np.uint8],     # uint8 in, uint8 out
               cv2.resize(tex, (width, height), interpolation=cv2.INTER_LINEAR))
    order = np.argsort(frame.boxes[:, 1] + frame.boxes[:, 3])
    for x, y, w, h in frame.boxes[order]:
        cv2.ellipse(img, (int(x + w / 2), int(y + h / 2)), (int(w / 2), int(h / 2)), 0, 0, 360,
                    (40, 40, 60), -1)
    return img


def visibility(boxes: FloatArray) -> FloatArray:
    """Fraction of each box not covered by boxes whose bottom is lower (nearer), (n,).
    Overlaps of occluders are not subtracted twice-over exactly: coverage is capped at 1."""
    n = boxes.shape[0]
    if n == 0:
        return np.zeros(0)
    y1 = boxes[:, 1] + boxes[:, 3]
    nearer = y1[None, :] > y1[:, None]
    covered = np.where(nearer, box_intersection(boxes, boxes), 0.0).sum(axis=1)
    return 1.0 - np.minimum(covered / np.maximum(boxes[:, 2] * boxes[:, 3], 1e-9), 1.0)


class SimulatedDetector:
    """A sliding-window detector simulated from ground truth (module docstring).

    Call :meth:`set_truth` with the current frame's object boxes before each ``detect``.
    """

    def __init__(self, geometry: DetectorGeometry | None = None,
                 box_shrink: BoxShrink = HOG_SHRINK, p_detect: float = 0.95,
                 jitter: float = 0.02, false_positives_per_frame: float = 0.5,
                 min_visible: float = 0.5, seed: int = 0) -> None:
        self.geometry = geometry or DetectorGeometry()
        self.box_shrink = box_shrink
        self.p_detect = p_detect
        self.jitter = jitter
        self.fp_rate = false_positives_per_frame
        self.min_visible = min_visible
        self.rng = np.random.default_rng(seed)
        self._truth = np.zeros((0, 4))
        self.calls = 0
        self.processed_area = 0.0

    def set_truth(self, object_boxes: FloatArray) -> None:
        self._truth = np.asarray(object_boxes, dtype=float).reshape(-1, 4)

    def detect(self, image: NDArray[np.uint8], regions: FloatArray | None = None) -> Detections:
        image = check_image(image)
        height, width = image.shape[:2]
        g = self.geometry
        if regions is None:
            regions = np.array([[0.0, 0.0, width, height, g.min_scale, np.inf]])
        regions = np.asarray(regions, dtype=float).reshape(-1, 6).copy()
        regions[:, [X0, X1]] = np.clip(regions[:, [X0, X1]], 0, width)
        regions[:, [Y0, Y1]] = np.clip(regions[:, [Y0, Y1]], 0, height)
        self.calls += 1
        win = self.box_shrink.invert(self._truth)                        # (n, 4) windows
        n, m = win.shape[0], regions.shape[0]
        boxes, scores = [np.zeros((0, 4))], [np.zeros(0)]
        step = g.scale_step
        if n:
            cx, cy = win[:, 0] + win[:, 2] / 2, win[:, 1] + win[:, 3] / 2
            s_true = win[:, 3] / g.window_h
            level = np.round(np.log(np.maximum(s_true, 1e-9)) / np.log(step))
            s_q = step ** level                                          # Eq. 5.9
            ww, wh = s_q * g.window_w, s_q * g.window_h
            q = s_q * g.stride                                           # Eq. 5.8
            # Per (person, region): window snapped to the region's grid, must fit inside it.
            ox, oy = regions[None, :, X0], regions[None, :, Y0]
            left = ox + np.round((cx[:, None] - ww[:, None] / 2 - ox) / q[:, None]) * q[:, None]
            top = oy + np.round((cy[:, None] - wh[:, None] / 2 - oy) / q[:, None]) * q[:, None]
            fits = ((left >= regions[None, :, X0] - 1e-6)
                    & (left + ww[:, None] <= regions[None, :, X1] + 1e-6)
                    & (top >= regions[None, :, Y0] - 1e-6)
                    & (top + wh[:, None] <= regions[None, :, Y1] + 1e-6)
                    & (s_q[:, None]
                       >= np.maximum(regions[None, :, S_LO], g.min_scale) / step - 1e-9)
                    & (s_q[:, None] <= regions[None, :, S_HI] * step + 1e-9))
            found_in = fits.any(axis=1)
            first = np.argmax(fits, axis=1)
            visible = visibility(self._truth) >= self.min_visible
            hit = found_in & visible & (self.rng.random(n) < self.p_detect) & (s_q >= g.min_scale)
            idx = np.flatnonzero(hit)
            jit = self.rng.normal(0.0, self.jitter, (idx.size, 3))
            bw, bh = ww[idx] * (1 + jit[:, 2]), wh[idx] * (1 + jit[:, 2])
            bx = left[idx, first[idx]] + ww[idx] / 2 + jit[:, 0] * ww[idx] - bw / 2
            by = top[idx, first[idx]] + wh[idx] / 2 + jit[:, 1] * wh[idx] - bh / 2
            boxes.append(np.stack([bx, by, bw, bh], axis=1))
            scores.append(self.rng.uniform(0.5, 1.5, idx.size))
        area = float(((regions[:, X1] - regions[:, X0]) * (regions[:, Y1] - regions[:, Y0])).sum())
        self.processed_area += area
        n_fp = self.rng.poisson(self.fp_rate * area / (width * height))
        if n_fp:
            r = regions[self.rng.integers(0, m, n_fp)]
            s = g.min_scale * step ** self.rng.integers(0, 10, n_fp)
            w, h = s * g.window_w, s * g.window_h
            x = r[:, X0] + self.rng.random(n_fp) * np.maximum(r[:, X1] - r[:, X0] - w, 0)
            y = r[:, Y0] + self.rng.random(n_fp) * np.maximum(r[:, Y1] - r[:, Y0] - h, 0)
            ok = (w <= r[:, X1] - r[:, X0]) & (h <= r[:, Y1] - r[:, Y0])
            boxes.append(np.stack([x, y, w, h], axis=1)[ok])
            scores.append(self.rng.uniform(0.0, 1.0, n_fp)[ok])
        return Detections(np.concatenate(boxes), np.concatenate(scores))


@dataclass
class SyntheticRun:
    """A tracker run on a synthetic scene with the simulated detector.

    metrics: py-motmetrics summary (:func:`.metrics.summarize`, one sequence).
    regions: per frame, the regions the detector processed ((m, 6); full image on full frames).
    plan_s, step_s: per frame, planning time and tracker step time without the detector.
    frames: the ground truth, for rendering.
    """

    metrics: dict[str, float | int | None]
    regions: list[FloatArray]
    plan_s: list[float]
    step_s: list[float]
    frames: list[SyntheticFrame]


def track_synthetic(cfg: TrackerConfig, n_people: int = 8, n_frames: int = 200,
                    seed: int = 0, image_size: tuple[int, int] = (640, 480),
                    **scene_kwargs: float) -> SyntheticRun:
    """Run a tracker configuration on a :class:`SyntheticScene` with the
    :class:`SimulatedDetector` and score it against the scene's ground truth."""
    from .metrics import MotEvaluator, summarize
    from .tracker import MotTracker

    scene = SyntheticScene(n_people=n_people, image_size=image_size, seed=seed, **scene_kwargs)
    frames = scene.frames(n_frames)
    detector = SimulatedDetector(seed=seed)
    tracker = MotTracker(detector, cfg)
    blank = np.zeros((image_size[1], image_size[0], 3), np.uint8)
    evaluator = MotEvaluator()
    regions, plan_s, step_s = [], [], []
    for i, frame in enumerate(frames):
        detector.set_truth(frame.boxes)
        result = tracker.step(blank)
        regions.append(result.regions)
        plan_s.append(result.plan_s)
        step_s.append(result.total_s - result.detector_s)
        evaluator.update(i + 1, frame.ids, frame.boxes, result.ids, result.boxes)
    metrics = summarize({'synthetic': evaluator})['synthetic']
    return SyntheticRun(metrics, regions, plan_s, step_s, frames)


def replay_detector_time(detector: Detector, images: list[NDArray[np.uint8]],
                         regions: list[FloatArray | None]) -> list[float]:
    """Wall time (s) of ``detector.detect(image, regions)`` per frame: what a real image
    detector costs on the regions another run chose (None or a full-image row: full frame)."""
    out = []
    for image, reg in zip(images, regions, strict=True):
        if reg is not None and len(reg) == 1 and not np.isfinite(reg[0, S_HI]) \
                and reg[0, X0] == 0 and reg[0, Y0] == 0 \
                and reg[0, X1] >= image.shape[1] and reg[0, Y1] >= image.shape[0]:
            reg = None
        t0 = time.perf_counter()
        if reg is None or len(reg):
            detector.detect(image, reg)
        out.append(time.perf_counter() - t0)
    return out
