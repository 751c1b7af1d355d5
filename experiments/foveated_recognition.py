#!/usr/bin/env python3
"""Thesis Figs. 2.7-2.9 in our setting: foveated recognition, first pass vs second pass.

Held-out single-object views rendered by the simulator (core.object_views, a seed used neither
for training nor for the training's held-out set): 640x480 left-eye images, each object
anywhere in the image except the outer 8 % (off-centre). For every view, fovea size f_0 and
initial fixation, `two_pass` (Fig. 2.5) foveates the image at the fixation (K = 5, sigma_1 =
sqrt(8/3), the node's settings), classifies it with the packaged CNN (pass 1), localises its
top-5 classes by gradient saliency (th = 0.7), re-foveates at each box centre and re-classifies
(pass 2, best non-repeated labels).

Initial fixations: the image centre ("centred") and a grid over the image (the thesis: an 8x8
grid; here 4 columns x 3 rows, plus the centre), so most initial fixations are away from the
object, as in Fig. 2.8. f_0 in {15, 30, 60, 100, 160, 250} px of the 640-px image, plus the
unfoveated image (the thesis's baseline f_0 = 227 = its image size).

Reported: top-1 / top-2 / top-5 error of pass 1 and pass 2 against f_0 (Fig. 2.7a, 2.9), for
centred and non-centred fixations; error against the initial fixation (Fig. 2.8, as a grid and
against the distance from the object); localisation error (no top-5 box with IoU >= 0.5 with
the true box) against th (Fig. 2.7b / 2.10a), at f_0 = 100 with a centred fixation. With 7
classes, top-5 is loose (5 of 7 labels); top-1 is the figure to read.

Writes experiments/results/foveated_recognition.json, foveated_recognition.png (error vs f_0,
error vs fixation, localisation vs th) and foveated_recognition_example.png (Fig. 2.5 on one
view, f_0 = 60).

    .venv/bin/python experiments/foveated_recognition.py [--per-class 8] [--quick]
    .venv/bin/python experiments/foveated_recognition.py --tabletop [--seeds 20] [--poses 4]

--tabletop (only that part; also run by the full experiment): recognition where the node runs,
the cluttered tabletop scene (`tabletop_accuracy`, core.tabletop_views): left-eye 640x480
renders of tabletop(seed) for seeds not used in training, the demo's head pose plus random
ones, two-pass recognition (f_0 = 100, the node's default) from the image centre and from
random fixations. A case is right when the final best label (pass 2's first) is the class of
the object under its saliency box's centre (of the unoccluded objects whose box holds that
point, the nearest; else the nearest). A case where pass 2 reports nothing (a model with the
background class rejected every candidate) is wrong; its fraction is no_detection. Chance: 1/7,
and always answering the commonest class of the objects picked. Writes
foveated_recognition_tabletop.json.

--images DIR --models A.pt B.pt ... (only that part): Figs. 2.7-2.10 on real photographs with
any TorchScript classifiers (e.g. the EfficientNet-Lite ImageNet networks written by
export_imagenet_classifier standing in for the thesis's CaffeNet / GoogLeNet / VGG). Folder
formats as recognize_folder's (a labels.csv, sub-folders per label, or `<label>[_x].<ext>`
names such as ImageNet's `<wnid>_<name>.JPEG`). Each photo is squashed to 227 x 227 px (the
thesis's network input; f0 in px of it) and foveated (K = 5, sigma_1 = sqrt(8/3)):

- error vs f0 per network, centred fixation, pass 1 (Figs. 2.7a, 2.9): f0 in {10, 25, 50, 70,
  100, 150} and unfoveated, all images;
- two passes (Fig. 2.5, th = 0.7, top-5) with each network (--pass2-models, default all) from
  the centre and the 8 other points of a 3 x 3 grid, f0 in {25, 50, 100}, every n-th image
  (--pass2-images 60; the same images, fixations and f0s for every network): second-pass gain
  centred / off-centre (Fig. 2.9), error per initial fixation (Fig. 2.8). JSON:
  second_pass_by_network {network: section}; second_pass = the first network's section (the
  key other code reads). --pass2-only computes only this part for the networks missing from
  the existing <name>.json (or --pass2-models) and merges it in (and redraws the plot);
- localisation vs th (Figs. 2.7b, 2.10a; f0 = 70, pass 1, centred and one off-centre grid point
  per image): the photographs carry no boxes, so each photo is pasted (a square of 0.5-0.7 of
  the side, random place) on another photo of the folder, and the true box is the pasted
  photo's extent; correct when any top-5 saliency box has IoU >= 0.5 with it;
- localisation vs f0 (Fig. 2.10b; th = 0.7, pass 1, the same collages and fixations): for each
  f0 of the error-vs-f0 list and unfoveated. --loc-vs-f0-only computes only this part and
  merges it into the existing <name>.json (and redraws the plot).

Work runs in --jobs worker processes (1 torch thread each). Writes <out>/<name>.json and .png
(name: foveated_recognition_imagenet), and with --example-only the Fig. 2.5 example
<name>_example.png (first network, f0 = 50, from the top-left grid point).

    export_imagenet_classifier --classes DIR/classes.txt --out /tmp/imagenet lite0 lite1 lite2
    .venv/bin/python experiments/foveated_recognition.py --images DIR \
        --models /tmp/imagenet/efficientnet_lite{0,1,2}.pt [--quick] [--loc-vs-f0-only] \
        [--pass2-only] [--pass2-models 1 2]
    .venv/bin/python experiments/foveated_recognition.py --images DIR --plot-only
"""

from __future__ import annotations

import os

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'foveation_node'))
from protocol import cpu_seconds, protocol  # noqa: E402

from foveation_node.core.foveation import Foveator  # noqa: E402
from foveation_node.core.recognition import Classifier, saliency_box, two_pass  # noqa: E402

MODELS = ROOT / 'src' / 'foveation_node' / 'foveation_node' / 'models'
W, H, LEVELS = 640, 480, 5
F0S = (15.0, 30.0, 60.0, 100.0, 160.0, 250.0)
GRID_U = tuple(W * (2 * i + 1) / 8 for i in range(4))       # 80, 240, 400, 560
GRID_V = tuple(H * (2 * j + 1) / 6 for j in range(3))       # 80, 240, 400
CENTRE = ((W - 1) / 2, (H - 1) / 2)
THRESHOLDS = tuple(np.round(np.arange(0.1, 0.96, 0.05), 2))
DIST_BINS = (0, 100, 200, 300, 400, 800)
EXAMPLE_F0 = 60.0
THESIS = {'max_second_pass_gain_non_centred': 0.43, 'max_second_pass_gain_centred': 0.10,
          'classification_error_saturates_at_f0': 70, 'best_threshold': (0.65, 0.7)}


def iou(a: tuple[int, ...], b: tuple[int, ...]) -> float:
    ix = max(0, min(a[2], b[2]) - max(a[0], b[0]) + 1)
    iy = max(0, min(a[3], b[3]) - max(a[1], b[1]) + 1)
    inter = ix * iy
    area = lambda r: (r[2] - r[0] + 1) * (r[3] - r[1] + 1)  # noqa: E731
    return inter / float(area(a) + area(b) - inter)


def rank_of(true: int, ranking: list[int]) -> int:
    """0-based position of the true class in a ranking (len(ranking) if absent)."""
    return ranking.index(true) if true in ranking else len(ranking)


THESIS_IMAGES = 50000      # ILSVRC 2012, "a total of 50K test images" (section 2.4.2)
THESIS_NETWORKS = 'CaffeNet, GoogLeNet, VGGNet (Caffe Model Zoo)'


def protocol_views(result: dict, cpu_s: float | None = None) -> dict:
    """Protocol of foveated_recognition.json (simulated single-object views)."""
    return protocol(
        data=f"{result['views']} held-out simulated single-object views ({result['per_class']} "
             f"per class, {len(result['classes'])} classes), 640x480, off-centre objects",
        repetitions=result['views'], thesis_repetitions=THESIS_IMAGES,
        models=f"the packaged foveation CNN ({len(result['classes'])} classes, trained on "
               'simulated views)',
        differs_from_thesis=[
            f"{len(result['classes'])} simulated object classes instead of ILSVRC 2012's 1000 "
            'photograph classes', f'one small CNN instead of {THESIS_NETWORKS}',
            'initial fixations on a 4x3 grid plus the centre (thesis: 8x8)'],
        cpu_s=cpu_s)


