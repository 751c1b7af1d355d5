"""Foveated recognition on a folder of one's own labelled images (thesis section 2.4.2,
Figs. 2.7-2.10), with any `recognition.Classifier` (TorchScript + labels).

Folder format (the first that applies):

1. a CSV file (`labels.csv` in the folder, or any path given): one row per image,
   `file,label[,x0,y0,x1,y1]`; `file` relative to the folder; `label` one of the model's labels;
   the optional box (pixels of the image as stored, inclusive) is the object's ground truth for
   localisation. A first row whose label is `label` is a header.
2. sub-folders named by label: `<folder>/<label>/<image>`.
3. file names: `<label>.<ext>` or `<label>_<anything>.<ext>`, e.g. ImageNet's
   `n01484850_great_white_shark.JPEG` against labels `n01484850_great_white_shark` (the whole stem
   equals a label) or `n01484850_...` (the part before the first `_` equals a label's part
   before its first `_`, so a WordNet id matches).

Labels compare case-insensitively with spaces and `_` alike. Images: whatever OpenCV reads
(.jpg, .jpeg, .png, .bmp, .tif, .tiff, .webp, any case).

Evaluation (`evaluate_image`): the image is resized (squashed) to `size` x `size` px (the thesis
foveates its 227 x 227 network input: f0 is then in px of that square; `size` None keeps the
image's own size, f0 in its px), foveated with `Foveator` (K levels, sigma_1 = the pyramid's
sqrt(8/3)) at each f0 and fixation, and classified: pass 1 only (one batched forward per f0),
or Fig. 2.5's two passes (`recognition.two_pass`, top-k saliency boxes at th, pass 2 at each box
centre). Returned per image: the 0-based rank of the true class in pass 1's full ranking and in
pass 2's k final labels (k when absent), for every (f0, fixation). `localisation_hits`: whether any
of pass 1's top-k saliency boxes overlaps the true box with IoU >= 0.5 (ILSVRC's criterion), for
each threshold th.

ROS-free: numpy, OpenCV, torch (through the Classifier).
"""

from __future__ import annotations

import csv
import math
from collections import OrderedDict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .foveation import DEFAULT_LEVELS, Foveator
from .recognition import DEFAULT_THRESHOLD, DEFAULT_TOP_K, Box, Classifier, saliency_box, two_pass

IMAGE_SUFFIXES = ('.jpg', '.jpeg', '.png', '.bmp', '.tif', '.tiff', '.webp')
CSV_NAME = 'labels.csv'
THESIS_SIZE = 227                   # the thesis's CNN input, N x N (section 2.4.1)


class FolderError(ValueError):
    """A folder, CSV row or image that cannot be used (the message names the file and why)."""


@dataclass(frozen=True)
class LabelledImage:
    path: Path
    label: int                       # index into the model's labels
    box: Box | None = None           # ground-truth box in the stored image's pixels


def _key(label: str) -> str:
    return label.strip().lower().replace(' ', '_')


def _is_image(path: Path) -> bool:
    return path.is_file() and path.suffix.lower() in IMAGE_SUFFIXES


class _LabelIndex:
    """Label lookup: whole label, then the part before the first '_' (a WordNet id)."""

    def __init__(self, labels: Sequence[str]) -> None:
        self.full = {_key(lab): i for i, lab in enumerate(labels)}
        heads: dict[str, list[int]] = {}
        for i, lab in enumerate(labels):
            heads.setdefault(_key(lab).split('_')[0], []).append(i)
        self.head = {h: ids[0] for h, ids in heads.items() if len(ids) == 1}

    def exact(self, name: str) -> int | None:
        return self.full.get(_key(name))

    def from_stem(self, stem: str) -> int | None:
        key = _key(stem)
        if key in self.full:
            return self.full[key]
        head = key.split('_')[0]
        if head in self.full:
            return self.full[head]
        return self.head.get(head)


