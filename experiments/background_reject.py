#!/usr/bin/env python3
"""Does the recogniser say "nothing here"? Two-pass recognition at fixations on no object and
on objects, before and after the background (reject) class.

Held-out renders (seeds from 20000: used neither for training nor by the end-to-end benchmark's
seeds 0-99) of the tabletop scene (the demo's start pose, one random pose over the table and two
poses anywhere within the joint limits: walls, floor, up and away) and of the visual_search
scene (its start pose and two poses anywhere), left eye, 640x480, foveated as the node does
(K = 5, f_0 = 100 px, sigma_1 = sqrt(8/3)), `two_pass` with top-k 5 and th 0.7:

- background fixations: up to BACKGROUND_PER_VIEW per view, uniform over the image at least
  BACKGROUND_MIN_PX from every object's box (training.background_views; TableView.extents),
  binned by that distance (no object in the image: "none in view");
- object fixations: up to OBJECTS_PER_VIEW unoccluded objects per view, fixated at their centre.

Reported per model: on background fixations, the fraction where pass 2 reports an object with
score >= saccade_min_score (0.3, what would draw a saccade), the fraction where that report is
false (its box centre lies on no object's box, padded by FALSE_PAD_PX; near objects a report
may rightly name a neighbour, pass 2 having moved its fovea there) and where it lies more than
FAR_PX from every object (on the wall or floor: the demo's "bottle 0.67" on the wall); on
object fixations, the top-1 accuracy of the classification at the fixation (pass 1; a
background answer counts as wrong), the fraction of those rejected as background, and the
two-pass final label (class of the object under its box) and how often pass 2 reports nothing.
Against the reporting threshold: reports far from objects on background fixations vs right
final labels on objects (the threshold-only alternative to a reject class).

    .venv/bin/python experiments/background_reject.py --baseline OLD.pt [--model NEW.pt]
        [--tabletop-scenes 20] [--search-scenes 10] [--quick]

Writes experiments/results/background_reject.json and .png (`--quick`: _quick).
"""

from __future__ import annotations

import os

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'experiments'))
from protocol import cpu_seconds, protocol, result_stem  # noqa: E402

from foveation_node.core.foveation import Foveator  # noqa: E402
from foveation_node.core.recognition import BACKGROUND_LABEL, Classifier, two_pass  # noqa: E402

MODELS = ROOT / 'src' / 'foveation_node' / 'foveation_node' / 'models'
W, H, LEVELS, F0 = 640, 480, 5, 100.0
SEED0 = 20000                     # training's held-out seeds (tabletop and visual_search)
TOP_K, TH = 5, 0.7
SACCADE_MIN_SCORE = 0.3           # the node's saccade_min_score
BACKGROUND_PER_VIEW = 3
OBJECTS_PER_VIEW = 3
BACKGROUND_MIN_PX = 40.0
FALSE_PAD_PX = 10.0
FAR_PX = 50.0                     # a report this far from every object box: on the wall
DIST_BINS = ((40.0, 100.0), (100.0, 200.0), (200.0, math.inf))
THRESHOLDS = tuple(round(t, 2) for t in np.arange(0.0, 0.951, 0.05))


