"""Fixtures of the foveation tests: a tiny TorchScript classifier built in the test.

The stub's class scores are colour detectors: class c's score is the strongest response, over
the image, of a 5x5 box filter on colour channel c (red, green, blue), so its saliency
(d score / d input) sits in the 5x5 window on the most colourful spot, and it ranks images by
which colour patch they hold. No training: the weights are fixed.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest
import torch
from torch import nn

from vizzy_runtime.testing import no_renderer

STUB_LABELS = ('red', 'green', 'blue')


class ColourDetector(nn.Module):
    """(N, 3, h, w) -> (N, 3): per channel, the max over space of a 5x5 mean filter."""

    def __init__(self) -> None:
        super().__init__()
        self.conv = nn.Conv2d(3, 3, 5, padding=2, groups=3, bias=False)
        with torch.no_grad():
            self.conv.weight.fill_(1.0 / 25.0)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        # a channel counts only where it exceeds the other two (colour, not brightness)
        excess = 2.0 * x - x.sum(dim=1, keepdim=True) + x
        return torch.relu(self.conv(excess)).amax(dim=(2, 3)) * 4.0


def script(module: nn.Module) -> torch.jit.ScriptModule:
    """torch.jit.script without the DeprecationWarning torch >= 2.9 gives on every use (the
    node loads TorchScript files; building them is the tests' business only)."""
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', DeprecationWarning)
        return torch.jit.script(module)


def save_stub(directory: Path, labels: tuple[str, ...] = STUB_LABELS) -> tuple[Path, Path]:
    """Write the stub model (stub.pt) and its labels (stub.labels) under directory."""
    model = script(ColourDetector().eval())
    model_path, labels_path = directory / 'stub.pt', directory / 'stub.labels'
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', DeprecationWarning)
        model.save(str(model_path))
    labels_path.write_text('\n'.join(labels) + '\n')
    return model_path, labels_path


@pytest.fixture
def stub_model(tmp_path: Path) -> tuple[Path, Path]:
    return save_stub(tmp_path)


# The tabletop scene of an unseen seed (training: >= 10000; benchmark: 0-99) with the head tilted
# up at the noise-textured wall, as the demo once ended; the objects at the image's bottom.
WALL_SEED, WALL_JOINTS, WALL_FIXATION = 903, (0.0, -0.15, -0.1, 0.0, 0.0), (320.0, 160.0)


@pytest.fixture(scope='module')
def wall_view():
    """(the simulator's view of that wall, the fixation on it); skipped without offscreen
    rendering."""
    render = pytest.importorskip('vizzy_sim_bridge.core.render')
    from foveation_node.training.tabletop_views import TabletopViews
    try:
        with TabletopViews() as tv:
            return tv.view(WALL_SEED, WALL_JOINTS), WALL_FIXATION
    except render.RendererUnavailable as exc:
        no_renderer(str(exc))
