"""Foveated CNN recognition with gradient saliency and two-pass saccades (thesis section 2.3.2,
Fig. 2.5).

- `Classifier`: any TorchScript image classifier plus a labels file (one label per line) and
  an optional preprocessing JSON next to the model (`<model>.json`: input size, mean, std);
  without it, ImageNet's 227x227 and mean/std. Images of any size are resized (squashed) to the
  network input.
- `Classifier.saliency`: the class saliency map of Eqs. 2.19-2.20, |d S_c / d I| (S_c the
  class score before the softmax) with the maximum magnitude over the colour channels,
  normalised to [0, 1]; `saliency_box`: the bounding box of the pixels above th (section
  2.3.2, "Bounding Box Object Localization"), mapped back to the image's pixels.
- `two_pass`: Fig. 2.5. Pass 1 classifies the image foveated at the initial fixation and
  localises its top-k classes; the fovea moves to each box centre and pass 2 re-classifies
  the k re-foveated images (one batched forward pass); the k x k labels are sorted by score
  and the best non-repeated ones are the result.
- Reject class: a model whose labels include BACKGROUND_LABEL ('background', "no object at the
  fixation") has it as `Classifier.reject_class`. It is never a detection, never localised and
  never a saccade target: pass 1 localises the top-k object classes (background left out: they
  are the candidates pass 2 looks at, even when the initial fixation is on background), and a
  pass-2 label counts only where its probability exceeds background's on the image it was seen
  in (a row whose best class is background gives nothing), so pass 2 may return no detection.
  A model without the label behaves as before. Pass 1 reports only the classes that beat
  background at its fixation (it still localises the top-k for pass 2 to look at).
- Window models: a preprocessing JSON with `"window": W` (px) makes the network see the W x W
  square of the (foveated) image centred at each pass's fixation (reflect-padded at the image's
  border), resized to its input, instead of the whole image: the classifier looks at what the
  fovea holds, at the fovea's resolution (a 6 cm can at 0.8 m is 29 px wide: shrunk with a
  640 x 480 frame to 227 px it would be 10). Saliency boxes map back from that square.
  `grid_recognition` is the uniform-resolution counterpart: every window of a grid over the
  whole unfoveated frame.

ROS-free: numpy, OpenCV and torch only.
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import cv2
import numpy as np
import torch

DEFAULT_INPUT_SIZE = (227, 227)                      # (width, height), as the thesis's CNNs
IMAGENET_MEAN = (0.485, 0.456, 0.406)                # RGB, of pixels scaled to [0, 1]
IMAGENET_STD = (0.229, 0.224, 0.225)
DEFAULT_THRESHOLD = 0.7                              # th of the segmentation mask (Fig. 2.9)
DEFAULT_TOP_K = 5
BACKGROUND_LABEL = 'background'                      # the reject class: no object at the fixation

Box = tuple[int, int, int, int]                      # (x0, y0, x1, y1), inclusive, image px
Foveate = Callable[[np.ndarray, tuple[float, float]], np.ndarray]
Region = tuple[int, int, int, int]                   # (x0, y0, x1, y1), x1 and y1 exclusive


class FoveateMany(Protocol):
    """foveate(image, f) for each fixation f; with regions (one per fixation), only each
    region need be right (`Foveator.foveate_many`)."""

    def __call__(self, image: np.ndarray, fixations: list[tuple[float, float]],
                 regions: list[Region] | None = None) -> list[np.ndarray]: ...


class ModelError(ValueError):
    """A model, labels or preprocessing file that cannot be used (the message says why)."""


@dataclass(frozen=True)
class Preprocessing:
    """How an RGB uint8 image becomes the network's input: the window x window square around
    the fixation (window > 0; 0: the whole image), resized to input_size (w, h), scaled to
    [0, 1], then (x - mean) / std per channel."""

    input_size: tuple[int, int] = DEFAULT_INPUT_SIZE
    mean: tuple[float, float, float] = IMAGENET_MEAN
    std: tuple[float, float, float] = IMAGENET_STD
    window: int = 0

    def as_dict(self) -> dict[str, list[float] | list[int] | int]:
        out: dict[str, list[float] | list[int] | int] = {
            'input_size': list(self.input_size), 'mean': list(self.mean), 'std': list(self.std)}
        if self.window:
            out['window'] = self.window
        return out


def window_origin(centre: tuple[float, float], window: int) -> tuple[int, int]:
    """Top-left pixel (x, y) of the window x window square centred at centre (image px)."""
    return (int(round(centre[0])) - window // 2, int(round(centre[1])) - window // 2)


def window_region(centre: tuple[float, float], window: int) -> Region:
    """The window x window square centred at centre as (x0, y0, x1, y1), x1 and y1 exclusive:
    the pixels crop_window reads (it mirrors the part outside the image from inside this)."""
    x0, y0 = window_origin(centre, window)
    return (x0, y0, x0 + window, y0 + window)


def crop_window(image: np.ndarray, centre: tuple[float, float], window: int) -> np.ndarray:
    """The window x window square of image centred at centre (x, y) [px], the part outside
    the image mirrored in (cv2's BORDER_REFLECT_101), as a new array."""
    h, w = image.shape[:2]
    x0, y0 = window_origin(centre, window)
    x1, y1 = x0 + window, y0 + window
    cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if cx0 >= cx1 or cy0 >= cy1:
        raise ValueError(f'window centre {centre} lies {window // 2} px or more outside the '
                         f'{w}x{h} image')
    part = image[cy0:cy1, cx0:cx1]
    pads = (cy0 - y0, y1 - cy1, cx0 - x0, x1 - cx1)
    if not any(pads):
        return part.copy()
    if max(pads[0], pads[1]) >= h or max(pads[2], pads[3]) >= w:   # mirror needs the room
        return cv2.copyMakeBorder(part, *pads, cv2.BORDER_REPLICATE)
    return cv2.copyMakeBorder(part, *pads, cv2.BORDER_REFLECT_101)


def preprocessing_path_for(model_path: str | Path) -> Path:
    """The preprocessing JSON that goes with a model: the model's path with .json."""
    return Path(model_path).with_suffix('.json')


def load_labels(path: str | Path) -> list[str]:
    """Class labels, one per line (blank lines and surrounding spaces ignored)."""
    try:
        text = Path(path).read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f'cannot read labels file {path}: {exc}') from exc
    labels = [line.strip() for line in text.splitlines() if line.strip()]
    if not labels:
        raise ModelError(f'labels file {path} holds no labels')
    return labels