def render_cases(tabletop_scenes: int, search_scenes: int) -> list[dict]:
    """The held-out views and their fixations: one dict per view with rgb, extents, objects,
    scene, pose kind and the list of (kind, (u, v), distance px or object label)."""
    from tqdm import tqdm

    from foveation_node.training.background_views import (
        away_joints,
        background_fixations,
        object_distance,
    )
    from foveation_node.training.tabletop_views import (
        DEFAULT_JOINTS,
        TabletopViews,
        random_joints,
    )
    from vizzy_sim_bridge.core.scenes import visual_search

    rng = np.random.default_rng(SEED0)
    views = []
    plan = [('tabletop', None, tabletop_scenes,
             [('start', lambda: DEFAULT_JOINTS), ('over table', lambda: random_joints(rng)),
              ('anywhere', lambda: away_joints(rng)), ('anywhere', lambda: away_joints(rng))]),
            ('visual_search', visual_search, search_scenes,
             [('start', lambda: (0.0,) * 5), ('anywhere', lambda: away_joints(rng)),
              ('anywhere', lambda: away_joints(rng))])]
    for name, builder, count, poses in plan:
        with TabletopViews(W, H, scene=builder) as tv:
            for s in tqdm(range(SEED0, SEED0 + count), desc=f'render {name}', unit='scene'):
                for pose, joints in poses:
                    try:
                        view = tv.view(s, joints())
                    except RuntimeError:
                        break
                    fixes = []
                    for u, v in background_fixations(view.extents, W, H, rng,
                                                     BACKGROUND_PER_VIEW, BACKGROUND_MIN_PX):
                        fixes.append(('background', (u, v),
                                      object_distance(view.extents, u, v)))
                    visible = [o for o in view.objects if o.visible]
                    for i in rng.permutation(len(visible))[:OBJECTS_PER_VIEW]:
                        u, v = visible[i].centre                    # in [0, W) x [0, H)
                        fixes.append(('object', (min(u, W - 1.0), min(v, H - 1.0)),
                                      visible[i].label))
                    views.append({'scene': name, 'seed': s, 'pose': pose, 'rgb': view.rgb,
                                  'extents': view.extents, 'objects': view.objects,
                                  'fixations': fixes})
    return views


def evaluate(clf: Classifier, views: list[dict], name: str) -> list[dict]:
    """One row per fixation: what two_pass says there (see the module docstring)."""
    from tqdm import tqdm

    from foveation_node.training.background_views import object_distance
    from foveation_node.training.tabletop_views import object_at

    foveator = Foveator(W, H, LEVELS, F0)
    rows = []
    cases = [(v, f) for v in views for f in v['fixations']]
    for view, (kind, fix, info) in tqdm(cases, desc=name, unit='case'):
        res = two_pass(clf, view['rgb'], fix, foveator.foveate, TOP_K, TH)
        best = max(res.second, key=lambda d: d.score, default=None)
        top1 = int(np.argmax(res.probs_first))
        row = {'kind': kind, 'scene': view['scene'], 'pose': view['pose'],
               'best_score': best.score if best else 0.0,
               'best_label': best.label if best else '',
               'best_distance_px': object_distance(view['extents'], *best.centre)
               if best is not None else math.inf,
               'top1': clf.labels[top1]}
        if kind == 'background':
            row['distance_px'] = info
        else:
            row['label'] = int(info)
            row['top1_right'] = top1 == info
            under = object_at(view['objects'], *best.centre) if best else None
            row['final_right'] = bool(best is not None and under is not None
                                      and best.class_id == under.label)
        rows.append(row)
    return rows


