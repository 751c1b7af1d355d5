#!/usr/bin/env python3
"""The budgeted tracker against ByteTrack on the same HOG detections. Last line: JSON.

    .venv/bin/python bench/mot_peers.py [--mot ../shared/data/mot17-mini] [--sim-seeds 0 1 2 3 4 5]
        [--seeds 0 1 2 3 4] [--sim-frames 300] [--budget-iterations 100] [--k-max 3] [--s-max 0.1]
        [--horizon T]
        [--birth-share B] [--report-misses N] [--scale-accel-std A] [--init-scale-velocity-std V]
        [--occluded-share O] [--tentative-misses N] [--region-hit-threshold T]
        [--read-upsample U] [--sim-area X0 X1 Y0 Y1]

Peer: ByteTrack (``trackers.ByteTrackTracker``, Roboflow's maintained re-implementation; the
``supervision`` package dropped its own ByteTrack in 0.27) fed with OpenCV's HOG people
detector run on every *full* frame. Ours: the deployed configuration of mot_planner (the
node's defaults: S_max binds the pixels the detector reads, new tracks from full-frame
detections paid from the budget, ``core/tracker.py``), HOG run only on the regions it plans,
with a deterministic planning budget of ``--budget-iterations`` MCTS runs per frame (same
numbers every run), once per MCTS seed of ``--seeds``: ours is reported as the mean over the
seeds (``ours``; each seed's in ``ours_per_seed``), since one seed moves street MOTA by up to
0.1. Both are scored by the same code (``core/metrics.py``, py-motmetrics
CLEAR MOT and IDF1, IoU >= 0.5) and both use the same detector boxes (HOG windows through
the same box shrink). Also reported: our tracker on the full-frame detections (``ours_full``).

ByteTrack's thresholds are on the detector's confidence; HOG's SVM scores are not in [0, 1],
so ByteTrack gets the raw scores and its two thresholds (``track_activation_threshold``,
``high_conf_det_threshold``) are searched over a grid of HOG score quantiles on each group of
sequences; the best by MOTA (then IDF1) is reported (``bytetrack_best``: tuned on the test
data itself, generous to the peer), with the grid point its defaults correspond to in rank
(``bytetrack_default_rank``).

Data: ``--mot`` MOTChallenge sequences (mot17-mini: seven MOT17 sequences of 4-8 frames), and
the simulator's pedestrians scene rendered to MOTChallenge folders (experiments/mot_budget.py
``render_sim_sequence``: left eye, head at rest, 640x480, 30 frames/s, 6 walkers, one
sequence per ``--sim-seeds`` value; ``--sim-area`` widens where they walk so that people
leave the view and come back; needs MuJoCo). Full-frame HOG detections and their CPU
time are cached under ``--cache`` (experiments/cache/, not in git).

Measured: per group and per sequence MOTA, IDF1, ID switches, MOTP; the share of each frame
the detector read (``read_fraction_mean`` over all frames, ``read_fraction_max_tracking`` over
the frames that were no full frame); detector CPU time per frame (time.process_time around
each HOG call, all its threads: steadier than wall time on a shared machine).

Skips (one line on stderr, ``{"skipped": ...}`` as the JSON) when ``trackers`` is missing:
it is a bench dependency only.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / 'experiments' / 'cache'


def skip(reason: str) -> None:
    print(f'mot_peers: skipped: {reason}', file=sys.stderr)
    print(json.dumps({'skipped': reason}), flush=True)
    sys.exit(0)


try:
    import supervision as sv
    from trackers import ByteTrackTracker
except ImportError as exc:                                   # bench dependency only
    skip(f'ByteTrack peer not installed ({exc}); pip install trackers==2.6.1 '
         'supervision==0.31.2')

from mot_planner_node.core.detector import Detections, HogDetector  # noqa: E402
from mot_planner_node.core.kalman import MotionModel  # noqa: E402
from mot_planner_node.core.metrics import MotEvaluator, summarize  # noqa: E402
from mot_planner_node.core.motchallenge import Sequence, find_sequences, load_sequence  # noqa: E402
from mot_planner_node.core.planner import PlannerConfig  # noqa: E402
from mot_planner_node.core.tracker import DEPLOYED, MotTracker, TrackerConfig, deployed_config  # noqa: E402
from mot_planner_node.evaluate import finite_or_none, read_frame  # noqa: E402


class CachedFullFrames:
    """HOG with the full-frame detections of a sequence precomputed: a full-frame call returns
    frame ``self.frame``'s and charges its measured CPU time; region calls run HOG and are
    timed. ``cpu_s`` collects the CPU time per call."""

    def __init__(self, hog: HogDetector, full: list[Detections], full_cpu: list[float]) -> None:
        self.hog, self.full, self.full_cpu = hog, full, full_cpu
        self.geometry, self.box_shrink = hog.geometry, hog.box_shrink
        self.frame = 0
        self.cpu_s = 0.0

    def detect(self, image: np.ndarray, regions: np.ndarray | None = None) -> Detections:
        if regions is None:
            self.cpu_s += self.full_cpu[self.frame]
            return self.full[self.frame]
        c0 = time.process_time()
        det = self.hog.detect(image, regions)
        self.cpu_s += time.process_time() - c0
        return det


def full_frame_detections(seq: Sequence, images: list[np.ndarray], hog: HogDetector,
                          cache: Path) -> tuple[list[Detections], list[float]]:
    """HOG on every full frame (boxes, scores, CPU seconds), cached per sequence."""
    key = cache / f'hog_full_{seq.name}_{len(images)}f.npz'
    if key.is_file():
        z = np.load(key)
        counts = z['counts']
        splits = np.cumsum(counts)[:-1]
        return ([Detections(b, s) for b, s in zip(np.split(z['boxes'], splits),
                                                    np.split(z['scores'], splits),
                                                    strict=True)],
                [float(c) for c in z['cpu']])
    dets, cpu = [], []
    for image in images:
        c0 = time.process_time()
        dets.append(hog.detect(image))
        cpu.append(time.process_time() - c0)
    cache.mkdir(parents=True, exist_ok=True)
    np.savez(key, boxes=np.concatenate([d.boxes.reshape(-1, 4) for d in dets]),
             scores=np.concatenate([d.scores.reshape(-1) for d in dets]),
             counts=np.array([len(d.scores) for d in dets]), cpu=np.array(cpu))
    return dets, cpu


def run_ours(seq: Sequence, images: list[np.ndarray], det: CachedFullFrames,
             cfg: TrackerConfig) -> tuple[MotEvaluator, dict[str, Any]]:
    tracker = MotTracker(det, cfg)
    ev = MotEvaluator()
    read, full, cpu, covered = [], [], [], []
    for i, image in enumerate(images):
        det.frame, det.cpu_s = i, 0.0
        r = tracker.step(image)
        read.append(r.processed_fraction)
        covered.append(r.covered_fraction)
        full.append(r.full_frame)
        cpu.append(det.cpu_s)
        ids, boxes, distractors = seq.gt.frame(i + 1)
        ev.update(i + 1, ids, boxes, r.ids, r.boxes, distractors)
    return ev, {'read': read, 'full': full, 'cpu': cpu, 'covered': covered}


def run_bytetrack(seq: Sequence, dets: list[Detections], shrink: Any, fps: float,
                  activation: float, high: float) -> MotEvaluator:
    bt = ByteTrackTracker(frame_rate=fps, track_activation_threshold=activation,
                          high_conf_det_threshold=high)
    ev = MotEvaluator()
    for i, d in enumerate(dets):
        boxes = shrink.apply(d.boxes)                          # the same object boxes as ours
        xyxy = np.concatenate([boxes[:, :2], boxes[:, :2] + boxes[:, 2:]], axis=1)
        out = bt.update(sv.Detections(xyxy=xyxy.reshape(-1, 4).astype(np.float32),
                                      confidence=d.scores.astype(np.float32),
                                      class_id=np.zeros(len(d.scores), int)))
        keep = np.asarray(out.tracker_id) >= 0
        xy = np.asarray(out.xyxy, float).reshape(-1, 4)[keep]
        hyp = np.concatenate([xy[:, :2], xy[:, 2:] - xy[:, :2]], axis=1)
        ids, gt_boxes, distractors = seq.gt.frame(i + 1)
        ev.update(i + 1, ids, gt_boxes, np.asarray(out.tracker_id)[keep], hyp, distractors)
    return ev


METRICS = ('mota', 'idf1', 'num_switches', 'motp', 'num_false_positives', 'num_misses',
           'num_objects')


def pick(m: dict[str, Any]) -> dict[str, Any]:
    return {k: (round(m[k], 4) if isinstance(m[k], float) else m[k]) for k in METRICS}


def mean_metrics(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """The mean over MCTS seeds of each metric :func:`pick` keeps (one seed moves MOTA by
    up to 0.1 on the street: single runs are noise)."""
    return {k: round(float(np.mean([r[k] for r in runs])), 4) for k in METRICS}


def group(name: str, seqs: list[Sequence], args: argparse.Namespace,
          cfgs: list[TrackerConfig]) -> dict[str, Any]:
    """Ours with each of ``cfgs`` (one per MCTS seed), ours on full frames and ByteTrack's
    threshold grid, on the sequences ``seqs``."""
    cfg = cfgs[0]
    hog = HogDetector(region_hit_threshold=args.region_hit_threshold,
                      upsample=args.read_upsample)
    ours: list[dict[str, MotEvaluator]] = [{} for _ in cfgs]       # per MCTS seed
    ours_full: dict[str, MotEvaluator] = {}
    stats: dict[str, dict[str, Any]] = {}       # per sequence, all seeds' frames
    data = {}
    full_cfg = replace(cfg, mode='full')       # the same tracker, detections on every frame
    for seq in seqs:
        images = [read_frame(seq, i)[0] for i in range(len(seq))]
        if any(im is None for im in images):
            raise SystemExit(f'mot_peers: {seq.path}: a frame cannot be read')
        dets, cpu = full_frame_detections(seq, images, hog, args.cache)
        data[seq.name] = (seq, dets, cpu)
        runs = []
        for k, c in enumerate(cfgs):
            ours[k][seq.name], st = run_ours(seq, images, CachedFullFrames(hog, dets, cpu), c)
            runs.append(st)
        stats[seq.name] = {key: [v for st in runs for v in st[key]] for key in runs[0]}
        stats[seq.name]['after'] = [v for st in runs for v in st['read'][1:]]
        stats[seq.name]['cpu_after'] = [v for st in runs for v in st['cpu'][1:]]
        ours_full[seq.name], _ = run_ours(seq, images, CachedFullFrames(hog, dets, cpu),
                                          full_cfg)
        print(f'{name}: {seq.name} done', file=sys.stderr, flush=True)
    scores = np.concatenate([d.scores for _, dets, _ in data.values() for d in dets])
    quantiles = np.quantile(scores, args.quantiles) if scores.size else np.zeros(1)
    grid = []
    for ai, a in enumerate(quantiles):
        for h in quantiles[:ai + 1]:                 # high-confidence split <= activation
            evs = {n: run_bytetrack(s, d, hog.box_shrink, s.frame_rate or 30.0, float(a),
                                    float(h)) for n, (s, d, _) in data.items()}
            m = summarize(evs)
            grid.append({'activation': round(float(a), 4), 'high': round(float(h), 4),
                         'metrics': m})
    best = max(grid, key=lambda g: (g['metrics']['OVERALL']['mota'] or -1e9,
                                    g['metrics']['OVERALL']['idf1'] or 0.0))
    m_seeds = [summarize(o) for o in ours]
    m_full = summarize(ours_full)
    read = np.concatenate([stats[n]['read'] for n in stats])
    full = np.concatenate([stats[n]['full'] for n in stats]).astype(bool)
    cpu_ours = np.concatenate([stats[n]['cpu'] for n in stats])
    covered = np.concatenate([stats[n]['covered'] for n in stats])
    cpu_full = np.concatenate([c for _, _, c in data.values()])
    per_seq = {}
    for n in data:
        r = np.asarray(stats[n]['read'])
        f = np.asarray(stats[n]['full'], bool)
        per_seq[n] = {
            'frames': len(data[n][0]), 'ours': mean_metrics([pick(m[n]) for m in m_seeds]),
            'ours_mota_per_seed': [round(m[n]['mota'], 4) for m in m_seeds],
            'bytetrack_best': pick(best['metrics'][n]),
            'ours_full': pick(m_full[n]),
            'read_fraction_mean': round(float(r.mean()), 4),
            'read_fraction_max_tracking': round(float(r[~f].max()), 4) if (~f).any() else None,
            'full_frames': round(float(f.sum()) / len(cfgs), 1),
            'covered_fraction_mean': round(float(np.mean(stats[n]['covered'])), 4),
            'detector_cpu_ms_ours': round(1e3 * float(np.mean(stats[n]['cpu'])), 2),
            'detector_cpu_ms_full': round(1e3 * float(np.mean(data[n][2])), 2)}
    return {
        'sequences': len(seqs), 'frames': int(read.size) // len(cfgs),
        'mcts_seeds': [c.planner.seed for c in cfgs],
        'ours': mean_metrics([pick(m['OVERALL']) for m in m_seeds]),
        'ours_per_seed': [pick(m['OVERALL']) for m in m_seeds],
        'bytetrack_best': pick(best['metrics']['OVERALL']),
        'bytetrack_best_thresholds': {'activation': best['activation'], 'high': best['high']},
        'bytetrack_grid': [{'activation': g['activation'], 'high': g['high'],
                            'mota': round(g['metrics']['OVERALL']['mota'], 4),
                            'idf1': round(g['metrics']['OVERALL']['idf1'], 4)} for g in grid],
        'ours_full': pick(m_full['OVERALL']),
        'read_fraction_mean': round(float(read.mean()), 4),
        'read_fraction_mean_after_bootstrap': round(float(np.mean(
            np.concatenate([stats[n]['after'] for n in stats]))), 4),
        'read_fraction_max_tracking': (round(float(read[~full].max()), 4) if (~full).any()
                                       else None),
        'full_frames': round(float(full.sum()) / len(cfgs), 1),
        'covered_fraction_mean': round(float(covered.mean()), 4),
        'covered_fraction_max_tracking': (round(float(covered[~full].max()), 4)
                                          if (~full).any() else None),
        'detector_cpu_ms_per_frame_ours': round(1e3 * float(cpu_ours.mean()), 2),
        'detector_cpu_ms_per_frame_full': round(1e3 * float(cpu_full.mean()), 2),
        'detector_cpu_ratio_full_over_ours': round(float(cpu_full.mean() / cpu_ours.mean()), 2),
        # frames 2..n of each sequence: both read the first frame whole
        'detector_cpu_ms_after_bootstrap_ours': round(1e3 * float(np.mean(np.concatenate(
            [stats[n]['cpu_after'] for n in stats]))), 2),
        'detector_cpu_ms_after_bootstrap_full': round(1e3 * float(np.mean(np.concatenate(
            [c[1:] for _, _, c in data.values()]))), 2),
        'per_sequence': per_seq,
    }


def sim_sequences(args: argparse.Namespace) -> list[Sequence]:
    sys.path.insert(0, str(ROOT / 'experiments'))
    try:
        from mot_budget import render_sim_sequence
        area = None
        if args.sim_area:
            x0, x1, y0, y1 = args.sim_area
            area = ((x0, x1), (y0, y1))
        paths = [render_sim_sequence(args.cache, s, args.sim_people, args.sim_frames, 30.0,
                                     area=area)
                 for s in args.sim_seeds]
    except ImportError as exc:
        print(f'mot_peers: no simulated sequences ({exc})', file=sys.stderr)
        return []
    return [load_sequence(p) for p in paths]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--mot', type=Path, default=ROOT.parent / 'shared' / 'data' / 'mot17-mini',
                   help='MOTChallenge sequence folder or folder of them (skipped if missing)')
    p.add_argument('--sim-seeds', type=int, nargs='*', default=[0, 1, 2, 3, 4, 5],
                   help='simulated street sequences (scene seeds; none: skip the simulator). Six '
                        'by default: on two, one MCTS seed moves MOTA by up to 0.2')
    p.add_argument('--sim-frames', type=int, default=300)
    p.add_argument('--sim-people', type=int, default=6)
    p.add_argument('--sim-area', type=float, nargs=4, metavar=('X0', 'X1', 'Y0', 'Y1'),
                   help='where the simulated people walk [m] (world x forward, y left; '
                        'default: the scene\'s, everyone always in view)')
    p.add_argument('--k-max', type=int, default=3)
    p.add_argument('--s-max', type=float, default=0.1)
    p.add_argument('--budget-iterations', type=int, default=100)
    p.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2, 3, 4],
                   help='MCTS seeds: ours runs once per seed and the figures are their mean '
                        '(one seed moves MOTA by up to 0.1 on the street)')
    p.add_argument('--area', default=DEPLOYED['area'])
    p.add_argument('--horizon', type=int, default=DEPLOYED['horizon'],
                   help='planning horizon T, the MCTS depth (default: the deployed one)')
    p.add_argument('--birth-share', type=float, default=DEPLOYED['birth_share'])
    p.add_argument('--period', type=int, default=DEPLOYED['full_frame_period'])
    p.add_argument('--report-misses', type=int, default=DEPLOYED['report_misses'])
    p.add_argument('--birth-score', type=float, default=DEPLOYED['birth_score'])
    p.add_argument('--occluded-share', type=float, default=DEPLOYED['occluded_share'],
                   help='occlusion reasoning share (0: none; default: the deployed one)')
    p.add_argument('--tentative-misses', type=int, default=DEPLOYED['tentative_misses'],
                   help='misses a new track survives before it is confirmed (default: the '
                        'deployed number)')
    p.add_argument('--region-hit-threshold', type=float,
                   default=DEPLOYED['region_hit_threshold'],
                   help="HOG's SVM threshold in the tracks' regions (default: the deployed one; "
                        'full frames, and so ByteTrack, keep 0)')
    p.add_argument('--read-upsample', type=float, default=DEPLOYED['read_upsample'],
                   help='regions read at this many times their smallest scale and enlarged '
                        'back (default: the deployed factor)')
    p.add_argument('--scale-accel-std', type=float, default=DEPLOYED['scale_accel_std'],
                   help='relative scale acceleration std per frame^2 of the motion model '
                        '(default: the deployed one)')
    p.add_argument('--init-scale-velocity-std', type=float,
                   default=DEPLOYED['init_scale_velocity_std'],
                   help='relative scale-velocity std of a new track (default: the deployed one)')
    p.add_argument('--quantiles', type=float, nargs='+', default=[0.0, 0.2, 0.4, 0.6, 0.8],
                   help='HOG score quantiles for the ByteTrack threshold grid')
    p.add_argument('--cache', type=Path, default=CACHE)
    args = p.parse_args()
    cfg = deployed_config(PlannerConfig(k_max=args.k_max, s_max=args.s_max, budget_ms=None,
                                        max_iterations=args.budget_iterations),
                          full_frame_period=args.period, birth_share=args.birth_share,
                          report_misses=args.report_misses, birth_score=args.birth_score,
                          occluded_share=args.occluded_share or None,
                          tentative_misses=args.tentative_misses,
                          init_scale_velocity_std=args.init_scale_velocity_std,
                          motion=replace(MotionModel(), scale_accel_std=args.scale_accel_std),
                          area=args.area, horizon=args.horizon)
    cfgs = [replace(cfg, planner=replace(cfg.planner, seed=seed)) for seed in args.seeds]
    t0, c0 = time.perf_counter(), time.process_time()
    out: dict[str, Any] = {'config': {k: str(v) if isinstance(v, Path) else v
                                      for k, v in vars(args).items()}}
    if args.mot.is_dir():
        seqs = [load_sequence(s) for s in find_sequences(args.mot)]
        out['mot'] = group('mot', seqs, args, cfgs)
    else:
        print(f'mot_peers: {args.mot}: not found, MOTChallenge part skipped', file=sys.stderr)
    if args.sim_seeds:
        seqs = sim_sequences(args)
        if seqs:
            out['sim'] = group('sim', seqs, args, cfgs)
    for g in ('mot', 'sim'):
        if g in out:
            o, b = out[g]['ours'], out[g]['bytetrack_best']
            out[f'{g}_mota_ours'], out[f'{g}_mota_bytetrack'] = o['mota'], b['mota']
            out[f'{g}_idf1_ours'], out[f'{g}_idf1_bytetrack'] = o['idf1'], b['idf1']
            out[f'{g}_read_fraction_mean'] = out[g]['read_fraction_mean']
            out[f'{g}_read_fraction_after_bootstrap'] = (
                out[g]['read_fraction_mean_after_bootstrap'])
            out[f'{g}_covered_fraction_mean'] = out[g]['covered_fraction_mean']
            out[f'{g}_detector_cpu_ratio'] = out[g]['detector_cpu_ratio_full_over_ours']
            per_seed = ', '.join(f'{r["mota"]:.3f}' for r in out[g]['ours_per_seed'])
            out[f'{g}_mota_ours_per_seed'] = [r['mota'] for r in out[g]['ours_per_seed']]
            print(f'{g}: ours (mean of {len(args.seeds)} MCTS seeds; MOTA {per_seed}) MOTA '
                  f'{o["mota"]:.3f} IDF1 {o["idf1"]:.3f} IDSW '
                  f'{o["num_switches"]:g} | ByteTrack (best) MOTA {b["mota"]:.3f} IDF1 '
                  f'{b["idf1"]:.3f} IDSW {b["num_switches"]} | read {out[g]["read_fraction_mean"]}'
                  f' of the image ({out[g]["read_fraction_mean_after_bootstrap"]} after the '
                  'first frame, which both read whole), detector CPU '
                  f'{out[g]["detector_cpu_ratio_full_over_ours"]}x less', file=sys.stderr)
    out['cpu_s'] = round(time.process_time() - c0, 1)
    out['wall_s'] = round(time.perf_counter() - t0, 1)
    out['load_avg_1min'] = round(os.getloadavg()[0], 2)
    print(json.dumps(finite_or_none(out), allow_nan=False), flush=True)


if __name__ == '__main__':
    main()
