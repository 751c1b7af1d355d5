"""Pre-attention shape classifier (thesis section 4.3.2, Fig. 4.1): is this image patch a cylinder?

The thesis fine-tunes a SqueezeNet on patches cut out of the RGB image around each segmented
cluster, so that clusters that are not cylinders never reach the (costlier, and fooled by boxes
and spheres) Hough fit. Here a much smaller CNN of the same family (Fire-like blocks: 1x1
squeeze, then 3x3 convolutions, global average pooling instead of fully connected layers) on
64x64 patches, trained on simulated tabletop scenes by `train_cylinder_classifier` (the stored
weights are in cylinder_detector_node/models/).

Patches: the cluster's image box made square (longest side + PATCH_MARGIN on each side, centred),
cropped with zero padding where it leaves the image, resized to PATCH_SIZE with area
interpolation; the network sees RGB scaled to [0, 1] and normalized per channel by the training
set's mean and std (stored with the weights).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import cv2
import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

PATCH_SIZE = 64
PATCH_MARGIN = 0.1          #: fraction of the longest side added around the box
MODEL_DIR = Path(__file__).resolve().parents[1] / 'models'
DEFAULT_MODEL = MODEL_DIR / 'cylinder_classifier.pt'


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


class Fire(nn.Module):
    """SqueezeNet's Fire module: 1x1 squeeze, then parallel 1x1 and 3x3 expands, concatenated."""

    def __init__(self, cin: int, squeeze: int, expand: int) -> None:
        super().__init__()
        self.squeeze = nn.Sequential(nn.Conv2d(cin, squeeze, 1), nn.ReLU(inplace=True))
        self.e1 = nn.Conv2d(squeeze, expand, 1)
        self.e3 = nn.Conv2d(squeeze, expand, 3, padding=1)
        self.bn = nn.BatchNorm2d(2 * expand)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        s = self.squeeze(x)
        return torch.relu(self.bn(torch.cat([self.e1(s), self.e3(s)], 1)))


class PatchNet(nn.Module):
    """A SqueezeNet-like patch classifier for 64x64 RGB: ~50k parameters, logit of 'cylinder'."""

    def __init__(self) -> None:
        super().__init__()
        self.features = nn.Sequential(
            # as SqueezeNet: a strided convolution and a max pool first (64 -> 16), Fires after
            nn.Conv2d(3, 32, 3, stride=2, padding=1), nn.BatchNorm2d(32), nn.ReLU(inplace=True),
            nn.MaxPool2d(2),                                                  # 16x16
            Fire(32, 16, 32), Fire(64, 16, 48), nn.MaxPool2d(2),              # 8x8
            Fire(96, 24, 64), nn.MaxPool2d(2),                                # 4x4
            Fire(128, 32, 64),
        )
        self.head = nn.Sequential(nn.Dropout(0.2), nn.Conv2d(128, 1, 1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(x)).mean(dim=(2, 3)).squeeze(1)


@dataclass
class PatchClassifier:
    """The trained network plus its input normalization; `probabilities` on uint8 RGB patches."""

    net: PatchNet
    mean: NDArray[np.float32]
    std: NDArray[np.float32]
    threshold: float = 0.5
    meta: dict | None = None

    @classmethod
    def load(cls, path: str | Path | None = None) -> PatchClassifier:
        """Weights and metadata from a .pt file (default: the packaged model). Raises
        FileNotFoundError / ValueError with the path in the message."""
        path = Path(path) if path else DEFAULT_MODEL
        if not path.is_file():
            raise FileNotFoundError(f'no classifier model at {path} '
                                    f'(train one with train_cylinder_classifier)')
        try:
            blob = torch.load(path, map_location='cpu', weights_only=True)
            net = PatchNet()
            net.load_state_dict(blob['state_dict'])
            meta = json.loads(blob['meta'])
        except Exception as exc:   # a corrupt or foreign file: one clear message
            raise ValueError(f'{path}: not a cylinder classifier model '
                             f'({type(exc).__name__}: {exc})') from exc
        net.eval()
        return cls(net, np.asarray(meta['mean'], np.float32), np.asarray(meta['std'], np.float32),
                   float(meta.get('threshold', 0.5)), meta)

    def save(self, path: str | Path, meta: dict) -> None:
        meta = dict(meta, mean=[float(v) for v in self.mean], std=[float(v) for v in self.std],
                    threshold=self.threshold, patch_size=PATCH_SIZE, patch_margin=PATCH_MARGIN)
        sd = {k: v.half() if v.is_floating_point() else v for k, v in self.net.state_dict().items()}
        torch.save({'state_dict': sd, 'meta': json.dumps(meta)}, path)

    def to_tensor(self, patches: NDArray[np.uint8]) -> torch.Tensor:
        x = torch.from_numpy(np.ascontiguousarray(patches, dtype=np.float32)).permute(0, 3, 1, 2)
        x = x / 255.0
        mean = torch.from_numpy(self.mean)[None, :, None, None]
        std = torch.from_numpy(self.std)[None, :, None, None]
        return (x - mean) / std

    def probabilities(self, patches: NDArray[np.uint8]) -> NDArray[np.float64]:
        """P(cylinder) of each (N, S, S, 3) uint8 RGB patch, one batched forward pass."""
        if len(patches) == 0:
            return np.zeros(0)
        with torch.inference_mode():
            logits = self.net(self.to_tensor(patches).float())
        return torch.sigmoid(logits.float()).double().numpy()

    def classify(self, image: NDArray[np.uint8],
                 boxes: list[tuple[int, int, int, int]]) -> NDArray[np.float64]:
        """P(cylinder) for each image box (u0, v0, u1, v1) of image (H, W, 3) RGB."""
        if not boxes:
            return np.zeros(0)
        return self.probabilities(np.stack([extract_patch(image, b) for b in boxes]))
