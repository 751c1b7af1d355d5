"""The pre-attention CNN as a PyTorch module, for training (train_cylinder_classifier); the node
runs the trained weights with NumPy (core.classifier.patch_logits)."""

from __future__ import annotations

import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from cylinder_detector_node.core.classifier import PatchClassifier


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
    """A SqueezeNet-like patch classifier for 64x64 RGB: ~50k parameters, logit of 'cylinder'.
    Its state dict's names are those core.classifier.patch_logits reads."""

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


def to_tensor(patches: NDArray[np.uint8], mean: NDArray[np.float32],
              std: NDArray[np.float32]) -> torch.Tensor:
    """(N, S, S, 3) uint8 RGB patches -> the network's (N, 3, S, S) input, as PatchClassifier
    normalizes them."""
    x = torch.from_numpy(np.ascontiguousarray(patches, dtype=np.float32)).permute(0, 3, 1, 2)
    x = x / 255.0
    return (x - torch.from_numpy(mean)[None, :, None, None]) \
        / torch.from_numpy(std)[None, :, None, None]


def classifier_of(net: PatchNet, mean: NDArray[np.float32], std: NDArray[np.float32],
                  threshold: float = 0.5) -> PatchClassifier:
    """The NumPy classifier with net's current weights (float16, as stored)."""
    state = {k: v.detach().half().float().numpy() for k, v in net.state_dict().items()
             if v.is_floating_point()}
    return PatchClassifier(state, mean, std, threshold)


__all__ = ['Fire', 'PatchNet', 'classifier_of', 'to_tensor']