def protocol_tabletop(res: dict, cpu_s: float | None = None) -> dict:
    """Protocol of foveated_recognition_tabletop.json (no thesis counterpart)."""
    return protocol(
        data=f"{res['views']} left-eye renders of tabletop scenes (seeds {res['seeds'][0]}.."
             f"{res['seeds'][1]}, {res['poses_per_scene']} head poses each), {res['cases']} "
             'two-pass cases', repetitions=res['cases'], thesis_repetitions=None,
        models=f"the packaged foveation CNN ({res['model']})",
        differs_from_thesis=['no thesis counterpart: recognition in the cluttered scene where '
                             'the node runs'], cpu_s=cpu_s)


def protocol_folder(result: dict, cpu_s: float | None = None) -> dict:
    """Protocol of a --images run (real photographs, e.g. foveated_recognition_imagenet.json)."""
    names = ', '.join(n['name'] for n in result['networks'])
    sp, loc = result['second_pass'], result['localisation']
    p2 = list(second_pass_networks(result))
    count = {1: 'one', 2: 'two', 3: 'three'}.get(len(p2), str(len(p2)))
    nets = f"network{'s' if len(p2) > 1 else ''} ({', '.join(p2)})"
    repetitions = {'error vs f0': result['images'], 'two passes': sp['images'],
                   'localisation': loc['images']}
    if 'localisation_vs_f0' in result:
        repetitions['localisation vs f0'] = result['localisation_vs_f0']['images']
    return protocol(
        data=f"{result['images']} labelled photographs ({result['folder']}), squashed to "
             f"{result['size_px']} px",
        repetitions=repetitions,
        thesis_repetitions={k: THESIS_IMAGES for k in repetitions},
        models=f'ImageNet classifiers {names} (TorchScript) standing in for {THESIS_NETWORKS}',
        differs_from_thesis=[
            f"{result['images']} photographs instead of ILSVRC 2012's 50000",
            f'networks {names} instead of {THESIS_NETWORKS}',
            f"second pass on {sp['images']} images with a {sp['grid']} grid of initial "
            f'fixations (thesis: 8x8) and {count} {nets}',
            'localisation on collages (the photographs carry no boxes; thesis: ILSVRC boxes)'],
        cpu_s=cpu_s)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--per-class', type=int, default=8, help='test views per class')
    parser.add_argument('--seed', type=int, default=3000)
    parser.add_argument('--quick', action='store_true', help='1 view per class, 3 f0 values')
    parser.add_argument('--model', type=Path, default=MODELS / 'foveation_cnn.pt')
    parser.add_argument('--labels', type=Path, default=MODELS / 'foveation_cnn.labels')
    parser.add_argument('--out', type=Path, default=ROOT / 'experiments' / 'results')
    parser.add_argument('--example-only', action='store_true',
                        help='only the Fig. 2.5 example (f0 = 60) of the same views')
    parser.add_argument('--tabletop', action='store_true', help='only the tabletop part')
    parser.add_argument('--seeds', type=int, default=20, help='tabletop scenes (--tabletop)')
    parser.add_argument('--poses', type=int, default=4, help='head poses per tabletop scene')
    folder = parser.add_argument_group(
        'real photographs (--images): Figs. 2.7-2.10 with any TorchScript classifiers')
    folder.add_argument('--images', type=Path, default=None,
                        help='a folder of labelled images (formats: recognize_folder --help); '
                             'runs only this part')
    folder.add_argument('--models', type=Path, nargs='+', default=None,
                        help='TorchScript classifiers (labels: <model>.labels; preprocessing: '
                             '<model>.json), e.g. from export_imagenet_classifier')
    folder.add_argument('--csv', type=Path, default=None, help='file,label rows (optional)')
    folder.add_argument('--size', type=int, default=227, help='images squashed to SIZE px')
    folder.add_argument('--f0s', type=float, nargs='+', default=list(FOLDER_F0S))
    folder.add_argument('--pass2-f0s', type=float, nargs='+', default=list(FOLDER_PASS2_F0S))
    folder.add_argument('--grid', type=int, default=3, help='N x N initial fixations (pass 2)')
    folder.add_argument('--pass2-images', type=int, default=60,
                        help='images for the two-pass grid (every n-th of the folder)')
    folder.add_argument('--pass2-models', type=int, nargs='+', default=None,
                        help='which of --models run the two-pass grid (indices; default: all; '
                             'the first also fills the legacy second_pass key and the example)')
    folder.add_argument('--pass2-only', action='store_true',
                        help='compute only the two-pass grid of --pass2-models (default: the '
                             'networks missing from <name>.json) and merge it into that JSON')
    folder.add_argument('--loc-images', type=int, default=60,
                        help='photos pasted on a canvas for localisation vs th')
    folder.add_argument('--loc-vs-f0-only', action='store_true',
                        help='compute only localisation vs f0 (Fig. 2.10b) and merge it into '
                             'the existing <name>.json')
    folder.add_argument('--jobs', type=int, default=2, help='worker processes (1 thread each)')
    folder.add_argument('--name', default='foveated_recognition_imagenet',
                        help='output stem under --out')
    parser.add_argument('--plot-only', action='store_true',
                        help='redraw foveated_recognition[_quick].png from its JSON (with '
                             '--images: <name>[_quick].png)')
    args = parser.parse_args()
    if args.plot_only and args.images is not None:
        stem = args.name + ('_quick' if args.quick else '')
        result = json.loads((args.out / f'{stem}.json').read_text())
        plot_folder(result, folder_grid(result), args.out / f'{stem}.png')
        return 0
    if args.plot_only:
        stem = 'foveated_recognition_quick' if args.quick else 'foveated_recognition'
        plot(json.loads((args.out / f'{stem}.json').read_text()), args.out / f'{stem}.png')
        return 0
    if args.images is not None:
        return run_folder(args)
    if args.tabletop:
        return run_tabletop(args)

    import torch
    from tqdm import tqdm

    from foveation_node.training.object_views import CLASSES, ObjectViews

    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    per_class = 1 if args.quick else args.per_class
    f0s = (30.0, 100.0, 250.0) if args.quick else F0S
    clf = Classifier(args.model, args.labels)
    assert clf.labels[:len(CLASSES)] == list(CLASSES), (clf.labels, CLASSES)   # + background
    t0 = time.perf_counter()
    with ObjectViews(W, H, seed=args.seed) as ov:
        views = ov.dataset(per_class * len(CLASSES), seed=args.seed)
    if args.example_only:
        example(clf, views, Foveator(W, H, LEVELS, EXAMPLE_F0),
                args.out / 'foveated_recognition_example.png')
        return 0
    fixations = [CENTRE] + [(u, v) for v in GRID_V for u in GRID_U]
    foveators = {f0: Foveator(W, H, LEVELS, f0) for f0 in f0s}
    identity = lambda img, fix: img  # noqa: E731  (uniform resolution: the baseline)

    # rank of the true class: [view, f0 (last = unfoveated), fixation, pass]
    settings = list(f0s) + [None]
    ranks = np.zeros((len(views), len(settings), len(fixations), 2), int)
    located = np.zeros((len(views), len(settings), len(fixations), 2), bool)
    cases = [(i, s, j) for i in range(len(views)) for s in range(len(settings))
             for j in range(len(fixations)) if settings[s] is not None or j == 0]
    for i, s, j in tqdm(cases, desc='two passes', unit='case'):
        view = views[i]
        f0 = settings[s]
        fov = identity if f0 is None else foveators[f0].foveate
        res = two_pass(clf, view.rgb, fixations[j], fov, top_k=5, threshold=0.7)
        first = list(np.argsort(-res.probs_first)[:5])
        second = [d.class_id for d in res.second]
        ranks[i, s, j] = rank_of(view.label, first), rank_of(view.label, second)
        located[i, s, j] = (any(iou(d.box, view.box) >= 0.5 for d in res.first),
                            any(iou(d.box, view.box) >= 0.5 for d in res.second))
        if f0 is None:                       # no fovea: every fixation gives the same result
            ranks[i, s, :] = ranks[i, s, 0]
            located[i, s, :] = located[i, s, 0]

    def error(sel: np.ndarray, k: int) -> float:
        return float((sel >= k).mean())

    result: dict = {'views': len(views), 'per_class': per_class, 'classes': list(CLASSES),
                    'f0_px': list(f0s), 'fixations_px': [list(map(float, f)) for f in fixations],
                    'image': [W, H], 'levels': LEVELS, 'threshold': 0.7, 'top_k': 5,
                    'by_f0': [], 'thesis': THESIS}
    for s, f0 in enumerate(settings):
        row = {'f0_px': 'unfoveated' if f0 is None else f0}
        for name, sl in (('centred', slice(0, 1)), ('non_centred', slice(1, None))):
            for p, pname in ((0, 'pass1'), (1, 'pass2')):
                r = ranks[:, s, sl, p]
                for k in (1, 2, 5):
                    row[f'{name}_{pname}_top{k}_error'] = error(r, k)
                row[f'{name}_{pname}_localisation_error'] = float(1 - located[:, s, sl, p].mean())
        result['by_f0'].append(row)
    foveated = [r for r in result['by_f0'] if r['f0_px'] != 'unfoveated']

    def gain(r: dict, name: str) -> float:
        return r[f'{name}_pass1_top1_error'] - r[f'{name}_pass2_top1_error']

    where = ('centred', 'non_centred')
    result['max_second_pass_gain_top1'] = {
        name: max((gain(r, name), r['f0_px']) for r in foveated) for name in where}
    result['mean_second_pass_gain_top1'] = {
        name: float(np.mean([gain(r, name) for r in foveated])) for name in where}

    # error against the initial fixation (Fig. 2.8): over all f0 (foveated settings only)
    fo = slice(0, len(f0s))
    grid = {p: (ranks[:, fo, 1:, i] >= 1).mean(axis=(0, 1)).reshape(len(GRID_V), len(GRID_U))
            for i, p in enumerate(('pass1', 'pass2'))}
    result['grid_top1_error'] = {p: g.round(4).tolist() for p, g in grid.items()}
    dist = np.array([[np.hypot(f[0] - v.centre[0], f[1] - v.centre[1]) for f in fixations]
                     for v in views])                                    # (views, fixations)
    by_dist = []
    for lo, hi in zip(DIST_BINS[:-1], DIST_BINS[1:], strict=True):
        sel = (dist >= lo) & (dist < hi)                                  # (views, fixations)
        if not sel.any():
            continue
        r = ranks[:, fo]                                                  # (views, f0, fix, 2)
        m = np.broadcast_to(sel[:, None, :], r.shape[:3])
        by_dist.append({'distance_px': [lo, hi], 'cases': int(m.sum()),
                        'pass1_top1_error': float((r[..., 0][m] >= 1).mean()),
                        'pass2_top1_error': float((r[..., 1][m] >= 1).mean())})
    result['by_distance_top1'] = by_dist

    # localisation error against th (Fig. 2.7b / 2.10a): f0 = 100, centred, pass-1 top-5 maps
    loc_f0 = 100.0 if 100.0 in foveators else f0s[len(f0s) // 2]
    loc_hits = np.zeros((len(views), len(THRESHOLDS)), bool)
    for i, view in enumerate(tqdm(views, desc='thresholds', unit='view')):
        img = foveators[loc_f0].foveate(view.rgb, CENTRE)
        top = list(np.argsort(-clf.classify(img)[0])[:5])
        maps = clf.saliency(img, top)
        for t, th in enumerate(THRESHOLDS):
            boxes = [clf.box_to_image(saliency_box(m, th), W, H) for m in maps]
            loc_hits[i, t] = any(iou(b, view.box) >= 0.5 for b in boxes)
    result['localisation_vs_threshold'] = {
        'f0_px': loc_f0, 'thresholds': [float(t) for t in THRESHOLDS],
        'error': [float(1 - loc_hits[:, t].mean()) for t in range(len(THRESHOLDS))]}
    result['seconds'] = round(time.perf_counter() - t0, 1)

    args.out.mkdir(parents=True, exist_ok=True)
    stem = 'foveated_recognition_quick' if args.quick else 'foveated_recognition'
    plot(result, args.out / f'{stem}.png')
    example(clf, views, Foveator(W, H, LEVELS, EXAMPLE_F0), args.out / f'{stem}_example.png')
    result['protocol'] = protocol_views(result, cpu_seconds())
    (args.out / f'{stem}.json').write_text(json.dumps(rounded(result), indent=1) + '\n')
    if not args.quick:
        run_tabletop(args)

    base = result['by_f0'][-1]
    print(f'{len(views)} views, {len(cases)} two-pass cases in {result["seconds"]:.0f} s')
    print('top-1 error, pass 1 -> pass 2 (centred | non-centred):')
    for r in result['by_f0']:
        print(f'  f0 {r["f0_px"]!s:>10}: {r["centred_pass1_top1_error"]:.3f} -> '
              f'{r["centred_pass2_top1_error"]:.3f} | {r["non_centred_pass1_top1_error"]:.3f} -> '
              f'{r["non_centred_pass2_top1_error"]:.3f}')
    print(f'unfoveated top-1 error {base["centred_pass1_top1_error"]:.3f}; max top-1 gain of pass '
          f'2: centred {result["max_second_pass_gain_top1"]["centred"]}, non-centred '
          f'{result["max_second_pass_gain_top1"]["non_centred"]} (thesis: 0.10, 0.43)')
    print(json.dumps({'non_centred_max_gain': result['max_second_pass_gain_top1']['non_centred'][0],
                      'centred_max_gain': result['max_second_pass_gain_top1']['centred'][0],
                      'unfoveated_top1_error': base['centred_pass1_top1_error']}))
    return 0


TABLETOP_SEED0 = 500             # training uses seeds >= 10000 (train_classifier.TABLETOP_SEED0)
TABLETOP_FIXATIONS = 4           # random initial fixations per view, besides the centre


def tabletop_accuracy(clf: Classifier, seeds: int = 20, poses: int = 4, f0: float = 100.0,
                      seed0: int = TABLETOP_SEED0) -> dict:
    """Two-pass recognition on rendered tabletop views (see the module docstring, --tabletop).

    Poses per scene: the demo's start (DEFAULT_JOINTS) and poses - 1 random ones. Fixations: the
    image centre and TABLETOP_FIXATIONS uniform ones. Returns accuracies (final label = class of
    the object under its box; pass 1's best label judged the same way; final label = class of
    any visible object), chance levels and the histograms of final labels and true classes.
    """
    from tqdm import tqdm

    from foveation_node.training.object_views import CLASSES
    from foveation_node.training.tabletop_views import (
        DEFAULT_JOINTS,
        TabletopViews,
        object_at,
        random_joints,
    )

    rng = np.random.default_rng(seed0)
    foveator = Foveator(W, H, LEVELS, f0)
    # (centred, final right, pass-1 right, final in scene, final, true class, no detection);
    # no pass-2 detection (the reject class won everywhere): final = -1, wrong
    rows = []
    n_views = 0
    with TabletopViews(W, H) as tv:
        for s in tqdm(range(seed0, seed0 + seeds), desc='tabletop scenes', unit='scene'):
            for p in range(poses):
                joints = DEFAULT_JOINTS if p == 0 else random_joints(rng)
                try:
                    view = tv.view(s, joints)
                except RuntimeError:
                    break                                 # the scene builder gave up on it
                if not any(o.visible for o in view.objects):
                    continue
                n_views += 1
                present = {o.label for o in view.objects if o.visible}
                fixations = [CENTRE] + [(float(rng.uniform(0, W - 1)), float(rng.uniform(0, H - 1)))
                                        for _ in range(TABLETOP_FIXATIONS)]
                for j, fix in enumerate(fixations):
                    res = two_pass(clf, view.rgb, fix, foveator.foveate, top_k=5, threshold=0.7)
                    first = res.first[0]
                    best = res.second[0] if res.second else first       # its box: the truth
                    truth = object_at(view.objects, *best.centre)
                    truth1 = object_at(view.objects, *first.centre)
                    found = bool(res.second)
                    rows.append((j == 0, found and best.class_id == truth.label,
                                 first.class_id == truth1.label,
                                 found and best.class_id in present,
                                 best.class_id if found else -1, truth.label, not found))
    r = np.array(rows, int)
    centred = r[:, 0] == 1
    true_hist = np.bincount(r[:, 5], minlength=len(CLASSES))
    out = {'scenes': seeds, 'poses_per_scene': poses, 'views': n_views, 'cases': len(r),
           'f0_px': f0, 'seeds': [seed0, seed0 + seeds - 1],
           'fixations': f'image centre + {TABLETOP_FIXATIONS} uniform random per view',
           'final_accuracy': float(r[:, 1].mean()),
           'final_accuracy_centred': float(r[centred, 1].mean()),
           'final_accuracy_random_fixation': float(r[~centred, 1].mean()),
           'pass1_accuracy': float(r[:, 2].mean()),
           'final_label_in_scene': float(r[:, 3].mean()),
           'no_detection': float(r[:, 6].mean()),
           'chance_uniform': 1.0 / len(CLASSES),
           'chance_commonest_class': float(true_hist.max() / len(r)),
           'final_labels': {c: int(n) for c, n in
                            zip(CLASSES, np.bincount(r[r[:, 4] >= 0, 4], minlength=len(CLASSES)),
                                strict=True)},
           'true_classes': {c: int(n) for c, n in zip(CLASSES, true_hist, strict=True)}}
    per_class = {}
    for i, c in enumerate(CLASSES):
        sel = r[:, 5] == i
        if sel.any():
            per_class[c] = float(r[sel, 1].mean())
    out['final_accuracy_per_true_class'] = per_class
    return out


def run_tabletop(args: argparse.Namespace) -> int:
    import torch

    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    clf = Classifier(args.model, args.labels)
    t0, cpu0 = time.perf_counter(), cpu_seconds()      # this part only, when run after others
    res = tabletop_accuracy(clf, args.seeds, args.poses)
    res['model'] = str(Path(args.model).resolve().relative_to(ROOT)) \
        if Path(args.model).resolve().is_relative_to(ROOT) else str(args.model)
    res['seconds'] = round(time.perf_counter() - t0, 1)
    args.out.mkdir(parents=True, exist_ok=True)
    res['protocol'] = protocol_tabletop(res, cpu_seconds() - cpu0)
    (args.out / 'foveated_recognition_tabletop.json').write_text(
        json.dumps(rounded(res), indent=1) + '\n')
    print(f'tabletop: {res["views"]} views, {res["cases"]} two-pass cases in '
          f'{res["seconds"]:.0f} s')
    print(f'final label = class under its box: {res["final_accuracy"]:.3f} (centred '
          f'{res["final_accuracy_centred"]:.3f}, random fixation '
          f'{res["final_accuracy_random_fixation"]:.3f}); pass 1 {res["pass1_accuracy"]:.3f}; '
          f'chance {res["chance_uniform"]:.3f} / commonest class '
          f'{res["chance_commonest_class"]:.3f}')
    print(f'final labels {res["final_labels"]}; true classes {res["true_classes"]}; no '
          f'detection {res["no_detection"]:.3f}')
    print(json.dumps({'tabletop_final_accuracy': res['final_accuracy'],
                      'tabletop_pass1_accuracy': res['pass1_accuracy'],
                      'chance_commonest_class': res['chance_commonest_class']}))
    return 0


# ------------------------------------------------------------------------------------------
# Real photographs (--images): Figs. 2.7-2.10 with any TorchScript classifiers

FOLDER_F0S = (10.0, 25.0, 50.0, 70.0, 100.0, 150.0)     # px of the 227-px image (the thesis's)
FOLDER_PASS2_F0S = (25.0, 50.0, 100.0)
LOC_F0 = 70.0                                           # Fig. 2.10a
LOC_SCALE = (0.5, 0.7)                                  # pasted photo side / canvas side
LOC_TH = 0.7                                            # Fig. 2.10b: localisation vs f0
_WORKER: dict = {}


def _worker_init(models: list[str]) -> None:
    import torch

    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    from foveation_node.core.folder_recognition import Foveators

    _WORKER['clfs'] = [Classifier(m, Path(m).with_suffix('.labels')) for m in models]
    _WORKER['fovs'] = Foveators(LEVELS)


def _folder_task(task: tuple) -> tuple:
    """One unit of work in a worker: ('pass1' | 'pass2' | 'loc', network, image index, ...)."""
    from foveation_node.core.folder_recognition import (
        evaluate_image,
        fit,
        localisation_hits,
        paste,
        read_rgb,
    )

    kind, net, idx, path, label, opts = task
    clf, fovs = _WORKER['clfs'][net], _WORKER['fovs']
    t0 = time.process_time()
    size = opts['size']
    if kind in ('loc', 'locf0'):
        rng = np.random.default_rng(1000 + idx)      # the same collage for both kinds
        scene, box = paste(read_rgb(path), size, float(rng.uniform(*LOC_SCALE)), rng,
                           background=read_rgb(opts['backgrounds'][idx]))
        centre = ((size - 1) / 2, (size - 1) / 2)
        off = opts['off_centre'][idx % len(opts['off_centre'])]
        if kind == 'loc':
            out = np.stack([localisation_hits(clf, scene, box, LOC_F0, centre,
                                              opts['thresholds'], fovs),
                            localisation_hits(clf, scene, box, LOC_F0, off, opts['thresholds'],
                                              fovs)])
        else:        # [fixation (centred, off-centre), setting (f0s, then unfoveated)] at LOC_TH
            settings = [*opts['f0s'], None]
            out = np.zeros((2, len(settings)), bool)
            for s, f0 in enumerate(settings):
                out[0, s] = localisation_hits(clf, scene, box, f0, centre, [LOC_TH], fovs)[0]
                # unfoveated: the fixation plays no part, one forward / backward serves both
                out[1, s] = out[0, s] if f0 is None else localisation_hits(
                    clf, scene, box, f0, off, [LOC_TH], fovs)[0]
    else:
        rgb, _ = fit(read_rgb(path), size)
        centre = ((size - 1) / 2, (size - 1) / 2)
        if kind == 'pass1':
            out = evaluate_image(clf, rgb, label, opts['f0s'], passes=1, fovs=fovs,
                                 fixations=[centre]).ranks
        else:
            out = evaluate_image(clf, rgb, label, opts['pass2_f0s'], passes=2, fovs=fovs,
                                 fixations=opts['fixations']).ranks
    return kind, net, idx, out, time.process_time() - t0


def run_folder(args: argparse.Namespace) -> int:
    """Figs. 2.7-2.10 on a folder of labelled photographs with the classifiers of --models."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    import torch

    from foveation_node.core.folder_recognition import FolderError, grid_fixations, load_folder
    from foveation_node.core.recognition import ModelError

    torch.set_num_threads(1)
    if not args.models:
        print('foveated_recognition: --images needs --models', file=sys.stderr)
        return 2
    try:
        clfs = [Classifier(m, Path(m).with_suffix('.labels')) for m in args.models]
        labels = clfs[0].labels
        for m, c in zip(args.models, clfs, strict=True):
            if c.labels != labels:
                raise ModelError(f'{m.with_suffix(".labels")}: labels differ from '
                                 f'{args.models[0].with_suffix(".labels")}')
        items = load_folder(args.images, labels, args.csv)
    except (ModelError, FolderError) as exc:
        print(f'foveated_recognition: {exc}', file=sys.stderr)
        return 2
    names = [m.stem.replace('efficientnet_', '') for m in args.models]
    if args.example_only:
        args.out.mkdir(parents=True, exist_ok=True)
        folder_example(clfs[(args.pass2_models or [0])[0]], items, args.size,
                       args.out / f'{args.name}_example.png')
        return 0
    info = [{'name': n, 'model': m.name, 'input_size': list(c.preprocessing.input_size)}
            for n, m, c in zip(names, args.models, clfs, strict=True)]
    del clfs
    size = args.size
    if args.quick:
        items = items[::10]
        args.pass2_images = min(args.pass2_images, 10)
        args.loc_images = min(args.loc_images, 10)
    f0s, f0s2 = list(args.f0s), list(args.pass2_f0s)
    centre = ((size - 1) / 2, (size - 1) / 2)
    grid = grid_fixations(size, size, args.grid)
    off = [f for f in grid if np.hypot(f[0] - centre[0], f[1] - centre[1]) > 1e-6]
    fixations = [centre] + off
    thresholds = [float(t) for t in THRESHOLDS]
    backgrounds = {i: str(items[(i + len(items) // 2) % len(items)].path)
                   for i in range(len(items))}
    opts = {'backgrounds': backgrounds, 'size': size, 'f0s': f0s, 'pass2_f0s': f0s2,
            'fixations': fixations,
            'off_centre': off, 'thresholds': thresholds}
    step2 = max(1, len(items) // max(1, args.pass2_images))
    pass2_idx = list(range(0, len(items), step2))[:args.pass2_images]
    steploc = max(1, len(items) // max(1, args.loc_images))
    loc_idx = list(range(0, len(items), steploc))[:args.loc_images]
    stem = args.name + ('_quick' if args.quick else '')
    path = args.out / f'{stem}.json'
    if args.loc_vs_f0_only and args.pass2_only:
        print('foveated_recognition: --loc-vs-f0-only and --pass2-only exclude each other',
              file=sys.stderr)
        return 2
    if args.pass2_only and args.pass2_models is None:       # the networks not yet in the JSON
        existing = read_existing(path, '--pass2-only')
        if existing is None:
            return 2
        have = set(second_pass_networks(existing))
        args.pass2_models = [n for n, name in enumerate(names) if name not in have]
        if not args.pass2_models:
            print(f'foveated_recognition: {path} already holds the second pass of every network '
                  f'({", ".join(names)}); nothing to compute')
            return 0
    p2s = list(range(len(names))) if args.pass2_models is None else list(args.pass2_models)
    if not p2s or len(set(p2s)) != len(p2s) or not all(0 <= n < len(names) for n in p2s):
        print(f'foveated_recognition: --pass2-models {p2s}: distinct indices of --models '
              f'(0..{len(names) - 1}) needed', file=sys.stderr)
        return 2
    tasks = []
    if not args.pass2_only:
        tasks += [('locf0', n, i, str(items[i].path), items[i].label, opts)
                  for n in range(len(names)) for i in loc_idx]
    if not (args.loc_vs_f0_only or args.pass2_only):
        tasks += [('pass1', n, i, str(items[i].path), items[i].label, opts)
                  for n in range(len(names)) for i in range(len(items))]
        tasks += [('loc', n, i, str(items[i].path), items[i].label, opts)
                  for n in range(len(names)) for i in loc_idx]
    if not args.loc_vs_f0_only:
        # the same images (every step2-th of the sorted folder), fixations and f0s for every
        # network: the selection depends only on the folder, --pass2-images and --grid
        tasks += [('pass2', n, i, str(items[i].path), items[i].label, opts)
                  for n in p2s for i in pass2_idx]
    r1 = np.zeros((len(names), len(items), len(f0s) + 1), int)
    r2 = {n: np.zeros((len(pass2_idx), len(f0s2) + 1, len(fixations), 2), int) for n in p2s}
    loc = np.zeros((len(names), len(loc_idx), 2, len(thresholds)), bool)
    locf0 = np.zeros((len(names), len(loc_idx), 2, len(f0s) + 1), bool)
    cpu = {'pass1': 0.0, **{f'pass2_{names[n]}': 0.0 for n in p2s}, 'loc': 0.0,
           'loc_vs_f0': 0.0}
    where2 = {i: k for k, i in enumerate(pass2_idx)}
    whereloc = {i: k for k, i in enumerate(loc_idx)}
    t0 = time.perf_counter()
    ctx = multiprocessing.get_context('spawn')
    from tqdm import tqdm
    with ProcessPoolExecutor(args.jobs, ctx, _worker_init, ([str(m) for m in args.models],)) as ex:
        for kind, net, idx, out, dt in tqdm(ex.map(_folder_task, tasks, chunksize=1),
                                            total=len(tasks), desc='tasks', unit='task'):
            cpu['loc_vs_f0' if kind == 'locf0' else
                f'pass2_{names[net]}' if kind == 'pass2' else kind] += dt
            if kind == 'pass1':
                r1[net, idx] = out[:, 0, 0]
            elif kind == 'pass2':
                r2[net][where2[idx]] = out
            elif kind == 'loc':
                loc[net, whereloc[idx]] = out
            else:
                locf0[net, whereloc[idx]] = out
    wall = time.perf_counter() - t0
    scene_text = (f'collage: each photo squashed to a square of side {LOC_SCALE[0]}-'
                  f'{LOC_SCALE[1]} x {size} px (uniform) at a uniform random place on another '
                  f'photo of the folder (half the folder away) squashed to {size}x{size}; the '
                  'true box is the pasted photo (the photographs carry no boxes)')
    criterion = 'any of the pass-1 top-5 saliency boxes with IoU >= 0.5'
    loc_vs_f0 = {
        'images': len(loc_idx), 'threshold': LOC_TH, 'f0_px': [*f0s, 'unfoveated'],
        'scene': scene_text + ' (the same collages as localisation)', 'criterion': criterion,
        'fixations': 'centred: the image centre; off_centre: the same 3x3-grid point per '
                     'collage as in localisation; unfoveated: the fixation plays no part '
                     '(off_centre = centred)',
        'error': {n: {'centred': (1 - locf0[i, :, 0].mean(0)).round(4).tolist(),
                      'off_centre': (1 - locf0[i, :, 1].mean(0)).round(4).tolist()}
                  for i, n in enumerate(names)},
        'wall_s': round(wall, 1) if args.loc_vs_f0_only else None}
    if args.loc_vs_f0_only:
        return merge_loc_vs_f0(path, loc_vs_f0, cpu['loc_vs_f0'], names, f0s)
    del loc_vs_f0['wall_s']
    by_net = {names[n]: second_pass_section(r2[n], names[n], grid, fixations, f0s2, args.grid)
              for n in p2s}
    if args.pass2_only:
        return merge_second_pass(path, by_net, {k: v for k, v in cpu.items()
                                                if k.startswith('pass2_')}, names, wall)
    err = _err
    settings = f0s + ['unfoveated']
    result: dict = {
        'images': len(items), 'folder': args.images.name, 'size_px': size, 'levels': LEVELS,
        'sigma_1_px': 'sqrt(8/3)', 'networks': info,
        'note': 'each photo squashed to size x size px (the thesis foveates its 227x227 network '
                'input), foveated (f0 in px of that square) and resized to each network\'s input',
        'error_vs_f0_centred_pass1': {
            n: [{'f0_px': f, 'top1_error': err(r1[i, :, s], 1), 'top5_error': err(r1[i, :, s], 5)}
                for s, f in enumerate(settings)] for i, n in enumerate(names)}}
    # second_pass: the first of --pass2-models (lite0 by default), as read by other code;
    # second_pass_by_network: the same structure for every network of --pass2-models
    result['second_pass'] = by_net[names[p2s[0]]]
    result['second_pass_by_network'] = by_net
    result['localisation'] = {
        'images': len(loc_idx), 'f0_px': LOC_F0, 'thresholds': thresholds,
        'scene': scene_text, 'criterion': criterion,
        'error': {n: {'centred': (1 - loc[i, :, 0].mean(0)).round(4).tolist(),
                      'off_centre': (1 - loc[i, :, 1].mean(0)).round(4).tolist()}
                  for i, n in enumerate(names)}}
    result['localisation_vs_f0'] = loc_vs_f0
    result['thesis'] = THESIS
    result['cpu_s'] = {k: round(v, 1) for k, v in cpu.items()}
    result['wall_s'] = round(wall, 1)
    result['jobs'] = args.jobs
    args.out.mkdir(parents=True, exist_ok=True)
    result['protocol'] = protocol_folder(result, sum(cpu.values()))
    write_folder_result(path, result)

    print(f'{len(items)} images, {len(tasks)} tasks in {wall:.0f} s wall, '
          f'CPU {sum(cpu.values()):.0f} s ({result["cpu_s"]})')
    for n, rowsn in result['error_vs_f0_centred_pass1'].items():
        print(f'{n}: top-1/top-5 error ' + ', '.join(
            f'{r["f0_px"]}: {r["top1_error"]:.3f}/{r["top5_error"]:.3f}' for r in rowsn))
    print_second_pass(by_net)
    best = {n: min(zip(v['centred'], thresholds, strict=True)) for n, v in
            result['localisation']['error'].items()}
    print(f'localisation (f0 {LOC_F0:g}, centred): best error, th = {best}')
    print_loc_vs_f0(loc_vs_f0)
    summary = {f'{n}_top1_error_unfoveated':
               result['error_vs_f0_centred_pass1'][n][-1]['top1_error'] for n in names}
    for n, sec in by_net.items():
        summary[f'{n}_max_gain_off_centre_points'] = max_gain(sec, 'off_centre')
        summary[f'{n}_max_gain_centred_points'] = max_gain(sec, 'centred')
    print(json.dumps(summary))
    return 0


def _err(r: np.ndarray, k: int) -> float:
    """top-k error: the fraction of true-class ranks >= k."""
    return float((r >= k).mean())


def second_pass_section(r2: np.ndarray, network: str, grid: list, fixations: list,
                        f0s2: list[float], n2: int) -> dict:
    """The second_pass object (Figs. 2.8 / 2.9) of one network from its ranks r2 [image,
    setting (f0s2, then unfoveated), fixation (centre first), pass]."""
    rows = []
    for s, f in enumerate(f0s2 + ['unfoveated']):
        row: dict = {'f0_px': f}
        for name, sl in (('centred', slice(0, 1)), ('off_centre', slice(1, None))):
            if f == 'unfoveated' and name == 'off_centre':
                continue
            rr = r2[:, s, sl]
            row[name] = {p: {'top1_error': _err(rr[..., i], 1),
                             'top5_error': _err(rr[..., i], 5)}
                         for i, p in enumerate(('pass1', 'pass2'))}
            row[name]['gain_top1_points'] = round(100 * (row[name]['pass1']['top1_error'] -
                                                         row[name]['pass2']['top1_error']), 2)
            row[name]['cases'] = int(rr[..., 0].size)
        rows.append(row)
    gridmap = {}
    for i, p in enumerate(('pass1', 'pass2')):
        g = np.zeros(len(grid))
        for j, f in enumerate(grid):
            k = fixations.index(f) if f in fixations else 0
            g[j] = (r2[:, :len(f0s2), k, i] >= 1).mean()
        gridmap[p] = g.reshape(n2, n2)
    return {
        'network': network, 'images': int(r2.shape[0]), 'grid': f'{n2}x{n2}',
        'fixations_px': [[round(u, 1), round(v, 1)] for u, v in fixations],
        'threshold': 0.7, 'top_k': 5, 'by_f0': rows,
        'grid_top1_error_over_f0s': {p: g.round(4).tolist() for p, g in gridmap.items()}}


def second_pass_networks(result: dict) -> dict[str, dict]:
    """The second-pass sections of a folder result by network (older results: only
    second_pass, one network)."""
    return result.get('second_pass_by_network') or {
        result['second_pass']['network']: result['second_pass']}


def max_gain(sec: dict, name: str) -> float:
    """The largest top-1 gain of pass 2 over pass 1 (points) over the f0s, centred or
    off_centre."""
    return max(r[name]['gain_top1_points'] for r in sec['by_f0'] if name in r)


def print_second_pass(by_net: dict[str, dict]) -> None:
    for n, sec in by_net.items():
        for r in sec['by_f0']:
            text = '; '.join(f'{k} {r[k]["pass1"]["top1_error"]:.3f} -> '
                             f'{r[k]["pass2"]["top1_error"]:.3f}'
                             for k in ('centred', 'off_centre') if k in r)
            print(f'two passes ({n}), f0 {r["f0_px"]}: top-1 error {text}')
        print(f'two passes ({n}): max top-1 gain centred {max_gain(sec, "centred"):.2f}, '
              f'off-centre {max_gain(sec, "off_centre"):.2f} points (thesis: 10, 43)')


SECOND_PASS_SAME = ('images', 'grid', 'fixations_px', 'threshold', 'top_k')


def merge_second_pass(path: Path, by_net: dict[str, dict], cpu: dict[str, float],
                      names: list[str], wall: float) -> int:
    """--pass2-only: put the second-pass sections of more networks into the existing result
    (second_pass_by_network; second_pass, read by other code, stays), after checking that they
    were made with the same images, grid, fixations, f0s, threshold and top-k; add their CPU
    time, redo the protocol, rewrite JSON and plot."""
    result = read_existing(path, '--pass2-only')
    if result is None:
        return 2
    have = [n['name'] for n in result['networks']]
    old = result['second_pass']
    key = lambda sec: ([sec[k] for k in SECOND_PASS_SAME],  # noqa: E731
                       [r['f0_px'] for r in sec['by_f0']])
    for sec in by_net.values():
        if have != names or key(rounded(sec)) != key(old):
            print(f'foveated_recognition: {path} was made with networks {have} and a second '
                  f'pass {key(old)}; this run has {names}, {key(rounded(sec))}', file=sys.stderr)
            return 2
    merged = dict(second_pass_networks(result))
    for n, sec in by_net.items():
        if n in merged:
            print(f'foveated_recognition: replacing the second pass of {n}')
        merged[n] = rounded(sec)
    merged = {n: merged[n] for n in names if n in merged}
    if old['network'] in by_net:
        old = merged[old['network']]
    out: dict = {}
    for k, v in result.items():                   # second_pass_by_network after second_pass
        if k == 'second_pass_by_network':
            continue
        out[k] = old if k == 'second_pass' else v
        if k == 'second_pass':
            out['second_pass_by_network'] = merged
    cpu_s: dict = {}
    for k, v in out['cpu_s'].items():             # the old run's 'pass2': its one network
        cpu_s[f"pass2_{result['second_pass']['network']}" if k == 'pass2' else k] = v
    cpu_s.update({k: round(v, 1) for k, v in cpu.items()})
    out['cpu_s'] = cpu_s
    out['protocol'] = protocol_folder(out, sum(cpu_s.values()))
    write_folder_result(path, out)
    print_second_pass({n: merged[n] for n in by_net})
    print(f'second pass of {", ".join(by_net)}: {sum(cpu.values()):.0f} s CPU ({cpu}), '
          f'{wall:.0f} s wall -> {path}')
    return 0


def print_loc_vs_f0(sec: dict) -> None:
    for n, e in sec['error'].items():
        print(f'localisation vs f0 (th {sec["threshold"]:g}), {n}: ' + ', '.join(
            f'{f}: {c:.3f}/{o:.3f}' for f, c, o in zip(sec['f0_px'], e['centred'],
                                                       e['off_centre'], strict=True))
            + ' (centred/off-centre)')


def merge_loc_vs_f0(path: Path, section: dict, cpu_s: float, names: list[str],
                    f0s: list[float]) -> int:
    """--loc-vs-f0-only: put the localisation-vs-f0 section into the existing result (same
    networks, f0 list and collages), add its CPU time, redo the protocol, rewrite JSON and plot."""
    result = read_existing(path, '--loc-vs-f0-only')
    if result is None:
        return 2
    have = [n['name'] for n in result['networks']]
    old_f0s = [r['f0_px'] for r in next(iter(result['error_vs_f0_centred_pass1'].values()))]
    if have != names or old_f0s != [*f0s, 'unfoveated'] or \
            result['localisation']['images'] != section['images']:
        print(f'foveated_recognition: {path} was made with networks {have}, f0 {old_f0s}, '
              f"{result['localisation']['images']} collages; this run has {names}, {f0s}, "
              f"{section['images']}", file=sys.stderr)
        return 2
    result['localisation_vs_f0'] = section
    result['cpu_s']['loc_vs_f0'] = round(cpu_s, 1)
    result['protocol'] = protocol_folder(result, sum(result['cpu_s'].values()))
    write_folder_result(path, result)
    print_loc_vs_f0(section)
    print(f"localisation vs f0: {cpu_s:.0f} s CPU, {section['wall_s']:.0f} s wall -> {path}")
    return 0


def read_existing(path: Path, flag: str) -> dict | None:
    """The result JSON a merging run (flag) adds to; None, after one line, when absent."""
    if not path.exists():
        print(f'foveated_recognition: {flag} needs {path} (run without it first)',
              file=sys.stderr)
        return None
    return json.loads(path.read_text())


def write_folder_result(path: Path, result: dict) -> None:
    """A folder result as strict JSON (no NaN) and its plot beside it."""
    path.write_text(json.dumps(rounded(result), indent=1, allow_nan=False) + '\n')
    plot_folder(result, folder_grid(result), path.with_suffix('.png'))


def folder_grid(result: dict) -> dict[str, np.ndarray]:
    """The pass-1 / pass-2 error grids (Fig. 2.8) as stored in a folder result."""
    return {p: np.asarray(g, float)
            for p, g in result['second_pass']['grid_top1_error_over_f0s'].items()}


def folder_example(clf: Classifier, items: list, size: int, path: Path,
                   f0: float = 50.0, attempts: int = 60) -> None:
    """Fig. 2.5 on one photograph: pass 1 from the top-left grid point (f0 = 50 px of the
    227-px image) with its top-5 boxes, pass 2 with the fovea on the best box. The photo: the
    first (in folder order) whose pass 1 is wrong and pass 2 right, else the first."""
    from foveation_node.core.folder_recognition import fit, grid_fixations, read_rgb

    fov = Foveator(size, size, LEVELS, f0)
    start = grid_fixations(size, size, 3)[0]
    chosen = None
    for item in items[:attempts]:
        rgb = fit(read_rgb(item.path), size)[0]
        res = two_pass(clf, rgb, start, fov.foveate, 5, 0.7)
        if chosen is None:
            chosen = (item, rgb, res)
        if res.first[0].class_id != item.label and res.second[0].class_id == item.label:
            chosen = (item, rgb, res)
            break
    item, rgb, res = chosen
    scale = 2                                         # drawn at 2x for legible labels
    big = lambda img: cv2.resize(img, (size * scale, size * scale),  # noqa: E731
                                 interpolation=cv2.INTER_NEAREST)
    one = cv2.cvtColor(big(fov.foveate(rgb, start)), cv2.COLOR_RGB2BGR)
    best = res.second[0]
    two = cv2.cvtColor(big(fov.foveate(rgb, best.fixation)), cv2.COLOR_RGB2BGR)
    short = lambda label: label.split('_', 1)[-1][:22]  # noqa: E731
    for d in res.first:
        b = [v * scale for v in d.box]
        cv2.rectangle(one, b[:2], b[2:], (0, 0, 255), 2)
        cv2.putText(one, f'{short(d.label)} {d.score:.2f}', (b[0] + 3, max(14, b[1] + 16)), 0,
                    0.5, (0, 0, 255), 1)
    cv2.circle(one, tuple(int(c * scale) for c in start), int(f0 * scale), (255, 255, 255), 1)
    b = [v * scale for v in best.box]
    cv2.rectangle(two, b[:2], b[2:], (0, 255, 0), 2)
    cv2.putText(two, f'{short(best.label)} {best.score:.2f}', (b[0] + 3, max(16, b[1] + 18)), 0,
                0.6, (0, 255, 0), 2)
    cv2.circle(two, tuple(int(c * scale) for c in best.fixation), int(f0 * scale),
               (255, 255, 255), 1)
    cv2.putText(one, f'pass 1 (true: {short(clf.labels[item.label])})', (8, size * scale - 10),
                0, 0.6, (255, 255, 255), 2)
    cv2.putText(two, 'pass 2, fovea on the best box', (8, size * scale - 10), 0, 0.6,
                (255, 255, 255), 2)
    example_legends(one, two, true_box=False)
    cv2.imwrite(str(path), np.hstack([one, two]))
    print(f'example: {item.path.name}: pass 1 {res.first[0].label} {res.first[0].score:.2f}, '
          f'pass 2 {best.label} {best.score:.2f} -> {path}')


def plot_folder(result: dict, grid: dict[str, np.ndarray], path: Path) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(17, 10))
    gs = fig.add_gridspec(2, 6)
    # top row: Figs. 2.7a, 2.9, 2.8 (classification); bottom row: Figs. 2.7b / 2.10a, 2.10b
    ax = [fig.add_subplot(gs[0, 0:2]), fig.add_subplot(gs[1, 1:3]), None,
          fig.add_subplot(gs[0, 4:6]), fig.add_subplot(gs[1, 3:5])]
    sub = gs[0, 2:4].subgridspec(1, 2, wspace=0.08)
    ax9 = [fig.add_subplot(sub[0, 0])]
    ax9.append(fig.add_subplot(sub[0, 1], sharey=ax9[0]))
    colours = plt.rcParams['axes.prop_cycle'].by_key()['color']
    size = result['size_px']
    for i, (n, rows) in enumerate(result['error_vs_f0_centred_pass1'].items()):
        fov = [r for r in rows if r['f0_px'] != 'unfoveated']
        x = [r['f0_px'] for r in fov] + [size]
        c = colours[i % len(colours)]
        ax[0].plot(x, [r['top1_error'] for r in fov] + [rows[-1]['top1_error']], '--o',
                   color=c, ms=4, label=f'{n} top-1')
        ax[0].plot(x, [r['top5_error'] for r in fov] + [rows[-1]['top5_error']], '-s',
                   color=c, ms=4, label=f'{n} top-5')
    ax[0].set(xlabel=f'fovea size f0 [px of the {size}x{size} image; {size} = unfoveated]',
              ylabel='classification error', xscale='log', ylim=(0, 1),
              title=f'error vs f0, centred, pass 1 (Fig. 2.7a)\n{result["images"]} photographs')
    ax[0].legend(fontsize=7, ncol=2)
    loc = result['localisation']
    for i, (n, e) in enumerate(loc['error'].items()):
        c = colours[i % len(colours)]
        ax[1].plot(loc['thresholds'], e['centred'], '-o', color=c, ms=3, label=f'{n} centred')
        ax[1].plot(loc['thresholds'], e['off_centre'], '--', color=c, label=f'{n} off-centre')
    ax[1].set(xlabel='saliency threshold th', ylabel='localisation error (no box IoU >= 0.5)',
              ylim=(0, 1), title=f'localisation vs th, f0 = {loc["f0_px"]:g} px, pass 1 '
              f'(Figs. 2.7b, 2.10a)\n{loc["images"]} photos pasted on other photos')
    ax[1].legend(fontsize=7)
    lf = result.get('localisation_vs_f0')
    if lf is not None:
        fov = [i for i, f in enumerate(lf['f0_px']) if f != 'unfoveated']
        x = [lf['f0_px'][i] for i in fov]
        un = lf['f0_px'].index('unfoveated') if 'unfoveated' in lf['f0_px'] else None
        for i, (n, e) in enumerate(lf['error'].items()):
            c = colours[i % len(colours)]
            for name, style in (('centred', '-o'), ('off_centre', '--s')):
                ax[4].plot(x, [e[name][j] for j in fov], style, color=c, ms=4,
                           label=f'{n} {name.replace("_", "-")}')
            if un is not None:
                ax[4].plot([size * 1.04 ** (i - 1)], [e['centred'][un]], '*', color=c, ms=11,
                           label=f'{n} unfoveated')
        ticks = x + ([size] if un is not None else [])
        ax[4].set_xscale('log')                  # before the ticks (set_xscale resets them)
        ax[4].set_xticks(ticks, [f'{v:g}' for v in x] + (['unfov.'] if un is not None else []))
        ax[4].minorticks_off()
        ax[4].set(xlabel=f'fovea size f0 [px of the {size}x{size} image]',
                  ylabel='localisation error (fraction with no top-5 box IoU >= 0.5)',
                  ylim=(0, 1), title=f'localisation error vs f0 at th {lf["threshold"]:g}, pass 1 '
                  f'(Fig. 2.10b)\n{lf["images"]} photos pasted on other photos')
        ax[4].legend(fontsize=7, ncol=3, loc='lower center')
    else:
        ax[4].text(0.5, 0.5, 'localisation vs f0 not computed\n(--loc-vs-f0-only)',
                   ha='center', va='center', transform=ax[4].transAxes)
        ax[4].set_axis_off()
    sp = result['second_pass']
    # Fig. 2.9, one panel per initial fixation kind: colour = network, dashed open circles =
    # pass 1, solid filled squares = pass 2, star = unfoveated (pass 1 = pass 2 there)
    order = [n['name'] for n in result['networks']]
    for k, (name, title) in enumerate((
            ('centred', f'centred fixation, {sp["images"]} photos'),
            ('off_centre', f'off-centre: 8 other {sp["grid"]}-grid points'))):
        a = ax9[k]
        for n, sec in second_pass_networks(result).items():
            c = colours[order.index(n) % len(colours)] if n in order else 'k'
            rows = [r for r in sec['by_f0'] if r['f0_px'] != 'unfoveated']
            x = [r['f0_px'] for r in rows]
            a.plot(x, [r[name]['pass1']['top1_error'] for r in rows], '--o', color=c, ms=5,
                   mfc='none', label=f'{n} pass 1')
            a.plot(x, [r[name]['pass2']['top1_error'] for r in rows], '-s', color=c, ms=4,
                   label=f'{n} pass 2')
            un = [r for r in sec['by_f0'] if r['f0_px'] == 'unfoveated']
            if un:
                a.plot([size], [un[0]['centred']['pass1']['top1_error']], '*', color=c, ms=10,
                       label=f'{n} unfoveated')
        a.set_xscale('log')
        a.set_xticks(x + [size], [f'{v:g}' for v in x] + ['unfov.'])
        a.minorticks_off()
        a.set(xlabel=f'fovea size f0 [px of {size}x{size}]', ylim=(0, 1))
        a.set_title(f'pass 1 vs pass 2, th = 0.7 (Fig. 2.9)\n{title}', fontsize=9.5)
        a.grid(alpha=0.3)
    ax9[0].set_ylabel('top-1 error (fraction of cases)')
    ax9[1].tick_params(labelleft=False)
    ax9[0].legend(fontsize=7, ncol=3, loc='upper center', bbox_to_anchor=(1.04, -0.13),
                  title='colour: network; dashed, open o: pass 1; solid, filled square: pass 2; '
                        'star: unfoveated', title_fontsize=7)
    both = np.hstack([grid['pass1'], np.full((grid['pass1'].shape[0], 1), np.nan), grid['pass2']])
    im = ax[3].imshow(both, cmap='gray', vmin=0, vmax=max(float(np.nanmax(both)), 0.05))
    for (r, c), val in np.ndenumerate(both):
        if np.isfinite(val):
            ax[3].text(c, r, f'{val:.2f}', ha='center', va='center', color='tab:orange')
    ax[3].set(title=f'top-1 error vs initial fixation (Fig. 2.8), {sp["network"]}\npass 1 | '
                    f'pass 2, mean over f0 {", ".join(f"{v:g}" for v in x)}', xticks=[],
              yticks=[])
    ax[3].set_anchor('E')                     # the grids next to their colour bar
    fig.colorbar(im, ax=ax[3], fraction=0.03, shrink=0.6, label='top-1 error')
    fig.tight_layout(h_pad=2.5)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def rounded(value: object, digits: int = 4) -> object:
    if isinstance(value, float):
        return round(value, digits)
    if isinstance(value, dict):
        return {k: rounded(v, digits) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [rounded(v, digits) for v in value]
    return value


def plot(result: dict, path: Path) -> None:
    """Figs. 2.7a / 2.9 (error vs f0), 2.7b / 2.10a (localisation vs th) and 2.8 (error vs the
    initial fixation), from the result alone (so --plot-only can redraw it)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 3, figsize=(16, 9.5))
    rows = [r for r in result['by_f0'] if r['f0_px'] != 'unfoveated']
    base = result['by_f0'][-1]
    x = [r['f0_px'] for r in rows]
    n_views = result['views']
    for k, (topk, ylim) in enumerate((('top1', 1.0), ('top5', 0.5))):
        a = ax[0, k]
        for name, colour, what in (('centred', 'tab:blue', 'centred fixation'),
                                   ('non_centred', 'tab:red', 'off-centre fixations')):
            for pss, style, pname in (('pass1', '--', 'pass 1'), ('pass2', '-', 'pass 2')):
                a.plot(x, [r[f'{name}_{pss}_{topk}_error'] for r in rows], style, color=colour,
                       marker='o', label=f'{what}, {pname}')
        a.axhline(base[f'centred_pass1_{topk}_error'], color='k', lw=1, ls=':',
                  label='unfoveated image')
        a.set(xlabel='fovea size f0 [px, in a 640x480 image]', xscale='log', ylim=(0, ylim),
              ylabel=f'{"top-1" if topk == "top1" else "top-5"} error (fraction of cases)',
              title=('top-1 error vs fovea size (Figs. 2.7a, 2.9)' if topk == 'top1' else
                     f'top-5 error vs fovea size ({len(result["classes"])} classes: loose)'))
        a.set_xticks(x, [f'{v:g}' for v in x])
        a.minorticks_off()
        a.grid(alpha=0.3)
        a.legend(fontsize=8, title='dashed: pass 1, solid: pass 2', title_fontsize=8,
                 handlelength=3.5)
    loc = result['localisation_vs_threshold']
    a = ax[0, 2]
    a.plot(loc['thresholds'], loc['error'], 'k-o', ms=4, label='centred fixation, pass 1')
    a.set(xlabel='saliency threshold th',
          ylabel='localisation error (no top-5 box with IoU >= 0.5)',
          title=f'localisation vs th (Figs. 2.7b, 2.10a; f0 = {loc["f0_px"]:g} px)', ylim=(0, 1))
    a.grid(alpha=0.3)
    a.legend(fontsize=8)
    grid = {k: np.asarray(v, float) for k, v in result['grid_top1_error'].items()}
    fx = sorted({p[0] for p in result['fixations_px'][1:]})
    fy = sorted({p[1] for p in result['fixations_px'][1:]})
    w, h = result['image']
    vmax = max(float(g.max()) for g in grid.values())
    for k, (pss, title) in enumerate((('pass1', 'pass 1'), ('pass2', 'pass 2'))):
        a = ax[1, k]
        g = grid[pss]
        im = a.imshow(g, cmap='viridis', vmin=0, vmax=vmax, extent=(0, w, h, 0))
        for (r, c), val in np.ndenumerate(g):
            a.text((c + 0.5) * w / g.shape[1], (r + 0.5) * h / g.shape[0], f'{val:.2f}',
                   ha='center', va='center', fontsize=11,
                   color='white' if val < 0.6 * vmax else 'black')
        a.set_xticks(fx)
        a.set_yticks(fy)
        a.set(xlabel='initial fixation x [px]', ylabel='initial fixation y [px]',
              title=f'top-1 error vs initial fixation, {title} (Fig. 2.8; mean over f0)')
    fig.colorbar(im, ax=ax[1, 1], label='top-1 error (fraction of views)', fraction=0.035)
    a = ax[1, 2]
    dist = result['by_distance_top1']
    mid = [0.5 * (d['distance_px'][0] + d['distance_px'][1]) for d in dist]
    a.plot(mid, [d['pass1_top1_error'] for d in dist], '--o', color='tab:red', label='pass 1')
    a.plot(mid, [d['pass2_top1_error'] for d in dist], '-o', color='tab:red', label='pass 2')
    a.set(xlabel='distance from the initial fixation to the object [px]',
          ylabel='top-1 error (fraction of cases)', ylim=(0, 1),
          title='top-1 error vs fixation-object distance')
    a.grid(alpha=0.3)
    a.legend(fontsize=8)
    fig.suptitle(f'Foveated recognition on {n_views} simulated views '
                 f'({result["per_class"]} per class, {len(result["classes"])} classes), '
                 'first vs second pass', fontsize=12)
    fig.tight_layout(rect=(0, 0, 0.97, 0.97))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def example_legends(one: np.ndarray, two: np.ndarray, true_box: bool) -> None:
    """The key of the Fig. 2.5 example's colours, in the nodes' overlay style (BGR)."""
    from vizzy_runtime.overlay import draw_legend

    draw_legend(one, [((0, 0, 255), 'pass 1: top-5 saliency boxes (label, score)'),
                      ((255, 255, 255), 'fovea (radius f0) at the first fixation')])
    draw_legend(two, [((0, 255, 0), 'pass 2: best box (label, score)')]
                + ([((255, 255, 0), 'true object box')] if true_box else [])
                + [((255, 255, 255), 'fovea (radius f0) on the best box')])