def load_folder(folder: str | Path, labels: Sequence[str],
                csv_path: str | Path | None = None) -> list[LabelledImage]:
    """The labelled images of folder (see the module docstring for the formats), sorted by
    path. Raises FolderError naming the file and the problem."""
    root = Path(folder)
    if not root.is_dir():
        raise FolderError(f'{root}: not a folder')
    index = _LabelIndex(labels)
    if csv_path is None and (root / CSV_NAME).is_file():
        csv_path = root / CSV_NAME
    if csv_path is not None:
        return _from_csv(root, Path(csv_path), index)
    subdirs = sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith('.'))
    items: list[LabelledImage] = []
    if subdirs and any(_is_image(f) for d in subdirs for f in d.iterdir()):
        for d in subdirs:
            files = sorted(f for f in d.iterdir() if _is_image(f))
            if not files:
                continue
            label = index.exact(d.name)
            if label is None:
                raise FolderError(f'{d}: folder name {d.name!r} is none of the model\'s '
                                  f'{len(labels)} labels')
            items += [LabelledImage(f, label) for f in files]
    else:
        for f in sorted(p for p in root.iterdir() if _is_image(p)):
            label = index.from_stem(f.stem)
            if label is None:
                raise FolderError(f'{f}: the name matches none of the model\'s {len(labels)} '
                                  f'labels (expected <label>[_anything]{f.suffix})')
            items.append(LabelledImage(f, label))
    if not items:
        raise FolderError(f'{root}: no images ({", ".join(IMAGE_SUFFIXES)}) found')
    return items


def _from_csv(root: Path, path: Path, index: _LabelIndex) -> list[LabelledImage]:
    try:
        rows = list(csv.reader(path.read_text(encoding='utf-8').splitlines()))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise FolderError(f'{path}: cannot read: {exc}') from exc
    items: list[LabelledImage] = []
    for n, row in enumerate(rows, 1):
        row = [c.strip() for c in row]
        if not row or not any(row) or row[0].startswith('#'):
            continue
        if n == 1 and len(row) >= 2 and _key(row[1]) == 'label':
            continue
        if len(row) not in (2, 6):
            raise FolderError(f'{path}:{n}: expected file,label[,x0,y0,x1,y1], got {len(row)} '
                              f'fields')
        file = root / row[0]
        if not file.is_file():
            raise FolderError(f'{path}:{n}: image {file} does not exist')
        label = index.exact(row[1])
        if label is None:
            label = index.from_stem(row[1])
        if label is None:
            raise FolderError(f'{path}:{n}: label {row[1]!r} is none of the model\'s labels')
        box = None
        if len(row) == 6:
            try:
                x0, y0, x1, y1 = (int(round(float(v))) for v in row[2:])
            except ValueError as exc:
                raise FolderError(f'{path}:{n}: box {row[2:]} is not 4 numbers') from exc
            if x1 < x0 or y1 < y0 or x0 < 0 or y0 < 0:
                raise FolderError(f'{path}:{n}: box {row[2:]} is not x0 <= x1, y0 <= y1, >= 0')
            box = (x0, y0, x1, y1)
        items.append(LabelledImage(file, label, box))
    if not items:
        raise FolderError(f'{path}: no rows')
    return items


def read_rgb(path: str | Path) -> np.ndarray:
    """An image file as RGB uint8 (H, W, 3); FolderError if OpenCV cannot decode it."""
    data = np.fromfile(str(path), np.uint8) if Path(path).is_file() else None
    img = cv2.imdecode(data, cv2.IMREAD_COLOR) if data is not None and data.size else None
    if img is None:
        raise FolderError(f'{path}: not an image OpenCV can read')
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def fit(rgb: np.ndarray, size: int | None, box: Box | None = None
        ) -> tuple[np.ndarray, Box | None]:
    """The image squashed to size x size (None: unchanged) and its box in the new pixels."""
    if size is None:
        return rgb, box
    h, w = rgb.shape[:2]
    out = cv2.resize(rgb, (size, size), interpolation=cv2.INTER_AREA
                     if (w >= size and h >= size) else cv2.INTER_LINEAR)
    if box is not None:
        sx, sy = size / w, size / h
        box = (int(box[0] * sx), int(box[1] * sy),
               min(size - 1, int(math.ceil((box[2] + 1) * sx)) - 1),
               min(size - 1, int(math.ceil((box[3] + 1) * sy)) - 1))
    return out, box