def summarise(rows: list[dict], classes: list[str]) -> dict:
    bg = [r for r in rows if r['kind'] == 'background']
    ob = [r for r in rows if r['kind'] == 'object']

    def frac(sel: list[dict], test: Callable[[dict], bool]) -> float:
        return float(np.mean([bool(test(r)) for r in sel])) if sel else float('nan')

    def report(r: dict, t: float = SACCADE_MIN_SCORE) -> bool:
        return bool(r['best_label']) and r['best_score'] >= t

    def false_report(r: dict, t: float = SACCADE_MIN_SCORE) -> bool:
        return report(r, t) and r['best_distance_px'] > FALSE_PAD_PX

    def far_report(r: dict, t: float = SACCADE_MIN_SCORE) -> bool:
        return report(r, t) and r['best_distance_px'] > FAR_PX

    groups: dict[str, list[dict]] = {'all': bg}
    for lo, hi in DIST_BINS:
        groups[f'{lo:g}-{hi:g} px' if hi < math.inf else f'>= {lo:g} px (in view)'] = [
            r for r in bg if lo <= r['distance_px'] < hi]
    groups['no object in view'] = [r for r in bg if r['distance_px'] == math.inf]
    groups['tabletop'] = [r for r in bg if r['scene'] == 'tabletop']
    groups['visual_search'] = [r for r in bg if r['scene'] == 'visual_search']
    groups['pose anywhere'] = [r for r in bg if r['pose'] == 'anywhere']
    background = {name: {'fixations': len(sel),
                         'object_reported': frac(sel, report),
                         'false_object_reported': frac(sel, false_report),
                         'far_object_reported': frac(sel, far_report),
                         'top1_background': frac(sel, lambda r: r['top1'] == BACKGROUND_LABEL)}
                  for name, sel in groups.items()}
    labels = [r['best_label'] for r in bg if false_report(r)]
    background['false_report_labels'] = {c: labels.count(c) for c in sorted(set(labels))}
    objects = {'fixations': len(ob),
               'top1_accuracy': frac(ob, lambda r: r['top1_right']),
               'top1_rejected_as_background': frac(ob, lambda r: r['top1'] == BACKGROUND_LABEL),
               'final_label_right': frac(ob, lambda r: r['final_right']),
               'final_label_right_reported': frac(ob, lambda r: r['final_right'] and report(r)),
               'no_detection': frac(ob, lambda r: not r['best_label']),
               'nothing_reported': frac(ob, lambda r: not report(r))}
    per_class = {}
    for i, c in enumerate(classes):
        sel = [r for r in ob if r['label'] == i]
        if sel:
            per_class[c] = {'fixations': len(sel),
                            'top1_accuracy': frac(sel, lambda r: r['top1_right']),
                            'rejected': frac(sel, lambda r: r['top1'] == BACKGROUND_LABEL)}
    objects['per_class'] = per_class
    objects['by_scene'] = {
        scene: {'fixations': len(sel),
                'top1_accuracy': frac(sel, lambda r: r['top1_right']),
                'top1_rejected_as_background': frac(sel,
                                                    lambda r: r['top1'] == BACKGROUND_LABEL),
                'final_label_right': frac(sel, lambda r: r['final_right']),
                'nothing_reported': frac(sel, lambda r: not report(r))}
        for scene in ('tabletop', 'visual_search')
        for sel in [[r for r in ob if r['scene'] == scene]]}
    curve = {'thresholds': list(THRESHOLDS),
             'background_object_reported': [frac(bg, lambda r, t=t: report(r, t))
                                            for t in THRESHOLDS],
             'background_false_report': [frac(bg, lambda r, t=t: false_report(r, t))
                                         for t in THRESHOLDS],
             'background_far_report': [frac(bg, lambda r, t=t: far_report(r, t))
                                       for t in THRESHOLDS],
             'background_no_object_in_view_reported': [
                 frac(groups['no object in view'], lambda r, t=t: report(r, t))
                 for t in THRESHOLDS],
             'objects_final_right_reported': [
                 frac(ob, lambda r, t=t: r['final_right'] and report(r, t)) for t in THRESHOLDS]}
    return {'background': background, 'objects': objects, 'vs_threshold': curve}


def _num(value: float | None) -> float:
    return float('nan') if value is None else float(value)


