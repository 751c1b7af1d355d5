"""Pre-attention shape classifier (thesis section 4.3.2, Fig. 4.1): is this image patch a cylinder?

The thesis fine-tunes a SqueezeNet on patches cut out of the RGB image around each segmented
cluster, so that clusters that are not cylinders never reach the (costlier, and fooled by boxes
and spheres) Hough fit. Here a much smaller CNN of the same family (Fire-like blocks: 1x1
squeeze, then 3x3 convolutions, global average pooling instead of fully connected layers) on
64x64 patches, trained on simulated tabletop scenes by `train_cylinder_classifier` with PyTorch
(training/patch_net.py; the stored weights are in cylinder_detector_node/models/, a NumPy .npz).

Inference here is NumPy: the node runs this ~50k-parameter network on a few patches per cloud,
and importing PyTorch for it would cost the node ~180 MB of memory (the graph's budget,
bench/graph_budget.py). test_classifier.py checks that it computes what the PyTorch module does.

Patches: the cluster's image box made square (longest side + PATCH_MARGIN on each side, centred),
cropped with zero padding where it leaves the image, resized to PATCH_SIZE with area
interpolation; the network sees RGB scaled to [0, 1] and normalized per channel by the training
set's mean and std (stored with the weights).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import cv2
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

PATCH_SIZE = 64
PATCH_MARGIN = 0.1          #: fraction of the longest side added around the box
MODEL_DIR = Path(__file__).resolve().parents[1] / 'models'
DEFAULT_MODEL = MODEL_DIR / 'cylinder_classifier.npz'
BN_EPS = 1e-5               #: BatchNorm2d's default epsilon
#: the Fire blocks of the network, in order, and where a 2x2 max pool follows one
FIRES = ('features.4', 'features.5', 'features.7', 'features.9')
POOL_AFTER = ('features.5', 'features.7')


def square_box(box: tuple[int, int, int, int],
               margin: float = PATCH_MARGIN) -> tuple[int, int, int, int]:
    """(u0, v0, u1, v1) -> a square box of side (1 + 2 margin) x the longest side, same centre."""
    u0, v0, u1, v1 = box
    side = max(u1 - u0, v1 - v0) * (1.0 + 2.0 * margin)
    side = max(int(round(side)), 2)
    cu, cv = 0.5 * (u0 + u1), 0.5 * (v0 + v1)
    a, b = int(round(cu - side / 2)), int(round(cv - side / 2))
    return a, b, a + side, b + side


def extract_patch(image: NDArray[np.uint8], box: tuple[int, int, int, int], size: int = PATCH_SIZE,
                  margin: float = PATCH_MARGIN) -> NDArray[np.uint8]:
    """The (size, size, 3) patch of image around box (u0, v0, u1, v1), square, zero-padded
    outside."""
    h, w = image.shape[:2]
    a, b, a1, b1 = square_box(box, margin)
    side = a1 - a
    crop = np.zeros((side, side, 3), np.uint8)
    su0, sv0, su1, sv1 = max(a, 0), max(b, 0), min(a1, w), min(b1, h)
    if su1 > su0 and sv1 > sv0:
        crop[sv0 - b:sv1 - b, su0 - a:su1 - a] = image[sv0:sv1, su0:su1, :3]
    interp = cv2.INTER_AREA if side > size else cv2.INTER_LINEAR
    return cast(NDArray[np.uint8], cv2.resize(crop, (size, size), interpolation=interp))


Weights = dict[str, NDArray[np.float32]]


def _conv(x: NDArray[np.float32], w: NDArray[np.float32], b: NDArray[np.float32],
          stride: int = 1, pad: int = 0) -> NDArray[np.float32]:
    """Conv2d of NHWC x with PyTorch's (out, in, k, k) weights."""
    k = w.shape[-1]
    if k == 1 and stride == 1:
        y = x @ w[:, :, 0, 0].T
    else:
        xp = np.pad(x, ((0, 0), (pad, pad), (pad, pad), (0, 0))) if pad else x
        win = sliding_window_view(xp, (k, k), axis=(1, 2))[:, ::stride, ::stride]
        y = np.tensordot(win, w, axes=([3, 4, 5], [1, 2, 3]))      # (N, H', W', out)
    return (y + b).astype(np.float32, copy=False)


def _batchnorm(x: NDArray[np.float32], weights: Weights, name: str) -> NDArray[np.float32]:
    scale = weights[f'{name}.weight'] / np.sqrt(weights[f'{name}.running_var'] + BN_EPS)
    return x * scale + (weights[f'{name}.bias'] - weights[f'{name}.running_mean'] * scale)