def example(clf: Classifier, views: list, foveator: Foveator, path: Path) -> None:
    """Fig. 2.5 on one view: pass 1 at the centre with its top-5 boxes (red), pass 2 with the
    fovea on the best box (green; the true box in cyan). The view: the one farthest from the
    centre whose pass 1 is wrong and pass 2 right (else the farthest)."""
    by_distance = sorted(views, key=lambda v: -np.hypot(v.centre[0] - CENTRE[0],
                                                        v.centre[1] - CENTRE[1]))
    view, res = by_distance[0], None
    for candidate in by_distance:
        r = two_pass(clf, candidate.rgb, CENTRE, foveator.foveate, 5, 0.7)
        if r.first[0].class_id != candidate.label and r.second and \
                r.second[0].class_id == candidate.label:
            view, res = candidate, r
            break
    if res is None:
        res = two_pass(clf, view.rgb, CENTRE, foveator.foveate, 5, 0.7)
    one = cv2.cvtColor(foveator.foveate(view.rgb, CENTRE), cv2.COLOR_RGB2BGR)
    best = res.second[0] if res.second else res.first[0]     # none: rejected as background
    two = cv2.cvtColor(foveator.foveate(view.rgb, best.fixation), cv2.COLOR_RGB2BGR)
    for d in res.first:
        cv2.rectangle(one, d.box[:2], d.box[2:], (0, 0, 255), 2)
        cv2.putText(one, f'{d.label} {d.score:.2f}', (d.box[0], max(12, d.box[1] - 4)), 0, 0.5,
                    (0, 0, 255), 1)
    cv2.circle(one, tuple(int(c) for c in CENTRE), int(foveator.f0), (255, 255, 255), 1)
    cv2.rectangle(two, best.box[:2], best.box[2:], (0, 255, 0), 2)
    cv2.putText(two, f'{best.label} {best.score:.2f}', (best.box[0], max(12, best.box[1] - 4)), 0,
                0.6, (0, 255, 0), 2)
    cv2.circle(two, tuple(int(c) for c in best.fixation), int(foveator.f0), (255, 255, 255), 1)
    cv2.rectangle(two, view.box[:2], view.box[2:], (255, 255, 0), 1)
    cv2.putText(one, f'pass 1 at the centre (true: {clf.labels[view.label]})', (8, H - 10), 0,
                0.6, (255, 255, 255), 2)
    cv2.putText(two, 'pass 2, fovea on the best box', (8, H - 10), 0, 0.6, (255, 255, 255), 2)
    example_legends(one, two, true_box=True)
    cv2.imwrite(str(path), np.hstack([one, two]))


if __name__ == '__main__':
    sys.exit(main())