def grid_fixations(width: int, height: int, n: int) -> list[tuple[float, float]]:
    """n x n fixations at the centres of an n x n partition of the image, row by row; for odd n
    the middle one is the image centre ((W - 1) / 2, (H - 1) / 2)."""
    us = (np.arange(n) + 0.5) * width / n - 0.5
    vs = (np.arange(n) + 0.5) * height / n - 0.5
    return [(float(u), float(v)) for v in vs for u in us]


def iou(a: Box, b: Box) -> float:
    """Intersection over union of two inclusive pixel boxes."""
    ix = max(0, min(a[2], b[2]) - max(a[0], b[0]) + 1)
    iy = max(0, min(a[3], b[3]) - max(a[1], b[1]) + 1)
    inter = ix * iy
    area_a = (a[2] - a[0] + 1) * (a[3] - a[1] + 1)
    area_b = (b[2] - b[0] + 1) * (b[3] - b[1] + 1)
    return inter / float(area_a + area_b - inter)


def true_rank(probs: np.ndarray, truth: int) -> np.ndarray:
    """0-based rank of class truth in each row of probs (N, C): the number of classes scored
    strictly higher (ties count in its favour)."""
    probs = np.atleast_2d(probs)
    return (probs > probs[:, truth:truth + 1]).sum(axis=1)


class Foveators:
    """One Foveator per (width, height, f0), built on first use; the `keep` most recently used
    are kept (a Foveator holds a few MB of buffers: photographs of many sizes would pile up)."""

    def __init__(self, levels: int = DEFAULT_LEVELS, keep: int = 16) -> None:
        self.levels = levels
        self.keep = keep
        self._cache: OrderedDict[tuple[int, int, float], Foveator] = OrderedDict()

    def get(self, width: int, height: int, f0: float) -> Foveator:
        key = (width, height, float(f0))
        if key in self._cache:
            self._cache.move_to_end(key)
        else:
            self._cache[key] = Foveator(width, height, self.levels, float(f0))
            while len(self._cache) > self.keep:
                self._cache.popitem(last=False)
        return self._cache[key]


@dataclass
class ImageRanks:
    """ranks[s, j, p]: 0-based rank of the true class for setting s (f0s, then unfoveated),
    fixation j, pass p (0: pass 1's full ranking; 1: pass 2's k final labels, k if absent, -1
    if pass 2 was not run). Fixations are in the evaluated (fitted) image's pixels."""

    ranks: np.ndarray
    fixations: list[tuple[float, float]]
    predicted: list[int]              # unfoveated pass-1 top-5 class ids


def evaluate_image(clf: Classifier, rgb: np.ndarray, truth: int,
                   f0s: Sequence[float], grid: int = 1, passes: int = 1,
                   fovs: Foveators | None = None, top_k: int = DEFAULT_TOP_K,
                   threshold: float = DEFAULT_THRESHOLD,
                   fixations: Sequence[tuple[float, float]] | None = None) -> ImageRanks:
    """Ranks of the true class on one (already fitted) RGB uint8 image, for each f0 of f0s plus
    the unfoveated image (the last setting), at the grid x grid fixations (or the given ones),
    after pass 1 and (passes == 2) after pass 2 (Fig. 2.5)."""
    if passes not in (1, 2):
        raise ValueError(f'passes must be 1 or 2, got {passes}')
    fovs = fovs or Foveators()
    h, w = rgb.shape[:2]
    fix = list(fixations) if fixations is not None else grid_fixations(w, h, grid)
    ranks = np.full((len(f0s) + 1, len(fix), 2), -1, np.int64)
    base = clf.classify(rgb)[0]
    ranks[-1, :, 0] = true_rank(base, truth)[0]
    if passes == 2:
        # unfoveated, pass 2 classifies k copies of the same image, so its k final labels are
        # pass 1's top-k in order (merge_second_pass of identical rows): no need to run it
        k = min(top_k, clf.num_classes)
        ranks[-1, :, 1] = min(int(ranks[-1, 0, 0]), k)
    for s, f0 in enumerate(f0s):
        fov = fovs.get(w, h, f0)
        if passes == 1:
            probs = clf.classify([fov.foveate(rgb, f) for f in fix])
            ranks[s, :, 0] = true_rank(probs, truth)
            continue
        for j, f in enumerate(fix):
            res = two_pass(clf, rgb, f, fov.foveate, top_k, threshold, localise_second=False)
            ranks[s, j, 0] = true_rank(res.probs_first, truth)[0]
            ranks[s, j, 1] = _final_rank(res.second, truth, top_k)
    return ImageRanks(ranks, fix, [int(c) for c in np.argsort(-base)[:5]])