def load_preprocessing(path: str | Path | None) -> Preprocessing:
    """The preprocessing JSON at path ({"input_size": [w, h], "mean": [3], "std": [3]}, each key
    optional); ImageNet's defaults if path is None or does not exist."""
    if path is None or not Path(path).exists():
        return Preprocessing()
    try:
        raw = json.loads(Path(path).read_text(encoding='utf-8'))
        size = tuple(int(v) for v in raw.get('input_size', DEFAULT_INPUT_SIZE))
        mean = tuple(float(v) for v in raw.get('mean', IMAGENET_MEAN))
        std = tuple(float(v) for v in raw.get('std', IMAGENET_STD))
        window = int(raw.get('window', 0))
    except (OSError, ValueError, TypeError, AttributeError) as exc:
        raise ModelError(f'cannot read preprocessing file {path}: {exc}') from exc
    if len(size) != 2 or min(size) < 8 or len(mean) != 3 or len(std) != 3 or min(std) <= 0:
        raise ModelError(f'preprocessing file {path}: need input_size [w >= 8, h >= 8], 3 means '
                         f'and 3 positive stds, got {raw}')
    if window < 0 or 0 < window < 8:
        raise ModelError(f'preprocessing file {path}: window must be 0 (the whole image) or at '
                         f'least 8 px, got {window}')
    return Preprocessing(size, mean, std, window)


