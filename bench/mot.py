#!/usr/bin/env python3
"""Benchmark of the resource-constrained tracker (thesis chapter 5). Last line: JSON.

    .venv/bin/python bench/mot.py [--frames 200] [--seeds 0 1 2] [--k-max 3]

What it measures (on a synthetic scene, so that it runs in seconds without a renderer; the
simulator's pedestrians are in experiments/mot_budget.py --sim):

1. Tracking: a synthetic 640x480 street (:class:`SyntheticScene`, 8 people 100-170 px tall
   walking at about 1 px/frame, as in the thesis's TUD-Stadtmitte set-up) seen by the
   simulated sliding-window detector (:class:`SimulatedDetector`: HOG's 64x128 window,
   8 px stride, 1.05 scale step, quantized boxes, 95 % detection, 0.5 false positives per
   full frame, occlusion). The tracker runs twice per seed with the thesis protocol
   (bootstrap on frame 1, no track births after it): detector on every full frame, and the
   MCTS planner with K_max, S_max = 0.1, --budget-iterations MCTS runs per plan (evaluate's
   default; --wall-clock: a 10 ms budget as the node). ``motp_delta_vs_full`` is the
   planner's MOTP minus the full-frame MOTP (thesis Eq. 5.26: percent overlap, averaged over
   seeds); ``plan_ms_p95`` is the 95th percentile of the planner's wall time per frame.
2. Detector time: OpenCV's HOG people detector (the default plug-in) is run for real on a
   rendering of each frame (textured background, a blob per person; HOG's cost hardly
   depends on content) over exactly the regions the planner chose that frame, and over the
   full frame (every 10th frame: its cost is constant). ``detector_speedup_at_smax_0.1`` =
   mean full-frame HOG time / mean planner HOG time per frame, frames 2..n, in the thesis
   protocol (no births after the first frame). ``detector_speedup_deployed``: the same for the
   node's own protocol (tracker.DEPLOYED: new people are born from full frames paid from the
   S_max budget, the regions get the rest), the saving the node really makes;
   ``mota_deployed`` / ``idf1_deployed`` per seed beside the thesis protocol's.
3. ``frame_ms``: mean per-frame time of the planner pipeline = tracker step (prediction,
   planning, association, update) without the simulated detector + the HOG time on that
   frame's regions.

Timings depend on the machine and its load (reported as ``load_avg_1min``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

from mot_planner_node.core.detector import HogDetector
from mot_planner_node.core.planner import PlannerConfig
from mot_planner_node.core.regions import read_area
from mot_planner_node.core.simulated import render, replay_detector_time, track_synthetic
from mot_planner_node.core.tracker import DEPLOYED, NOT_TRACKER_TERMS, TrackerConfig
from mot_planner_node.evaluate import DEFAULT_BUDGET_ITERATIONS

SIZE = (640, 480)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--frames', type=int, default=200)
    p.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2])
    p.add_argument('--k-max', type=int, default=3)
    p.add_argument('--s-max', type=float, default=0.1)
    p.add_argument('--budget-iterations', type=int,
                   default=DEFAULT_BUDGET_ITERATIONS['thesis'],
                   help='MCTS runs per plan (the same plans at any load; the deployed run: '
                        f"{DEFAULT_BUDGET_ITERATIONS['deployed']}, its shorter horizon)")
    p.add_argument('--wall-clock', action='store_true',
                   help='plan for --budget-ms of wall time instead, as the node does')
    p.add_argument('--budget-ms', type=float, default=10.0)
    p.add_argument('--full-every', type=int, default=10,
                   help='time full-frame HOG on every n-th frame')
    args = p.parse_args()

    hog = HogDetector()
    motp_delta, plan_ms, frame_ms, full_det, plan_det = [], [], [], [], []
    deployed_det: list[float] = []
    per_seed = []
    t_start = time.perf_counter()
    load_start = os.getloadavg()[0]
    for seed in args.seeds:
        budget = ({'budget_ms': args.budget_ms} if args.wall_clock
                  else {'budget_ms': None, 'max_iterations': args.budget_iterations})
        planner = PlannerConfig(k_max=args.k_max, s_max=args.s_max, seed=seed, **budget)
        deployed_budget = ({'budget_ms': args.budget_ms} if args.wall_clock
                           else {'budget_ms': None,
                                 'max_iterations': DEFAULT_BUDGET_ITERATIONS['deployed']})
        full = track_synthetic(TrackerConfig(mode='full', new_tracks='none', planner=planner),
                               n_frames=args.frames, seed=seed, image_size=SIZE)
        plan = track_synthetic(TrackerConfig(mode='planner', new_tracks='none', planner=planner),
                               n_frames=args.frames, seed=seed, image_size=SIZE)
        # the node's own protocol: births from full frames paid from the budget (the regions
        # get (1 - birth_share) S_max), the read area at the detector's scale
        deployed = track_synthetic(
            TrackerConfig(mode='planner', planner=PlannerConfig(
                k_max=args.k_max, s_max=args.s_max, seed=seed, area=DEPLOYED['area'],
                depth=DEPLOYED['horizon'], **deployed_budget),
                **{k: v for k, v in DEPLOYED.items() if k not in NOT_TRACKER_TERMS}),
            n_frames=args.frames, seed=seed, image_size=SIZE)
        images = [render(f, SIZE, seed) for f in plan.frames]
        det_plan = replay_detector_time(hog, images[1:], plan.regions[1:])
        deployed_det += replay_detector_time(hog, images[1:], deployed.regions[1:])
        idx = list(range(1, args.frames, args.full_every))
        det_full = replay_detector_time(hog, [images[i] for i in idx], [None] * len(idx))
        plan_det += det_plan
        full_det += det_full
        plan_ms += [1e3 * s for s in plan.plan_s[1:]]
        frame_ms += [1e3 * (s + d) for s, d in zip(plan.step_s[1:], det_plan, strict=True)]
        motp_delta.append(plan.metrics['motp'] - full.metrics['motp'])
        per_seed.append({
            'seed': seed,
            'motp_planner': round(plan.metrics['motp'], 3),
            'motp_full': round(full.metrics['motp'], 3),
            'mota_planner': round(plan.metrics['mota'], 3),
            'mota_full': round(full.metrics['mota'], 3),
            'idf1_planner': round(plan.metrics['idf1'], 3),
            'idf1_full': round(full.metrics['idf1'], 3),
            'mota_deployed': round(deployed.metrics['mota'], 3),
            'idf1_deployed': round(deployed.metrics['idf1'], 3),
            # the union of the crops HOG reads (overlaps once), frames 2..n
            'processed_fraction': round(float(np.mean(
                [read_area(r, SIZE) / (SIZE[0] * SIZE[1]) for r in plan.regions[1:]])), 4),
        })
        print(f'seed {seed}: MOTP planner {plan.metrics["motp"]:.2f} / full '
              f'{full.metrics["motp"]:.2f}; HOG {1e3 * np.mean(det_plan):.1f} ms / '
              f'{1e3 * np.mean(det_full):.1f} ms', file=sys.stderr, flush=True)

    summary = {
        'detector_speedup_at_smax_0.1': round(float(np.mean(full_det) / np.mean(plan_det)), 2),
        # with the births the node pays for (full frames from the budget): its real saving
        'detector_speedup_deployed': round(float(np.mean(full_det) / np.mean(deployed_det)), 2),
        'deployed_detector_ms': round(1e3 * float(np.mean(deployed_det)), 3),
        'motp_delta_vs_full': round(float(np.mean(motp_delta)), 3),
        'plan_ms_p95': round(float(np.percentile(plan_ms, 95)), 3),
        'frame_ms': round(float(np.mean(frame_ms)), 3),
        'planner_detector_ms': round(1e3 * float(np.mean(plan_det)), 3),
        'full_frame_detector_ms': round(1e3 * float(np.mean(full_det)), 3),
        'plan_ms_p50': round(float(np.percentile(plan_ms, 50)), 3),
        'budget_ms': args.budget_ms if args.wall_clock else None,
        'budget_iterations': None if args.wall_clock else args.budget_iterations,
        'k_max': args.k_max,
        's_max': args.s_max,
        'frames': args.frames,
        'per_seed': per_seed,
        'image_size': list(SIZE),
        'load_avg_1min': round(os.getloadavg()[0], 2),
        'load_avg_1min_start': round(load_start, 2),
        'cpus': os.cpu_count(),
        'wall_s': round(time.perf_counter() - t_start, 1),
    }
    print(f'detector {summary["detector_speedup_at_smax_0.1"]}x less time than full frame '
          f'(thesis protocol; {summary["detector_speedup_deployed"]}x with the node\'s births); '
          f'MOTP delta {summary["motp_delta_vs_full"]:+.2f} points; plan p95 '
          f'{summary["plan_ms_p95"]} ms', file=sys.stderr, flush=True)
    print(json.dumps(summary), flush=True)


if __name__ == '__main__':
    main()