def _final_rank(second: Sequence, truth: int, top_k: int) -> int:
    ids = [d.class_id for d in second]
    return ids.index(truth) if truth in ids else max(top_k, len(ids))


def localisation_hits(clf: Classifier, rgb: np.ndarray, box: Box, f0: float | None,
                      fixation: tuple[float, float], thresholds: Iterable[float],
                      fovs: Foveators | None = None, top_k: int = DEFAULT_TOP_K) -> np.ndarray:
    """For each threshold th: does any of pass 1's top-k saliency boxes (at th) overlap the
    true box with IoU >= 0.5? f0 None: the unfoveated image. One forward, one batched
    backward."""
    h, w = rgb.shape[:2]
    img = rgb if f0 is None else (fovs or Foveators()).get(w, h, f0).foveate(rgb, fixation)
    probs = clf.classify(img)[0]
    top = [int(c) for c in np.argsort(-probs)[:min(top_k, clf.num_classes)]]
    maps = clf.saliency(img, top)
    return np.array([any(iou(clf.box_to_image(saliency_box(m, th), w, h), box) >= 0.5
                         for m in maps) for th in thresholds], bool)


def paste(rgb: np.ndarray, size: int, scale: float, rng: np.random.Generator,
          background: np.ndarray | int = 128) -> tuple[np.ndarray, Box]:
    """The image squashed to a (scale * size)-px square and put at a random place on a
    size x size canvas: `background` squashed to fill it (another photograph: a collage), or a
    grey level. A scene whose object box is known (the pasted photograph's extent), for
    localisation when the photographs carry no boxes."""
    side = int(round(scale * size))
    if not 8 <= side <= size:
        raise ValueError(f'scale {scale} gives a {side}-px photo on a {size}-px canvas')
    small, _ = fit(rgb, side)
    x0 = int(rng.integers(0, size - side + 1))
    y0 = int(rng.integers(0, size - side + 1))
    if isinstance(background, np.ndarray):
        canvas = fit(background, size)[0].copy()
    else:
        canvas = np.full((size, size, 3), int(background), np.uint8)
    canvas[y0:y0 + side, x0:x0 + side] = small
    return canvas, (x0, y0, x0 + side - 1, y0 + side - 1)


def top_errors(ranks: np.ndarray, ks: Sequence[int] = (1, 5)) -> dict[str, float | None]:
    """{'top1_error': ..., 'top5_error': ...} over an array of ranks (-1 entries: not run)."""
    valid = ranks[ranks >= 0]
    return {f'top{k}_error': (float((valid >= k).mean()) if valid.size else None) for k in ks}


__all__ = ['CSV_NAME', 'FolderError', 'Foveators', 'IMAGE_SUFFIXES', 'ImageRanks',
           'LabelledImage', 'THESIS_SIZE', 'evaluate_image', 'fit', 'grid_fixations', 'iou',
           'load_folder', 'localisation_hits', 'paste', 'read_rgb', 'top_errors', 'true_rank']