def plot(result: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    models = result['models']
    fig, axes = plt.subplots(1, 3, figsize=(17, 5))
    ax = axes[0]
    groups = [g for g in result['by_model'][models[0]['name']]['background']
              if g.endswith('px') or g.endswith('(in view)') or g == 'no object in view']
    groups += ['visual_search', 'pose anywhere']
    x = np.arange(len(groups))
    width = 0.8 / (2 * len(models))
    for m, model in enumerate(models):
        bg = result['by_model'][model['name']]['background']
        for j, (key, hatch, what) in enumerate((
                ('object_reported', '', 'any object'),
                ('far_object_reported', '//', f'box centre > {FAR_PX:g} px from every object'))):
            ax.bar(x + (2 * m + j - len(models) + 0.5) * width, [_num(bg[g][key]) for g in groups],
                   width, hatch=hatch, color=f'C{m}', alpha=1.0 if j == 0 else 0.6,
                   label=f"{model['name']}: {what}")
    counts = result['by_model'][models[0]['name']]['background']
    short = {'>= 200 px (in view)': '>= 200 px', 'no object in view': 'no object\nin view',
             'visual_search': 'visual\nsearch', 'pose anywhere': 'pose\nanywhere'}
    ax.set_xticks(x, [f"{short.get(g, g)}\n(n={counts[g]['fixations']})" for g in groups],
                  fontsize=8)
    ax.set_xlabel('background fixation: distance to the nearest object box; scene; pose')
    ax.set_ylabel('fraction of background fixations')
    ax.set_title(f'pass 2 reports (score >= {SACCADE_MIN_SCORE:g}) from a fixation on no object',
                 fontsize=10)
    ax.set_ylim(0, 1.3)
    ax.set_yticks(np.arange(0, 1.01, 0.2))
    ax.legend(fontsize=7, loc='upper center', ncol=2)

    ax = axes[1]
    keys = [('tabletop', 'top1_accuracy', 'tabletop:\ntop-1 right'),
            ('tabletop', 'top1_rejected_as_background', 'tabletop:\nrejected'),
            ('visual_search', 'top1_accuracy', 'search:\ntop-1 right'),
            ('visual_search', 'top1_rejected_as_background', 'search:\nrejected'),
            (None, 'final_label_right', 'all: two-pass\nfinal right'),
            (None, 'nothing_reported', f'all: nothing\nreported >= {SACCADE_MIN_SCORE:g}')]
    x = np.arange(len(keys))
    width = 0.8 / len(models)
    for m, model in enumerate(models):
        ob = result['by_model'][model['name']]['objects']
        values = [_num((ob if scene is None else ob['by_scene'][scene])[k])
                  for scene, k, _ in keys]
        ax.bar(x + (m - (len(models) - 1) / 2) * width, values, width, color=f'C{m}',
               label=model['name'])
    ax.set_xticks(x, [name for _, _, name in keys], fontsize=8)
    ax.set_ylabel('fraction of object fixations')
    n = result['by_model'][models[0]['name']]['objects']['fixations']
    by_scene = result['by_model'][models[0]['name']]['objects']['by_scene']
    ax.set_title(f"fixations on objects (n = {n}: tabletop {by_scene['tabletop']['fixations']}, "
                 f"visual_search {by_scene['visual_search']['fixations']})", fontsize=10)
    ax.set_ylim(0, 1)
    ax.legend(fontsize=8)

    ax = axes[2]
    for m, model in enumerate(models):
        c = result['by_model'][model['name']]['vs_threshold']
        ax.plot(c['thresholds'], [_num(v) for v in c['background_far_report']], '-',
                color=f'C{m}',
                label=f"{model['name']}: report > {FAR_PX:g} px from objects (background)")
        ax.plot(c['thresholds'], [_num(v) for v in c['objects_final_right_reported']], '--',
                color=f'C{m}',
                label=f"{model['name']}: right label reported on objects")
    ax.axvline(SACCADE_MIN_SCORE, color='grey', lw=0.8, ls=':')
    ax.set_xlabel('least reported score (threshold)')
    ax.set_ylabel('fraction of fixations')
    ax.set_title('a threshold alone vs the reject class')
    ax.set_ylim(0, 1)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def rounded(value: object, digits: int = 4) -> object:
    if isinstance(value, float):
        return round(value, digits) if math.isfinite(value) else None     # nan: no cases
    if isinstance(value, dict):
        return {k: rounded(v, digits) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [rounded(v, digits) for v in value]
    return value


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--model', type=Path, default=MODELS / 'foveation_cnn.pt',
                        help='the model with the background class (labels: <model>.labels)')
    parser.add_argument('--baseline', type=Path, default=None,
                        help='the model before (e.g. `git show b98e87c:<path>` of foveation_cnn.pt '
                             '.labels .json into a folder)')
    parser.add_argument('--names', nargs=2, default=('before', 'after'),
                        help='names of --baseline and --model in the plot and JSON')
    parser.add_argument('--tabletop-scenes', type=int, default=20)
    parser.add_argument('--search-scenes', type=int, default=10)
    parser.add_argument('--quick', action='store_true', help='3 + 2 scenes')
    parser.add_argument('--out', type=Path, default=ROOT / 'experiments' / 'results')
    parser.add_argument('--plot-only', action='store_true')
    args = parser.parse_args()
    stem = result_stem('background_reject', args.quick)
    if args.plot_only:
        plot(json.loads((args.out / f'{stem}.json').read_text()), args.out / f'{stem}.png')
        return 0
    import cv2
    import torch

    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    if args.quick:
        args.tabletop_scenes, args.search_scenes = 3, 2
    t0 = time.perf_counter()
    views = render_cases(args.tabletop_scenes, args.search_scenes)
    models = []
    if args.baseline is not None:
        models.append((args.names[0], args.baseline))
    models.append((args.names[1] if args.baseline is not None else 'model', args.model))
    from foveation_node.training.object_views import CLASSES

    result: dict = {
        'seeds': {'tabletop': [SEED0, SEED0 + args.tabletop_scenes - 1],
                  'visual_search': [SEED0, SEED0 + args.search_scenes - 1]},
        'views': len(views), 'image': [W, H], 'levels': LEVELS, 'f0_px': F0, 'top_k': TOP_K,
        'threshold': TH, 'saccade_min_score': SACCADE_MIN_SCORE,
        'background_min_distance_px': BACKGROUND_MIN_PX, 'false_report_pad_px': FALSE_PAD_PX,
        'models': [], 'by_model': {}}
    for name, path in models:
        clf = Classifier(path, path.with_suffix('.labels'))
        result['models'].append({
            'name': name, 'path': str(path.resolve().relative_to(ROOT))
            if path.resolve().is_relative_to(ROOT) else str(path),
            'labels': clf.labels})
        result['by_model'][name] = summarise(evaluate(clf, views, name), list(CLASSES))
    result['seconds'] = round(time.perf_counter() - t0, 1)
    n_bg = sum(f[0] == 'background' for v in views for f in v['fixations'])
    n_ob = sum(f[0] == 'object' for v in views for f in v['fixations'])
    result['protocol'] = protocol(
        data=f'{len(views)} held-out left-eye renders (tabletop seeds {SEED0}.., visual_search '
             f'seeds {SEED0}..; start, over-table and anywhere head poses), {n_bg} background '
             f'and {n_ob} object fixations', repetitions={'background': n_bg, 'objects': n_ob},
        thesis_repetitions=None,
        models=', '.join(f"{m['name']}: {m['path']} ({len(m['labels'])} classes)"
                         for m in result['models']),
        differs_from_thesis=['no thesis counterpart: the thesis\'s ImageNet networks always '
                             'name one of their 1000 classes; this measures a reject class'],
        cpu_s=cpu_seconds())
    args.out.mkdir(parents=True, exist_ok=True)
    result = rounded(result)                                        # type: ignore[assignment]
    (args.out / f'{stem}.json').write_text(json.dumps(result, indent=1) + '\n')
    plot(result, args.out / f'{stem}.png')
    for name, _ in models:
        r = result['by_model'][name]
        bg, ob = r['background'], r['objects']
        print(f"{name}: background fixations {bg['all']['fixations']}: object reported "
              f"{bg['all']['object_reported']}, false {bg['all']['false_object_reported']} "
              f"(no object in view: {bg['no object in view']['object_reported']}); objects "
              f"{ob['fixations']}: top-1 {ob['top1_accuracy']}, rejected "
              f"{ob['top1_rejected_as_background']}, final right {ob['final_label_right']}, "
              f"nothing reported {ob['nothing_reported']}")
    print(f'{result["seconds"]:.0f} s; wrote {args.out / stem}.json and .png')
    return 0


if __name__ == '__main__':
    sys.exit(main())
