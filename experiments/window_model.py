#!/usr/bin/env python3
"""The window model (fovea_cnn: the 160 px window around the fixation at 96x96) against the
whole-frame model (foveation_cnn: the foveated frame shrunk to 227x227) on the same held-out
renders, in the closed loop's case: the head fixating each object.

Held-out scenes (seeds from 20000: used neither for training nor by the end-to-end benchmark's
seeds 0-99): tabletop and visual_search. For every object of a scene the head fixates it as the
gaze controller does (vizzy_gaze solve_fixation of its centre in base_link: the object at the
principal point of the left eye; objects hidden there are skipped); the left-eye 640x480 render
is foveated as the node does (K = 5, f_0 = 100 px) at the principal point, and each model

- classifies it (pass 1 at the fixation): top-1 over every class, background included (a
  background answer is wrong), and how often it says background;
- runs `two_pass` (top-k 5, th 0.7): the final label (pass 2's best) is right when it is the
  class of the object the eye sees at its box centre (the ray through it; where it meets no
  object, the object whose box holds it, tabletop_views.object_at); "nothing" when pass 2
  reports no label.

Background fixations, in the same views (one per view) and in poses anywhere within the joint
limits (tabletop: two, and one tilted up at the wall behind the table; visual_search: two), two
each: uniform over the image at least BACKGROUND_MIN_PX (f_0 / 2) from every object's box. Per
model: pass 1 says background (rejection), pass 1 reports an object (some object class beats
background at the fixation), and two_pass reports an object with score >= 0.3 (what draws a
saccade) more than FAR_PX from every object's box (a false report on the wall, floor or table).

CPU: process CPU time (torch on one thread, as the node's recognition_threads 1) per window
(a window model) or per image (whole-frame), per two_pass recognition as above (mean over the
object fixations: foveation of the k pass-2 images included), and per grid_recognition of a
frame (the uniform baseline, stride 40 px).

    .venv/bin/python experiments/window_model.py [--tabletop-scenes 40] [--search-scenes 20]
        [--quick] [--update-report]

Writes experiments/results/window_model.json (`--quick`: _quick); --update-report also puts the
figures into the window model's JSON (models/fovea_cnn.json, key "evaluation").
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
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'experiments'))
from protocol import cpu_seconds, protocol, result_stem  # noqa: E402

from foveation_node.core.foveation import Foveator  # noqa: E402
from foveation_node.core.recognition import (  # noqa: E402
    Classifier,
    grid_recognition,
    two_pass,
)

MODELS = ROOT / 'src' / 'foveation_node' / 'foveation_node' / 'models'
W, H, LEVELS, F0 = 640, 480, 5, 100.0
SEED0 = 20000
TOP_K, TH = 5, 0.7
SACCADE_MIN_SCORE = 0.3
BACKGROUND_MIN_PX = F0 / 2
FAR_PX = 50.0
GRID_STRIDE = 40
PRINCIPAL = (319.5, 239.5)


class Case:
    """One fixation and what each model said there."""

    def __init__(self, kind: str, scene: str, label: int | None, source: str) -> None:
        self.kind, self.scene, self.label, self.source = kind, scene, label, source
        self.by_model: dict[str, dict[str, Any]] = {}


def _timed(fn: Any) -> tuple[Any, float]:
    t = time.process_time()
    out = fn()
    return out, time.process_time() - t


def run(models: dict[str, Classifier], tabletop_scenes: int, search_scenes: int
        ) -> list[Case]:
    from tqdm import tqdm

    from foveation_node.training.background_views import (
        away_joints,
        background_fixations,
        object_distance,
    )
    from foveation_node.training.tabletop_views import TabletopViews, object_at
    from foveation_node.training.window_views import fixation_joints, wall_joints
    from vizzy_sim_bridge.core.scenes import visual_search

    fov = Foveator(W, H, LEVELS, F0)
    cases: list[Case] = []

    def judge(tv: Any, view: Any, case: Case, fix: tuple[float, float]) -> None:
        image, fov_s = _timed(lambda: fov.foveate(view.rgb, fix))
        for name, clf in models.items():
            probs, cls_s = _timed(lambda c=clf: c.classify(image, [fix])[0])
            res, tp_s = _timed(lambda c=clf: two_pass(c, view.rgb, fix, fov.foveate, TOP_K, TH))
            best = max(res.second, key=lambda d: d.score, default=None)
            row: dict[str, Any] = {'top1': int(np.argmax(probs)),
                                   'pass1_reports': bool(res.first),
                                   'classify_s': cls_s, 'two_pass_s': tp_s + fov_s,
                                   'best_score': best.score if best else 0.0}
            if best is not None:
                seen = tv.object_under(*best.centre)
                truth = (next(o.label for o in view.objects if o.name == seen)
                         if seen is not None and any(o.name == seen for o in view.objects)
                         else None)
                if truth is None:
                    under = object_at(view.objects, *best.centre)
                    truth = under.label if under is not None else -1
                row['best_right'] = best.class_id == truth
                row['best_distance_px'] = object_distance(view.extents, *best.centre)
            case.by_model[name] = row
        cases.append(case)

    rng = np.random.default_rng([SEED0, 5])
    for scene, builder, count in (('tabletop', None, tabletop_scenes),
                                  ('visual_search', visual_search, search_scenes)):
        with TabletopViews(W, H, scene=builder) as tv:
            for seed in tqdm(range(SEED0, SEED0 + count), desc=scene, unit='scene'):
                try:
                    points = tv.object_points(seed)
                except RuntimeError:
                    continue
                for label, name, point in points:
                    joints = fixation_joints(point)
                    if joints is None:
                        continue
                    view = tv.view(seed, joints)
                    if tv.object_under(*PRINCIPAL) not in (name, None):
                        continue                        # hidden where the head looks
                    judge(tv, view, Case('object', scene, label, 'fixated'), PRINCIPAL)
                    for fix in background_fixations(view.extents, W, H, rng, 1,
                                                    BACKGROUND_MIN_PX):
                        judge(tv, view, Case('background', scene, None, 'fixated pose'), fix)
                poses = [('anywhere', away_joints(rng)) for _ in range(2)]
                if scene == 'tabletop':
                    poses.append(('wall', wall_joints(rng)))
                for source, joints in poses:
                    view = tv.view(seed, joints)
                    for fix in background_fixations(view.extents, W, H, rng, 2,
                                                    BACKGROUND_MIN_PX):
                        judge(tv, view, Case('background', scene, None, source), fix)
    return cases


def summarise(cases: list[Case], name: str, classes: list[str], reject: int) -> dict[str, Any]:
    r = lambda a: round(float(np.mean(a)), 4) if len(a) else None  # noqa: E731
    out: dict[str, Any] = {}
    objects = [c for c in cases if c.kind == 'object']
    for scope, sel in (('all', objects),
                       ('tabletop', [c for c in objects if c.scene == 'tabletop']),
                       ('visual_search', [c for c in objects if c.scene == 'visual_search'])):
        rows = [c.by_model[name] for c in sel]
        out[f'objects_{scope}'] = {
            'fixations': len(sel),
            'top1': r([row['top1'] == c.label for c, row in zip(sel, rows, strict=True)]),
            'rejected_as_background': r([row['top1'] == reject for row in rows]),
            'two_pass_final_label_right': r([bool(row.get('best_right')) for row in rows]),
            'two_pass_nothing_reported': r([row['best_score'] == 0.0 for row in rows])}
    out['objects_per_class_top1'] = {
        c: r([o.by_model[name]['top1'] == i for o in objects if o.label == i])
        for i, c in enumerate(classes)}
    out['objects_per_class_fixations'] = {c: sum(o.label == i for o in objects)
                                          for i, c in enumerate(classes)}
    confusion = np.zeros((len(classes) + 1, len(classes) + 1), int)
    for o in objects:
        confusion[o.label, o.by_model[name]['top1']] += 1
    bgs = [c for c in cases if c.kind == 'background']
    for b in bgs:
        confusion[len(classes), b.by_model[name]['top1']] += 1
    out['confusion_rows_true_cols_predicted'] = confusion.tolist()
    for scope in ('all', 'fixated pose', 'anywhere', 'wall', 'visual_search'):
        sel = [b for b in bgs if scope == 'all' or b.source == scope
               or (scope == 'visual_search' and b.scene == scope)]
        if scope in ('fixated pose', 'anywhere', 'wall'):
            sel = [b for b in sel if b.scene == 'tabletop']
        rows = [b.by_model[name] for b in sel]
        reported = [row['best_score'] >= SACCADE_MIN_SCORE for row in rows]
        out[f'background_{scope.replace(" ", "_")}'] = {
            'fixations': len(sel),
            'called_background': r([row['top1'] == reject for row in rows]),
            'pass1_reports_an_object': r([row['pass1_reports'] for row in rows]),
            'two_pass_object_reported': r(reported),
            'two_pass_report_far_from_objects': r([
                rep and row['best_distance_px'] > FAR_PX
                for rep, row in zip(reported, rows, strict=True)])}
    every = [c.by_model[name] for c in cases]
    out['cpu_ms'] = {'classify_one_fixation': round(1000 * float(np.mean(
                         [row['classify_s'] for row in every])), 2),
                     'two_pass_recognition': round(1000 * float(np.mean(
                         [c.by_model[name]['two_pass_s'] for c in objects])), 1)}
    return out


def cpu_per_window(clf: Classifier, image: np.ndarray, repeats: int = 30) -> dict[str, float]:
    """Process CPU ms of one classification (one window or image), of a batch of 6 and, for a
    window model, of grid_recognition over the frame (uniform baseline)."""
    fixes = [(100.0 + 60 * i, 240.0) for i in range(6)]
    clf.classify(image, fixes[:1])
    _, one = _timed(lambda: [clf.classify(image, fixes[:1]) for _ in range(repeats)])
    _, six = _timed(lambda: [clf.classify([image] * 6, fixes) for _ in range(repeats // 3)])
    out = {'one': round(1000 * one / repeats, 2), 'batch_of_6': round(1000 * six / (repeats // 3),
                                                                      2)}
    if clf.window:
        _, grid = _timed(lambda: [grid_recognition(clf, image, GRID_STRIDE) for _ in range(3)])
        out['grid_recognition_frame'] = round(1000 * grid / 3, 1)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--model', type=Path, default=MODELS / 'fovea_cnn.pt')
    parser.add_argument('--baseline', type=Path, default=MODELS / 'foveation_cnn.pt')
    parser.add_argument('--tabletop-scenes', type=int, default=40)
    parser.add_argument('--search-scenes', type=int, default=20)
    parser.add_argument('--quick', action='store_true', help='4 + 2 scenes')
    parser.add_argument('--out', type=Path, default=ROOT / 'experiments' / 'results')
    parser.add_argument('--update-report', action='store_true',
                        help="write the figures into --model's JSON (key 'evaluation')")
    args = parser.parse_args()
    import cv2
    import torch

    from foveation_node.training.object_views import CLASSES

    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    if args.quick:
        args.tabletop_scenes, args.search_scenes = 4, 2
    t0 = time.perf_counter()
    models = {'whole_frame': Classifier(args.baseline, args.baseline.with_suffix('.labels')),
              'window': Classifier(args.model, args.model.with_suffix('.labels'))}
    cases = run(models, args.tabletop_scenes, args.search_scenes)
    rel = lambda p: (str(p.resolve().relative_to(ROOT))  # noqa: E731
                     if p.resolve().is_relative_to(ROOT) else str(p))
    result: dict[str, Any] = {
        'seeds': {'tabletop': [SEED0, SEED0 + args.tabletop_scenes - 1],
                  'visual_search': [SEED0, SEED0 + args.search_scenes - 1]},
        'image': [W, H], 'levels': LEVELS, 'f0_px': F0, 'top_k': TOP_K, 'threshold': TH,
        'saccade_min_score': SACCADE_MIN_SCORE, 'background_min_distance_px': BACKGROUND_MIN_PX,
        'far_px': FAR_PX,
        'models': {'whole_frame': rel(args.baseline), 'window': rel(args.model)},
        'by_model': {}}
    frame = np.random.default_rng(0).integers(0, 256, (H, W, 3), dtype=np.uint8)
    for name, clf in models.items():
        result['by_model'][name] = summarise(cases, name, list(CLASSES), clf.reject_class)
        result['by_model'][name]['cpu_ms'].update(cpu_per_window(clf, frame))
    result['seconds'] = round(time.perf_counter() - t0, 1)
    n_ob = sum(c.kind == 'object' for c in cases)
    n_bg = len(cases) - n_ob
    result['protocol'] = protocol(
        data=f'held-out left-eye renders (tabletop seeds {SEED0}..'
             f'{SEED0 + args.tabletop_scenes - 1}, visual_search seeds {SEED0}..'
             f'{SEED0 + args.search_scenes - 1}): the head '
             f'fixating each object ({n_ob} fixations), {n_bg} background fixations',
        repetitions={'objects': n_ob, 'background': n_bg}, thesis_repetitions=None,
        models=f'whole_frame: {rel(args.baseline)}; window: {rel(args.model)}',
        differs_from_thesis=['the thesis\'s ImageNet CNNs see the whole foveated image; the '
                             'window model sees the 160 px around the fixation'],
        cpu_s=cpu_seconds(), machine=f'{os.cpu_count()} CPUs, torch {torch.__version__}, '
                                     '1 thread')
    args.out.mkdir(parents=True, exist_ok=True)
    stem = result_stem('window_model', args.quick)
    (args.out / f'{stem}.json').write_text(json.dumps(result, indent=1) + '\n')
    for name in models:
        m = result['by_model'][name]
        o, b = m['objects_all'], m['background_all']
        print(f"{name}: objects {o['fixations']}: top-1 {o['top1']} (rejected "
              f"{o['rejected_as_background']}), two-pass right {o['two_pass_final_label_right']}"
              f" (nothing {o['two_pass_nothing_reported']}); background {b['fixations']}: called "
              f"background {b['called_background']}, far reports "
              f"{b['two_pass_report_far_from_objects']}; per class "
              f"{m['objects_per_class_top1']}; cpu {m['cpu_ms']}")
    if args.update_report:
        path = args.model.with_suffix('.json')
        report = json.loads(path.read_text(encoding='utf-8'))
        report['evaluation'] = {'script': f'experiments/window_model.py'
                                          f'{" --quick" if args.quick else ""}',
                                **{k: v for k, v in result.items() if k != 'protocol'}}
        path.write_text(json.dumps(report, indent=1) + '\n', encoding='utf-8')
        print(f'updated {path}')
    print(f'{result["seconds"]:.0f} s; wrote {args.out / stem}.json')
    return 0 if math.isfinite(result['seconds']) else 1


if __name__ == '__main__':
    sys.exit(main())