@dataclass(frozen=True)
class Detection:
    """One class found in one pass: its label, probability, saliency box (image px) and the
    fixation of the pass that found it; for pass 2, row: its row of TwoPassResult.probs_second
    (the image foveated at the pass-1 box centre it was found in; None in pass 1)."""

    class_id: int
    label: str
    score: float
    box: Box
    fixation: tuple[float, float]
    pass_index: int
    row: int | None = None

    @property
    def centre(self) -> tuple[float, float]:
        x0, y0, x1, y1 = self.box
        return ((x0 + x1) / 2.0, (y0 + y1) / 2.0)


@dataclass
class TwoPassResult:
    """first: pass 1's top-k (boxes from its saliency; with a reject class only those whose
    probability beats background's at the fixation); second: the best non-repeated labels of
    pass 2 (boxes from the saliency of each label on the image it was found in);
    probs_first: pass 1's class probabilities; probs_second: (k, C), one row per box centre
    (pass 1's top-k boxes, reported or not)."""

    first: list[Detection]
    second: list[Detection]
    probs_first: np.ndarray
    probs_second: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))


class Classifier:
    """A TorchScript classifier with its labels and preprocessing (see the module docstring).

    Raises ModelError when the model file does not load, does not run on an image of its input
    size, or gives another number of outputs than there are labels.
    """

    def __init__(self, model_path: str | Path, labels_path: str | Path,
                 preprocessing_path: str | Path | None = None) -> None:
        self.labels = load_labels(labels_path)
        #: index of BACKGROUND_LABEL (the reject class) in labels, None if the model has none
        self.reject_class = (self.labels.index(BACKGROUND_LABEL)
                             if BACKGROUND_LABEL in self.labels else None)
        self.preprocessing = load_preprocessing(
            preprocessing_path if preprocessing_path is not None
            else preprocessing_path_for(model_path))
        try:
            with warnings.catch_warnings():   # torch >= 2.9 deprecates TorchScript; it still runs
                warnings.simplefilter('ignore', DeprecationWarning)
                self.model = torch.jit.load(str(model_path), map_location='cpu')
        except Exception as exc:  # RuntimeError, ValueError, OSError: all mean "not a model"
            raise ModelError(f'cannot load TorchScript model {model_path}: '
                             f'{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ""}'
                             ) from exc
        self.model.eval()
        for param in self.model.parameters():   # saliency needs d/d input only
            param.requires_grad_(False)
        w, h = self.preprocessing.input_size
        mean = torch.tensor(self.preprocessing.mean, dtype=torch.float32).view(1, 3, 1, 1)
        std = torch.tensor(self.preprocessing.std, dtype=torch.float32).view(1, 3, 1, 1)
        self._scale = 1.0 / (255.0 * std)            # x_net = x_uint8 * scale + shift
        self._shift = -mean / std
        try:
            with torch.inference_mode():
                out = self.model(torch.zeros(1, 3, h, w))
        except Exception as exc:
            raise ModelError(f'model {model_path} fails on a 1x3x{h}x{w} input: '
                             f'{type(exc).__name__}: {exc}') from exc
        if not isinstance(out, torch.Tensor) or out.shape != (1, len(self.labels)):
            shape = tuple(out.shape) if isinstance(out, torch.Tensor) else type(out).__name__
            raise ModelError(f'model {model_path} outputs {shape} for one image, but '
                             f'{labels_path} has {len(self.labels)} labels')

    @property
    def num_classes(self) -> int:
        return len(self.labels)

    @property
    def object_classes(self) -> list[int]:
        """Indices of the classes that can be detected: all but the reject class."""
        return [c for c in range(len(self.labels)) if c != self.reject_class]

    # ----------------------------------------------------------------------------------------

    @property
    def window(self) -> int:
        """Side [px] of the square around the fixation the network sees; 0: the whole image."""
        return self.preprocessing.window

    def preprocess(self, images: np.ndarray | Sequence[np.ndarray],
                   centres: Sequence[tuple[float, float]] | None = None) -> torch.Tensor:
        """(N, 3, h, w) float32 network input of RGB uint8 images (one (H, W, 3) or a list);
        each is resized to the input size (cv2.INTER_AREA when shrinking). A window model takes
        the window around centres[i] of image i (one image and several centres: that image's
        windows; no centres: the images' centres)."""
        if isinstance(images, np.ndarray) and images.ndim == 3:
            images = [images]
        images = list(images)
        if self.window:
            if centres is None:
                centres = [((img.shape[1] - 1) / 2.0, (img.shape[0] - 1) / 2.0) for img in images]
            if len(images) == 1 and len(centres) > 1:
                images = images * len(centres)
            if len(centres) != len(images):
                raise ValueError(f'{len(centres)} window centres for {len(images)} images')
            for img in images:
                if img.ndim != 3 or img.shape[2] != 3:
                    raise ValueError(f'expected an (H, W, 3) RGB image, got shape {img.shape}')
            images = [crop_window(img, c, self.window)
                      for img, c in zip(images, centres, strict=True)]
        w, h = self.preprocessing.input_size
        batch = np.empty((len(images), h, w, 3), np.uint8)
        for i, img in enumerate(images):
            if img.ndim != 3 or img.shape[2] != 3:
                raise ValueError(f'expected an (H, W, 3) RGB image, got shape {img.shape}')
            shrink = img.shape[0] >= h and img.shape[1] >= w
            batch[i] = img if img.shape[:2] == (h, w) else cv2.resize(
                img, (w, h), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
        x = torch.from_numpy(batch).permute(0, 3, 1, 2).float()
        return x * self._scale + self._shift

    def logits(self, x: torch.Tensor) -> torch.Tensor:
        return self.model(x)

    def classify(self, images: np.ndarray | Sequence[np.ndarray],
                 centres: Sequence[tuple[float, float]] | None = None) -> np.ndarray:
        """(N, C) class probabilities (softmax of the scores) of RGB uint8 images (a window
        model: of their windows at centres, see preprocess)."""
        with torch.inference_mode():
            return torch.softmax(self.model(self.preprocess(images, centres)), dim=1).numpy()

    def saliency(self, images: np.ndarray | Sequence[np.ndarray],
                 classes: Sequence[int],
                 centres: Sequence[tuple[float, float]] | None = None) -> np.ndarray:
        """(N, h, w) class saliency maps (Eqs. 2.19-2.20) in network-input pixels, in [0, 1].

        Map i is |d S_c / d I| of class classes[i] on image i (one image: the same image for
        every class), max over colour channels, divided by its maximum. Several images: one
        batched backward pass of the sum of the chosen scores, each depending on its own image
        only. One image: one forward pass and a backward pass per class (the same maps; the
        forward pass of N copies of the image cost more than the N - 1 backward passes saved).
        """
        if isinstance(images, np.ndarray) and images.ndim == 3 and (
                centres is None or len(centres) == 1):
            return self._saliency_of_one(self.preprocess(images, centres), classes)[1]
        x = self.preprocess(images, centres)
        if x.shape[0] != len(classes):
            raise ValueError(f'{x.shape[0]} images for {len(classes)} classes')
        x.requires_grad_(True)
        with torch.enable_grad():
            scores = self.model(x)
            idx = torch.as_tensor(list(classes), dtype=torch.long)
            scores.gather(1, idx[:, None]).sum().backward()
        assert x.grad is not None                                     # set by backward()
        return _normalised(x.grad.abs().amax(dim=1))                  # (N, h, w)

    def classify_with_saliency(
            self, image: np.ndarray, centre: tuple[float, float] | None,
            choose: Callable[[np.ndarray], Sequence[int]]) -> tuple[np.ndarray, np.ndarray]:
        """classify(image, [centre])[0] and the saliency maps of the classes choose(probs)
        picks from them, (len, h, w), from one forward pass (what pass 1 of Fig. 2.5 needs)."""
        return self._saliency_of_one(self.preprocess(image, None if centre is None
                                                     else [centre]), choose)

    def _saliency_of_one(
            self, x: torch.Tensor,
            classes: Sequence[int] | Callable[[np.ndarray], Sequence[int]]
    ) -> tuple[np.ndarray, np.ndarray]:
        """(probabilities, maps) of one preprocessed image x (1, 3, h, w): the classes given,
        or chosen from the probabilities; one forward pass, one backward pass per class."""
        x = x.detach().requires_grad_(True)
        with torch.enable_grad():
            scores = self.model(x)
            probs = torch.softmax(scores.detach(), dim=1).numpy()[0]
            chosen = list(classes(probs) if callable(classes) else classes)
            grads = [torch.autograd.grad(scores[0, int(c)], x, retain_graph=i < len(chosen) - 1)[0]
                     for i, c in enumerate(chosen)]
        if not grads:
            h, w = x.shape[2:]
            return probs, np.zeros((0, h, w), np.float32)
        return probs, _normalised(torch.cat(grads).abs().amax(dim=1))

    def box_to_image(self, box: Box, width: int, height: int,
                     centre: tuple[float, float] | None = None) -> Box:
        """A box in network-input pixels as a box in a width x height image's pixels (a window
        model: in the window at centre, default the image's centre), clipped to the image."""
        w, h = self.preprocessing.input_size
        ox, oy = 0, 0
        if self.window:
            if centre is None:
                centre = ((width - 1) / 2.0, (height - 1) / 2.0)
            ox, oy = window_origin(centre, self.window)
            sx, sy = self.window / w, self.window / h
        else:
            sx, sy = width / w, height / h
        x0, y0, x1, y1 = box
        return (min(max(ox + int(math.floor(x0 * sx)), 0), width - 1),
                min(max(oy + int(math.floor(y0 * sy)), 0), height - 1),
                min(max(ox + int(math.ceil((x1 + 1) * sx)) - 1, 0), width - 1),
                min(max(oy + int(math.ceil((y1 + 1) * sy)) - 1, 0), height - 1))


def _normalised(grad: torch.Tensor) -> np.ndarray:
    """(N, h, w) gradient magnitudes, each map divided by its maximum."""
    peak = grad.flatten(1).amax(dim=1).clamp_min(1e-12)
    return (grad / peak[:, None, None]).numpy()


def saliency_box(saliency: np.ndarray, threshold: float = DEFAULT_THRESHOLD) -> Box:
    """Bounding box (x0, y0, x1, y1) of the pixels whose saliency exceeds threshold times the
    map's maximum (the segmentation mask of section 2.3.2); the peak pixel if none does."""
    peak = float(saliency.max())
    mask = saliency > threshold * peak if peak > 0 else saliency >= peak
    if not mask.any():
        mask = saliency >= peak
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    return (int(cols[0]), int(rows[0]), int(cols[-1]), int(rows[-1]))


def localise(classifier: Classifier, image: np.ndarray, classes: Sequence[int],
             threshold: float = DEFAULT_THRESHOLD,
             net_input: np.ndarray | Sequence[np.ndarray] | None = None,
             centres: Sequence[tuple[float, float]] | None = None) -> list[Box]:
    """Saliency boxes (image px) of classes on image (or on the images of net_input, one per
    class, all of image's size); a window model: in the windows at centres (one per class, or
    one for all)."""
    maps = classifier.saliency(image if net_input is None else net_input, classes, centres)
    h, w = image.shape[:2]
    return boxes_of(classifier, maps, w, h, threshold, centres)


def boxes_of(classifier: Classifier, maps: np.ndarray, width: int, height: int,
             threshold: float = DEFAULT_THRESHOLD,
             centres: Sequence[tuple[float, float]] | None = None) -> list[Box]:
    """The saliency boxes of maps (network-input pixels) in a width x height image's pixels
    (a window model: in the windows at centres, one per map or one for all)."""
    per = list(centres) if centres is not None else [None]
    if len(per) == 1:
        per = per * len(maps)
    return [classifier.box_to_image(saliency_box(m, threshold), width, height, c)
            for m, c in zip(maps, per, strict=True)]


def merge_second_pass(probs: np.ndarray, top_k: int,
                      reject: int | None = None) -> list[tuple[int, int, float]]:
    """Fig. 2.5's choice: the k x k (class, score) pairs of pass 2 (row i: the image foveated at
    box i), sorted by score, the best non-repeated classes first. Returns up to top_k
    (class, row, score).

    reject: the reject (background) class, or None. Then each row's top-k are its best k other
    classes, and a pair counts only if its score exceeds the row's reject score (the class beats
    background where it was seen); fewer than top_k pairs, or none, may remain."""
    ranked = np.argsort(-probs, axis=1)
    if reject is not None:
        ranked = ranked[ranked != reject].reshape(probs.shape[0], -1)
    k = min(top_k, ranked.shape[1])
    top = ranked[:, :k]                                         # (rows, k)
    rows = np.repeat(np.arange(probs.shape[0]), k)
    cls = top.ravel()
    score = probs[rows, cls]
    order = np.argsort(-score, kind='stable')
    out: list[tuple[int, int, float]] = []
    seen: set[int] = set()
    for i in order:
        c = int(cls[i])
        if reject is not None and not score[i] > probs[rows[i], reject]:
            continue
        if c not in seen:
            seen.add(c)
            out.append((c, int(rows[i]), float(score[i])))
            if len(out) == k:
                break
    return out


def two_pass(classifier: Classifier, image: np.ndarray, fixation: tuple[float, float],
             foveate: Foveate, top_k: int = DEFAULT_TOP_K,
             threshold: float = DEFAULT_THRESHOLD, localise_second: bool = True, *,
             first_image: np.ndarray | None = None,
             foveate_many: FoveateMany | None = None) -> TwoPassResult:
    """Fig. 2.5 on an RGB uint8 image: pass 1 at fixation, pass 2 at each pass-1 box centre.

    foveate(image, (u, v)) gives the image foveated at (u, v) (same size), e.g.
    `Foveator.foveate`; pass lambda img, fix: img for a uniform-resolution sensor.
    first_image: foveate(image, fixation) when the caller has it already (a node foveates
    every frame at the fixation anyway); foveate_many(image, fixations[, regions]): the pass-2
    images at once (`Foveator.foveate_many`, one pyramid for all), else foveate one by one; a
    window model asks it for each image's window only (window_region), all the network sees.
    localise_second: also compute each pass-2 label's box (one more batched backward pass).
    With a reject class (Classifier.reject_class), pass 1 takes the top-k object classes and
    pass 2 keeps only labels that beat background (merge_second_pass): `second` may be empty.
    """
    if int(top_k) < 1:
        raise ValueError(f'top_k must be >= 1, got {top_k}')
    reject = classifier.reject_class
    k = min(int(top_k), classifier.num_classes - (reject is not None))
    fixation = (float(fixation[0]), float(fixation[1]))
    if first_image is None:
        first_image = foveate(image, fixation)
    elif first_image.shape != image.shape:
        raise ValueError(f'first_image is {first_image.shape}, the image {image.shape}')
    # the top-k object classes (never background) and their saliency, from one forward pass
    def top_classes(probs: np.ndarray) -> list[int]:
        return [int(c) for c in np.argsort(-probs) if c != reject][:k]

    probs1, maps1 = classifier.classify_with_saliency(first_image, fixation, top_classes)
    classes1 = top_classes(probs1)
    if not classes1:                                # a model that knows background only
        return TwoPassResult([], [], probs1, np.zeros((0, classifier.num_classes)))
    boxes1 = boxes_of(classifier, maps1, image.shape[1], image.shape[0], threshold, [fixation])
    looked = [Detection(c, classifier.labels[c], float(probs1[c]), b, fixation, 0)
              for c, b in zip(classes1, boxes1, strict=True)]
    # pass 2 looks at every top-k box; pass 1 reports only what beats background where it looked
    first = (looked if reject is None
             else [d for d in looked if probs1[d.class_id] > probs1[reject]])

    centres = [d.centre for d in looked]
    if foveate_many is None:
        second_images = [foveate(image, c) for c in centres]
    elif classifier.window:        # the network sees only the window: foveate only that
        second_images = foveate_many(image, centres,
                                     [window_region(c, classifier.window) for c in centres])
    else:
        second_images = foveate_many(image, centres)
    probs2 = classifier.classify(second_images, centres)
    chosen = merge_second_pass(probs2, k, reject)
    if localise_second and chosen:
        boxes2 = localise(classifier, image, [c for c, _, _ in chosen], threshold,
                          net_input=[second_images[r] for _, r, _ in chosen],
                          centres=[centres[r] for _, r, _ in chosen])
    else:
        boxes2 = [looked[r].box for _, r, _ in chosen]
    second = [Detection(c, classifier.labels[c], s, b, centres[r], 1, row=r)
              for (c, r, s), b in zip(chosen, boxes2, strict=True)]
    return TwoPassResult(first, second, probs1, probs2)


def grid_centres(width: int, height: int, stride: int) -> list[tuple[float, float]]:
    """Centres [px] of a grid with the given stride over a width x height image, every pixel
    within stride / 2 (in x and in y) of one."""
    xs = np.arange(stride / 2.0 - 0.5, width, stride)
    ys = np.arange(stride / 2.0 - 0.5, height, stride)
    return [(float(x), float(y)) for y in ys for x in xs]


def grid_recognition(classifier: Classifier, image: np.ndarray, stride: int,
                     batch: int = 64) -> tuple[list[Detection], np.ndarray]:
    """Recognition at uniform resolution everywhere: a window model classifies the window at
    every centre of grid_centres(stride) of the (unfoveated) image, in batches. Each window
    whose best object class beats background (any best class, without a reject class) is a
    Detection of pass 0 at that centre, its box the window clipped to the image. Returns the
    detections and the (N, C) probabilities of every window."""
    if not classifier.window:
        raise ValueError('grid recognition needs a window model (preprocessing "window")')
    if stride < 1:
        raise ValueError(f'stride must be at least 1 px, got {stride}')
    h, w = image.shape[:2]
    centres = grid_centres(w, h, stride)
    probs = np.concatenate([classifier.classify(image, centres[i:i + batch])
                            for i in range(0, len(centres), batch)])
    reject = classifier.reject_class
    objects = classifier.object_classes
    best = np.asarray(objects)[np.argmax(probs[:, objects], axis=1)]
    score = probs[np.arange(len(centres)), best]
    keep = score > probs[:, reject] if reject is not None else np.ones(len(centres), bool)
    half = classifier.window // 2
    out = []
    for i in np.flatnonzero(keep):
        u, v = centres[i]
        x0, y0 = window_origin((u, v), classifier.window)
        box = (max(x0, 0), max(y0, 0), min(x0 + 2 * half - 1, w - 1), min(y0 + 2 * half - 1, h - 1))
        c = int(best[i])
        out.append(Detection(c, classifier.labels[c], float(score[i]), box, (u, v), 0))
    return out, probs


def saccade_target(detections: Sequence[Detection], centre: tuple[float, float],
                   min_score: float, min_offset_px: float) -> Detection | None:
    """The detection to saccade to: the best-scoring one (detections come best first) if its
    score is at least min_score and its box centre lies at least min_offset_px from centre
    (the pixel the eyes already fixate: nothing to gain from a saccade of a few pixels).
    A BACKGROUND_LABEL detection (two_pass gives none) is never a target."""
    detections = [d for d in detections if d.label != BACKGROUND_LABEL]
    if not detections:
        return None
    best = max(detections, key=lambda d: d.score)
    if best.score < min_score:
        return None
    du, dv = best.centre[0] - centre[0], best.centre[1] - centre[1]
    return best if math.hypot(du, dv) >= min_offset_px else None


__all__ = ['BACKGROUND_LABEL', 'Box', 'Classifier', 'DEFAULT_INPUT_SIZE', 'DEFAULT_THRESHOLD',
           'DEFAULT_TOP_K', 'Detection', 'IMAGENET_MEAN', 'IMAGENET_STD', 'ModelError',
           'Preprocessing',
           'TwoPassResult', 'crop_window', 'grid_centres', 'grid_recognition', 'load_labels',
           'load_preprocessing', 'localise', 'boxes_of', 'window_region', 'merge_second_pass',
           'preprocessing_path_for', 'saccade_target', 'saliency_box', 'two_pass',
           'window_origin']