def _maxpool2(x: NDArray[np.float32]) -> NDArray[np.float32]:
    n, h, w, c = x.shape
    return x[:, :h // 2 * 2, :w // 2 * 2].reshape(n, h // 2, 2, w // 2, 2, c).max(axis=(2, 4))


def _fire(x: NDArray[np.float32], weights: Weights, name: str) -> NDArray[np.float32]:
    """SqueezeNet's Fire module: 1x1 squeeze, then parallel 1x1 and 3x3 expands, concatenated."""
    s = np.maximum(_conv(x, weights[f'{name}.squeeze.0.weight'],
                         weights[f'{name}.squeeze.0.bias']), 0.0)
    e = np.concatenate([_conv(s, weights[f'{name}.e1.weight'], weights[f'{name}.e1.bias']),
                        _conv(s, weights[f'{name}.e3.weight'], weights[f'{name}.e3.bias'],
                              pad=1)], axis=-1)
    return np.maximum(_batchnorm(e, weights, f'{name}.bn'), 0.0)


def patch_logits(weights: Weights, x: NDArray[np.float32]) -> NDArray[np.float32]:
    """The network's logit of 'cylinder' for normalized (N, S, S, 3) patches: a strided 3x3
    convolution and a max pool (64 -> 16 px, as SqueezeNet), Fire blocks with max pools (to 4x4),
    a 1x1 convolution to one channel, averaged over the image (global average pooling)."""
    x = _conv(x, weights['features.0.weight'], weights['features.0.bias'], stride=2, pad=1)
    x = _maxpool2(np.maximum(_batchnorm(x, weights, 'features.1'), 0.0))
    for name in FIRES:
        x = _fire(x, weights, name)
        if name in POOL_AFTER:
            x = _maxpool2(x)
    logits = _conv(x, weights['head.1.weight'], weights['head.1.bias'])
    return logits.mean(axis=(1, 2))[:, 0]


def _arrays(state: dict[str, object]) -> Weights:
    """The float tensors of a state dict (torch or numpy) as float32 arrays (BatchNorm's
    num_batches_tracked counters left out)."""
    out: Weights = {}
    for key, value in state.items():
        arr = np.asarray(value.numpy() if hasattr(value, 'numpy') else value)
        if arr.dtype.kind == 'f':
            out[key] = arr.astype(np.float32)
    return out


@dataclass
class PatchClassifier:
    """The trained network's weights plus its input normalization; `probabilities` on uint8 RGB
    patches."""

    weights: Weights
    mean: NDArray[np.float32]
    std: NDArray[np.float32]
    threshold: float = 0.5
    meta: dict | None = None

    @property
    def parameters(self) -> int:
        return int(sum(v.size for k, v in self.weights.items() if not k.endswith(
            ('running_mean', 'running_var'))))

    @classmethod
    def load(cls, path: str | Path | None = None) -> PatchClassifier:
        """Weights and metadata from a .npz file (default: the packaged model) or a PyTorch .pt
        file of train_cylinder_classifier's (that needs PyTorch). Raises FileNotFoundError /
        ValueError with the path in the message."""
        path = Path(path) if path else DEFAULT_MODEL
        if not path.is_file():
            raise FileNotFoundError(f'no classifier model at {path} '
                                    f'(train one with train_cylinder_classifier)')
        try:
            if path.suffix == '.pt':
                import torch  # only for a model in PyTorch's format
                blob = torch.load(path, map_location='cpu', weights_only=True)
                state, meta = blob['state_dict'], json.loads(blob['meta'])
            else:
                with np.load(path, allow_pickle=False) as npz:
                    state = {k: npz[k] for k in npz.files if k != 'meta'}
                    meta = json.loads(str(npz['meta']))
            weights = _arrays(state)
            clf = cls(weights, np.asarray(meta['mean'], np.float32),
                      np.asarray(meta['std'], np.float32), float(meta.get('threshold', 0.5)), meta)
            clf.probabilities(np.zeros((1, PATCH_SIZE, PATCH_SIZE, 3), np.uint8))  # all there?
        except Exception as exc:   # a corrupt or foreign file: one clear message
            raise ValueError(f'{path}: not a cylinder classifier model '
                             f'({type(exc).__name__}: {exc})') from exc
        return clf

    def save(self, path: str | Path, meta: dict) -> None:
        """As a .npz of float16 weights and the metadata (JSON)."""
        meta = dict(meta, mean=[float(v) for v in self.mean], std=[float(v) for v in self.std],
                    threshold=self.threshold, patch_size=PATCH_SIZE, patch_margin=PATCH_MARGIN)
        arrays: dict[str, Any] = {k: v.astype(np.float16) for k, v in self.weights.items()}
        arrays['meta'] = np.array(json.dumps(meta))
        with open(path, 'wb') as f:
            np.savez_compressed(f, **arrays)

    def normalize(self, patches: NDArray[np.uint8]) -> NDArray[np.float32]:
        """(N, S, S, 3) uint8 RGB -> the network's input: [0, 1], minus mean, over std."""
        x = np.asarray(patches, dtype=np.float32) / np.float32(255.0)
        return ((x - self.mean) / self.std).astype(np.float32, copy=False)

    def probabilities(self, patches: NDArray[np.uint8]) -> NDArray[np.float64]:
        """P(cylinder) of each (N, S, S, 3) uint8 RGB patch, one batched forward pass."""
        if len(patches) == 0:
            return np.zeros(0)
        logits = patch_logits(self.weights, self.normalize(patches)).astype(np.float64)
        return 1.0 / (1.0 + np.exp(-logits))

    def classify(self, image: NDArray[np.uint8],
                 boxes: list[tuple[int, int, int, int]]) -> NDArray[np.float64]:
        """P(cylinder) for each image box (u0, v0, u1, v1) of image (H, W, 3) RGB."""
        if not boxes:
            return np.zeros(0)
        return self.probabilities(np.stack([extract_patch(image, b) for b in boxes]))
