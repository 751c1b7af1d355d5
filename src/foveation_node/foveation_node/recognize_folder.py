"""recognize_folder: foveated recognition on a folder of labelled images, with any TorchScript
classifier (the node's model by default, or e.g. one from export_imagenet_classifier).

    recognize_folder IMAGES/ --model efficientnet_lite0.pt --f0 25 50 100 [--grid 3] [--two-pass]

Folder formats (first that applies; see foveation_node.core.folder_recognition): a CSV
`labels.csv` (or --csv FILE) of `file,label[,x0,y0,x1,y1]` rows; sub-folders named by label;
file names `<label>[_anything].<ext>` (ImageNet's `<wnid>_<name>.JPEG` match labels `<wnid>_...`).

Each image is squashed to --size x --size px (227, the thesis's setting; 0 keeps its own size),
foveated at each f0 (px of that image) from the centre and, with --grid N, from the other points
of an N x N grid, and classified (pass 1); --two-pass adds Fig. 2.5's second pass. Prints the
top-1 / top-5 error of each setting and, as the last line, a JSON summary; --json FILE also
writes each image's ranks and unfoveated top-5. Bad input: one line on stderr, exit status 2.
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from .cli_common import OneLineParser, fail

PROG = 'recognize_folder'
DEFAULT_MODEL = Path(__file__).resolve().parent / 'models' / 'foveation_cnn.pt'


def build_parser() -> OneLineParser:
    ap = OneLineParser(prog=PROG, description=__doc__.split('\n\n')[0])
    ap.add_argument('folder', type=Path, help='folder of labelled images')
    ap.add_argument('--model', type=Path, default=DEFAULT_MODEL,
                    help='TorchScript classifier (default: the packaged simulator model); its '
                         '<model>.json, if present, gives input size, mean and std')
    ap.add_argument('--labels', type=Path, default=None,
                    help='labels file, one per line (default: the model path with .labels)')
    ap.add_argument('--csv', type=Path, default=None,
                    help='file,label[,x0,y0,x1,y1] rows (default: <folder>/labels.csv if any)')
    ap.add_argument('--f0', type=float, nargs='*', default=[100.0],
                    help='fovea sizes f0 [px of the evaluated image] (default 100; none: '
                         'unfoveated only)')
    ap.add_argument('--grid', type=int, default=1,
                    help='N: initial fixations on an N x N grid besides the centre (default 1: '
                         'the centre only)')
    ap.add_argument('--two-pass', action='store_true', help='also run pass 2 (Fig. 2.5)')
    ap.add_argument('--size', type=int, default=227,
                    help='squash each image to SIZE x SIZE px first (0: keep its size)')
    ap.add_argument('--levels', type=int, default=5, help='pyramid levels K')
    ap.add_argument('--top-k', type=int, default=5)
    ap.add_argument('--threshold', type=float, default=0.7, help='saliency mask threshold th')
    ap.add_argument('--threads', type=int, default=1, help='torch threads')
    ap.add_argument('--limit', type=int, default=0, help='only the first N images (0: all)')
    ap.add_argument('--json', type=Path, default=None, help='write per-image results here')
    return ap


def _check(args) -> str | None:
    if any(not (math.isfinite(f) and f > 0) for f in args.f0):
        return f'--f0 values must be finite and > 0, got {args.f0}'
    if args.grid < 1 or args.grid > 16:
        return f'--grid must be in [1, 16], got {args.grid}'
    if not 1 <= args.levels <= 8:
        return f'--levels must be in [1, 8], got {args.levels}'
    if args.size != 0 and args.size < 2 ** args.levels:
        return f'--size must be 0 or >= 2^levels = {2 ** args.levels}, got {args.size}'
    if args.top_k < 1:
        return f'--top-k must be >= 1, got {args.top_k}'
    if not (0 < args.threshold <= 1):
        return f'--threshold must be in (0, 1], got {args.threshold}'
    if not 1 <= args.threads <= 64:
        return f'--threads must be in [1, 64], got {args.threads}'
    if args.limit < 0:
        return f'--limit must be >= 0, got {args.limit}'
    return None


def fixations_for(width: int, height: int, grid: int) -> list[tuple[float, float]]:
    """The centre first, then the grid points other than the centre."""
    from .core.folder_recognition import grid_fixations
    centre = ((width - 1) / 2.0, (height - 1) / 2.0)
    rest = [f for f in grid_fixations(width, height, grid) if grid > 1 and
            math.hypot(f[0] - centre[0], f[1] - centre[1]) > 1e-6]
    return [centre] + rest


def summarise(ranks: np.ndarray, f0s: list[float], two: bool) -> dict:
    """ranks (images, settings, fixations, 2) -> errors per setting, centred / off-centre."""
    from .core.folder_recognition import top_errors
    rows = []
    for s, f0 in enumerate(list(f0s) + [None]):
        row: dict = {'f0_px': f0 if f0 is not None else 'unfoveated'}
        parts = [('centred', slice(0, 1))]
        if ranks.shape[2] > 1 and f0 is not None:
            parts.append(('off_centre', slice(1, None)))
        for name, sl in parts:
            row[name] = {'pass1': top_errors(ranks[:, s, sl, 0])}
            if two:
                row[name]['pass2'] = top_errors(ranks[:, s, sl, 1])
        rows.append(row)
    return {'by_f0': rows}


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    problem = _check(args)
    if problem:
        return fail(PROG, problem)
    import cv2
    import torch

    from .core.folder_recognition import (
        FolderError,
        Foveators,
        evaluate_image,
        fit,
        load_folder,
        read_rgb,
    )
    from .core.recognition import Classifier, ModelError

    torch.set_num_threads(args.threads)
    cv2.setNumThreads(1)
    labels = args.labels or args.model.with_suffix('.labels')
    if not args.model.is_file():
        return fail(PROG, f'{args.model}: model file does not exist')
    if not Path(labels).is_file():
        return fail(PROG, f'{labels}: labels file does not exist (give --labels)')
    try:
        clf = Classifier(args.model, labels)
    except ModelError as exc:
        return fail(PROG, str(exc))
    try:
        items = load_folder(args.folder, clf.labels, args.csv)
    except FolderError as exc:
        hint = ''
        if args.model == DEFAULT_MODEL and 'none of the model' in str(exc):
            # the default is the simulator's network: ImageNet photos need an ImageNet model
            hint = ('; the default model is the simulator\'s: for ImageNet photos run '
                    '`python -m foveation_node.export_imagenet_classifier --out models/ lite0` '
                    'and give --model models/efficientnet_lite0.pt')
        return fail(PROG, str(exc) + hint)
    if args.limit:
        items = items[:args.limit]
    fovs = Foveators(args.levels)
    size = args.size or None
    passes = 2 if args.two_pass else 1
    per_image, all_ranks = [], []
    t0 = time.process_time()
    for item in items:
        try:
            rgb, _ = fit(read_rgb(item.path), size)
            h, w = rgb.shape[:2]
            if min(w, h) < 2 ** args.levels:
                raise FolderError(f'{item.path}: {w}x{h} px is too small for {args.levels} '
                                  f'levels (needs >= {2 ** args.levels} px)')
            res = evaluate_image(clf, rgb, item.label, args.f0, passes=passes, fovs=fovs,
                                 top_k=args.top_k, threshold=args.threshold,
                                 fixations=fixations_for(w, h, args.grid))
        except (FolderError, ValueError) as exc:
            return fail(PROG, str(exc) if str(item.path) in str(exc) else f'{item.path}: {exc}')
        all_ranks.append(res.ranks)
        per_image.append({'file': str(item.path), 'label': clf.labels[item.label],
                          'unfoveated_top5': [clf.labels[c] for c in res.predicted],
                          'ranks': res.ranks.tolist()})
    ranks = np.stack(all_ranks)
    summary = {'images': len(items), 'model': str(args.model), 'classes': clf.num_classes,
               'size_px': size, 'levels': args.levels, 'grid': args.grid,
               'fixations': int(ranks.shape[2]),
               'passes': passes, 'top_k': args.top_k, 'threshold': args.threshold,
               **summarise(ranks, args.f0, passes == 2),
               'cpu_s': round(time.process_time() - t0, 2)}
    for row in summary['by_f0']:
        text = []
        for name in ('centred', 'off_centre'):
            if name in row:
                for p, e in row[name].items():
                    text.append(f'{name} {p} top-1 {e["top1_error"]:.3f} top-5 '
                                f'{e["top5_error"]:.3f}')
        print(f'f0 {row["f0_px"]!s:>10}: ' + '; '.join(text) + ' (error)')
    if args.json is not None:
        try:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps({'summary': summary, 'images': per_image},
                                            allow_nan=False) + '\n')
        except OSError as exc:
            return fail(PROG, f'{args.json}: cannot write: {exc}')
    print(json.dumps(summary, allow_nan=False))
    return 0


if __name__ == '__main__':
    sys.exit(main())
