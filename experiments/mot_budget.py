#!/usr/bin/env python3
"""Thesis Fig. 5.3: detector time and MOTP against the attention budget (K_max, S_max).

    .venv/bin/python experiments/mot_budget.py --motchallenge ../shared/data/mot17-mini
    .venv/bin/python experiments/mot_budget.py --synthetic [--frames 150]
    .venv/bin/python experiments/mot_budget.py --sim --new-tracks periodic --trials 20 \
        --s-max 0.1 0.2 0.4 0.7 1.0 --area centres pixels --iterations 200 --jobs 2
        # the run in docs/results.md (9519 s CPU)

For every K_max in {1, 2, 3, 4} and S_max in [0.1, 1.0] the planner tracks the sequences
``--trials`` times (different MCTS seeds; the thesis ran 100), against the full-frame
baseline (detector on every full frame). ``--area`` names one or more readings of S_max run
side by side (``centres``, the thesis's; ``pixels``, the window-inclusive one). HOG runs
single-threaded and its time is CPU time per frame, so ``--jobs`` worker processes do not
distort it; ``--iterations`` replaces the 10 ms wall-clock planning budget by a fixed number
of MCTS iterations, so a trial does not depend on the machine's load either. ``--plot-only``
redraws the plot from the JSON. By default tracking follows the thesis protocol:
tracks start from a full-frame detection on the first frame, none are created later. With
``--new-tracks periodic`` (MOTChallenge and sim) the planner also starts tracks from a
full-frame detection every 30 frames, charged at the baseline's full-frame detector time (the
runs share cached full-frame detections), and the baseline from its detections on any frame;
``detector_ms_planned_frames`` is the planner's time on the other frames. With
``--new-tracks budget`` (the deployed configuration, S_max counting ``--area`` pixels) the
full frames are paid from the S_max budget and come when the savings allow.

- ``--motchallenge DIR``: MOTChallenge sequences (a sequence folder or a folder of them) with
  OpenCV's HOG people detector. The first frame's full-frame detection is computed once per
  sequence and shared by all runs; detector time is per frame from frame 2 on.
- ``--synthetic``: the benchmark's synthetic street (bench/mot.py) with the simulated
  detector for tracking; detector time is HOG's, run for real on each frame's chosen regions
  (see bench/mot.py).
- ``--sim``: the simulator's pedestrians scene (vizzy_sim_bridge, ``--seed``, ``--people``
  walkers) rendered in-process (MuJoCo offscreen, no ROS) from the left eye with the head at
  rest, ``--frames`` at ``--fps``, written once as a MOTChallenge folder under
  ``--cache`` (default experiments/cache/, not in git; reused when the parameters match):
  img1/*.jpg and gt/gt.txt, whose boxes are each walker's geoms projected into the image
  (what the sim publishes on /sim/ground_truth/left/pedestrians), clipped to the image, with
  the fraction inside the image as visibility. Then as ``--motchallenge`` on that folder.

Writes experiments/results/mot_budget_<name>.png (one column per reading; rows: detector time,
the share of the image read, MOTP and MOTA against S_max, one line per K_max, median and
quartiles over trials, dashed: full frame) and .json (per-trial runs and the aggregated grid).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from protocol import cpu_seconds  # noqa: E402
from protocol import protocol as make_protocol  # noqa: E402
from tqdm import tqdm  # noqa: E402

from mot_planner_node.core.detector import Detections, HogDetector  # noqa: E402
from mot_planner_node.core.metrics import summarize  # noqa: E402
from mot_planner_node.core.motchallenge import find_sequences, load_sequence  # noqa: E402
from mot_planner_node.core.planner import PlannerConfig  # noqa: E402
from mot_planner_node.core.simulated import render, replay_detector_time, track_synthetic  # noqa: E402
from mot_planner_node.core.tracker import (  # noqa: E402
    DEPLOYED,
    PROTOCOLS,
    MotTracker,
    TrackerConfig,
    protocol_config,
)
from mot_planner_node.evaluate import read_frame, read_summary, run_sequence, timing_summary  # noqa: E402

RESULTS = Path(__file__).resolve().parent / 'results'
CACHE = Path(__file__).resolve().parent / 'cache'
THESIS = {'dataset': 'TUD-Stadtmitte, 640x480, 179 frames', 'detector_s_at_smax_0.1': 0.02,
          'full_frame_detector_s': 0.24, 'speedup_at_smax_0.1': 12.0}
THESIS_TRIALS = 100
THESIS_S_MAX = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]


def protocol_of(summary: dict, cpu_s: float | None = None) -> dict:
    """The protocol object of a result (issue 16), from the result's own fields."""
    new_tracks = summary.get('new_tracks')
    areas = summary.get('areas') or ['centres']
    s_values = sorted({r['s_max'] for r in summary['grid']})
    differs = [f"{summary['trials']} trials per (K_max, S_max) instead of {THESIS_TRIALS}",
               f"{summary['frames']} frames of {len(summary['sequences'])} sequence(s) "
               f"({', '.join(summary['sequences'])}) instead of TUD-Stadtmitte's 179"]
    if s_values != THESIS_S_MAX:
        differs.append(f'S_max in {s_values} instead of 0.1..1.0 in steps of 0.1')
    if summary['name'] == 'synthetic':
        differs.append('tracking on the simulated detector; only the detector time is HOG run '
                       "on each frame's regions")
    if new_tracks not in (None, 'none'):
        differs.append(f"new tracks '{new_tracks}' (thesis: only from the first frame)")
    if areas != ['centres']:
        differs.append(f"S_max read as {' and '.join(repr(a) for a in areas)}, side by side "
                       "(thesis reading: 'centres')")
    if summary.get('iterations'):
        differs.append(f"a planning budget of {summary['iterations']} MCTS iterations instead "
                       'of 10 ms wall clock (what 10 ms buys on this CPU on the simulated street '
                       'at K_max 1; deterministic for a seed whatever the load of parallel '
                       'trials)')
    if summary['runs'] and summary['runs'][0].get('detector_cpu_ms_after_bootstrap') is not None:
        differs.append('detector time is single-threaded HOG CPU time per frame')
    return make_protocol(
        data=f"{summary['name']}: {', '.join(summary['sequences'])}, {summary['frames']} frames",
        repetitions=summary['trials'], thesis_repetitions=THESIS_TRIALS,
        models='OpenCV HOG people detector (default SVM); MCTS planner',
        differs_from_thesis=differs, cpu_s=cpu_s, new_tracks=new_tracks, s_max_readings=areas)


class SharedFullFrames:
    """Wraps a detector: full-frame results are computed once per image object and reused
    (the bootstrap frame of every run); region calls go through."""

    def __init__(self, detector: HogDetector) -> None:
        self.detector = detector
        self.geometry = detector.geometry
        self.box_shrink = detector.box_shrink
        self._cache: dict[int, Detections] = {}

    def detect(self, image: np.ndarray, regions: np.ndarray | None = None) -> Detections:
        if regions is not None:
            return self.detector.detect(image, regions)
        key = id(image)
        if key not in self._cache:
            self._cache[key] = self.detector.detect(image)
        return self._cache[key]


# The worker processes' share of the grid (set before the pool forks; read-only after).
_GRID: dict[str, Any] = {}


def _tracker_config(protocol: str, new_tracks: str, period: int, k: int, s: float, t: int,
                    area: str, budget_ms: float | None, iterations: int | None) -> TrackerConfig:
    """The planner's tracker for one grid cell (``protocol``'s tracking terms)."""
    return protocol_config(protocol, PlannerConfig(k_max=k, s_max=s, budget_ms=budget_ms, seed=t,
                                                   max_iterations=iterations),
                           area=area, mode='planner', new_tracks=new_tracks,
                           full_frame_period=period)


def _run_all(cfg: TrackerConfig, detector: Any) -> dict[str, Any]:
    """Every sequence through one tracker: metrics, timings and the share of the image read.

    For the planner, full frames after the first (births, 'periodic' or 'budget') are charged
    at the baseline's full-frame time (wall and CPU), since SharedFullFrames answers them from
    its cache; ``*_planned_frames`` is the time on the other frames."""
    seqs, images = _GRID['seqs'], _GRID['images']
    runs = {s.name: run_sequence(s, MotTracker(detector, cfg), images=images[s.name],
                                 progress=False) for s in seqs}
    m = summarize({n: r.evaluator for n, r in runs.items()})['OVERALL']
    out = {**m, **timing_summary(list(runs.values())), **read_summary(list(runs.values()))}
    if cfg.mode == 'planner':
        full = np.array([i > 0 and f for r in runs.values() for i, f in enumerate(r.full)])
        first = np.array([i == 0 for r in runs.values() for i in range(len(r.detector_s))])
        planned = ~full & ~first
        n_full = int(full.sum())
        for key, times in (('detector_ms', 'detector_s'), ('detector_cpu_ms', 'detector_cpu_s')):
            t = np.concatenate([getattr(r, times) for r in runs.values()])[planned]
            full_ms = _GRID['full_ms'][key]
            out[f'{key}_planned_frames'] = 1e3 * float(t.mean())
            out[f'{key}_after_bootstrap'] = (1e3 * float(t.sum()) + n_full * full_ms) / (
                int(planned.sum()) + n_full)
        out['full_frames_after_bootstrap'] = n_full
        read = np.concatenate([np.asarray(r.processed, float) for r in runs.values()])
        out['read_fraction_planned_frames'] = float(read[planned].mean())
    return out


def _run_cell(cell: tuple[int, float, int, str]) -> dict[str, Any]:
    k, s, t, area = cell
    g = _GRID
    cfg = _tracker_config(g['protocol'], g['new_tracks'], g['period'], k, s, t, area,
                          g['budget_ms'], g['iterations'])
    return {'area': area, 'k_max': k, 's_max': s, 'trial': t, **_run_all(cfg, g['shared'])}


def motchallenge_grid(path: Path, k_values: list[int], s_values: list[float], trials: int,
                      budget_ms: float | None, new_tracks: str = 'none',
                      period: int = 30, areas: tuple[str, ...] = ('centres',),
                      iterations: int | None = None, jobs: int = 1) -> dict[str, Any]:
    """The (reading, K_max, S_max, trial) grid against the full-frame baseline.

    HOG runs single-threaded (cv2.setNumThreads(1)) in the baseline and every cell, so the
    detector's CPU time per frame compares like with like however many ``jobs`` run side by
    side; ``iterations`` (instead of the wall-clock ``budget_ms``) makes the planner's search
    independent of the machine's load."""
    import cv2
    cv2.setNumThreads(1)
    protocol = 'deployed' if new_tracks == 'budget' else 'thesis'
    seqs = [load_sequence(p) for p in find_sequences(path)]
    images = {s.name: [read_frame(s, i)[0] for i in range(len(s))] for s in seqs}
    hog = HogDetector(region_hit_threshold=PROTOCOLS[protocol]['region_hit_threshold'],
                      upsample=PROTOCOLS[protocol]['read_upsample'])
    shared = SharedFullFrames(hog)
    _GRID.update(seqs=seqs, images=images, shared=shared, protocol=protocol,
                 new_tracks=new_tracks, period=period, budget_ms=budget_ms,
                 iterations=iterations)

    print('full-frame baseline ...', file=sys.stderr, flush=True)
    baseline = _run_all(protocol_config(protocol, mode='full', new_tracks=new_tracks), hog)
    _GRID['full_ms'] = {'detector_ms': baseline['detector_ms_after_bootstrap'],
                        'detector_cpu_ms': baseline['detector_cpu_ms_after_bootstrap']}
    for s in seqs:                      # seed the cache with the full frames of every run
        for i, image in enumerate(images[s.name]):
            if i == 0 or (new_tracks == 'periodic' and i % period == 0):
                shared.detect(image)
    grid = [(k, s, t, a) for a in areas for k in k_values for s in s_values
            for t in range(trials)]
    bar = tqdm(total=len(grid), desc='reading x K_max x S_max x trial', file=sys.stderr)
    cells = []
    if jobs > 1:
        from multiprocessing import get_context
        with get_context('fork').Pool(jobs) as pool:      # workers inherit _GRID
            for cell in pool.imap_unordered(_run_cell, grid, chunksize=1):
                cells.append(cell)
                bar.update()
    else:
        for cell in map(_run_cell, grid):
            cells.append(cell)
            bar.update()
    bar.close()
    cells.sort(key=lambda c: (areas.index(c['area']), c['k_max'], c['s_max'], c['trial']))
    return {'sequences': [s.name for s in seqs], 'frames': sum(len(s) for s in seqs),
            'baseline': baseline, 'cells': cells}


def render_sim_sequence(root: Path, seed: int, people: int, frames: int, fps: float,
                        start_s: float = 0.0,
                        area: tuple[tuple[float, float], tuple[float, float]] | None = None
                        ) -> Path:
    """Render the simulator's pedestrians scene to a MOTChallenge folder (module docstring);
    returns the folder. Reuses a complete folder rendered with the same parameters. area: where
    the people walk (``scenes.pedestrians``; None: the default, everyone always in view)."""
    import cv2
    import mujoco

    from vizzy_sim_bridge.core.model import EYE_CAMERA, compile_model
    from vizzy_sim_bridge.core.render import CameraRenderer
    from vizzy_sim_bridge.core.scenes import build_scene
    from vizzy_sim_bridge.make_samples import mot_gt_row
    from vizzy_vision.camera import EYE_HFOV_DEG, camera_matrix, project
    from vizzy_vision.kinematics import CAMERA_FRAMES, JOINT_NAMES, frames_in_base

    params = {'scene': 'pedestrians', 'seed': seed, 'people': people, 'frames': frames,
              'fps': fps, 'start_s': start_s, 'camera': 'left, head at rest'}
    name = f'sim-pedestrians-s{seed}-p{people}-{frames}f-{fps:g}fps'
    if area is not None:
        (x0, x1), (y0, y1) = area
        params['area'] = [[x0, x1], [y0, y1]]
        name += f'-area{x0:g}_{x1:g}_{y0:g}_{y1:g}'
    seq = root / name
    stamp = seq / 'render.json'
    if stamp.is_file() and json.loads(stamp.read_text()) == params:
        return seq
    (seq / 'img1').mkdir(parents=True, exist_ok=True)
    (seq / 'gt').mkdir(exist_ok=True)
    scene = (build_scene('pedestrians', seed, count=people) if area is None else
             build_scene('pedestrians', seed, count=people, area=area))
    model, _ = compile_model(scene)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)                         # the head at rest (all joints 0)
    width, height = EYE_CAMERA.width, EYE_CAMERA.height
    k = camera_matrix(width, height, EYE_HFOV_DEG)
    pose = frames_in_base([0.0] * len(JOINT_NAMES))[CAMERA_FRAMES['left']]
    rows = []
    with CameraRenderer(model, width, height) as renderer:
        for f in tqdm(range(frames), desc=f'rendering {name}', file=sys.stderr):
            scene.update(model, data, start_s + f / fps)
            rgb, _ = renderer.render(data, 'left_camera')
            cv2.imwrite(str(seq / 'img1' / f'{f + 1:06d}.jpg'),
                        cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 95])
            for box in scene.moving_ground_truth(model, data):
                row = mot_gt_row(f + 1, box['id'] + 1, project(k, pose, box['corners']),
                                 width, height)
                if row is not None:
                    rows.append(row)
    (seq / 'gt' / 'gt.txt').write_text('\n'.join(rows) + '\n')
    (seq / 'seqinfo.ini').write_text(
        f'[Sequence]\nname={name}\nimDir=img1\nframeRate={fps:g}\nseqLength={frames}\n'
        f'imWidth={width}\nimHeight={height}\nimExt=.jpg\n')
    stamp.write_text(json.dumps(params) + '\n')
    return seq


def synthetic_grid(k_values: list[int], s_values: list[float], trials: int, budget_ms: float,
                   frames: int) -> dict[str, Any]:
    hog = HogDetector()
    size = (640, 480)

    def timed(run: Any, seed: int, full: bool) -> dict[str, Any]:
        images = [render(f, size, seed) for f in run.frames[1:]]
        if full:                                # constant cost: every 10th frame
            det = replay_detector_time(hog, images[::10], [None] * len(images[::10]))
        else:
            det = replay_detector_time(hog, images, run.regions[1:])
        return {**run.metrics, 'detector_ms_after_bootstrap': 1e3 * float(np.mean(det)),
                'plan_ms_p95': 1e3 * float(np.percentile(run.plan_s[1:], 95))}

    base = [timed(track_synthetic(TrackerConfig(mode='full', new_tracks='none'),
                                  n_frames=frames, seed=t), t, True) for t in range(trials)]
    baseline = {k: float(np.mean([b[k] for b in base])) for k in
                ('mota', 'motp', 'idf1', 'detector_ms_after_bootstrap')}
    cells = []
    grid = [(k, s, t) for k in k_values for s in s_values for t in range(trials)]
    for k, s, t in tqdm(grid, desc='K_max x S_max x trial', file=sys.stderr):
        cfg = TrackerConfig(mode='planner', new_tracks='none',
                            planner=PlannerConfig(k_max=k, s_max=s, budget_ms=budget_ms, seed=t))
        cells.append({'k_max': k, 's_max': s, 'trial': t,
                      **timed(track_synthetic(cfg, n_frames=frames, seed=t), t, False)})
    return {'sequences': ['synthetic'], 'frames': frames * trials, 'baseline': baseline,
            'cells': cells}


METRICS = ('detector_cpu_ms_after_bootstrap', 'detector_ms_after_bootstrap', 'motp', 'mota',
           'idf1', 'plan_ms_p95', 'detector_cpu_ms_planned_frames', 'detector_ms_planned_frames',
           'read_fraction_planned_frames', 'read_fraction_max_tracking', 'num_matches')


def aggregate(result: dict[str, Any]) -> list[dict[str, Any]]:
    """Per (reading, K_max, S_max): mean, std, median and quartiles over trials. The speed-up
    is on detector CPU time where the cells have it (single-threaded HOG), else wall time."""
    out = []
    cells = result['cells']
    keys = sorted({(c.get('area', 'centres'), c['k_max'], c['s_max']) for c in cells})
    base = result['baseline']
    cpu = all(c.get('detector_cpu_ms_after_bootstrap') is not None for c in cells)
    time_key = 'detector_cpu_ms_after_bootstrap' if cpu else 'detector_ms_after_bootstrap'
    for a, k, s in keys:
        cs = [c for c in cells if (c.get('area', 'centres'), c['k_max'], c['s_max']) == (a, k, s)]
        row: dict[str, Any] = {'area': a, 'k_max': k, 's_max': s, 'trials': len(cs)}
        for m in METRICS:
            v = np.array([c[m] for c in cs if c.get(m) is not None], dtype=float)
            row[m] = float(v.mean()) if v.size else None
            row[m + '_std'] = float(v.std()) if v.size else None
            q1, med, q3 = np.percentile(v, [25, 50, 75]) if v.size else (None,) * 3
            row[m + '_q1'], row[m + '_median'], row[m + '_q3'] = q1, med, q3
        row['speedup'] = base[time_key] / row[time_key]
        row['speedup_on'] = time_key
        out.append(row)
    return out


RUN_KEYS = ('area', 'k_max', 's_max', 'trial', 'mota', 'motp', 'idf1', 'num_matches',
            'num_misses', 'num_false_positives', 'num_switches',
            'detector_cpu_ms_after_bootstrap', 'detector_ms_after_bootstrap',
            'detector_cpu_ms_planned_frames', 'read_fraction_planned_frames',
            'read_fraction_max_tracking', 'plan_ms_p95', 'full_frames_after_bootstrap')


def slim(cell: dict[str, Any]) -> dict[str, Any]:
    """A trial's record as stored in the JSON: the keys the grid and the docs use, floats to
    5 significant digits (1600 trials per file)."""
    return {k: float(f'{v:.5g}') if isinstance(v, float) else v
            for k, v in cell.items() if k in RUN_KEYS}


READING_TITLES = {'centres': "S_max counts the centre boxes (the thesis's reading)",
                  'pixels': 'S_max counts the pixels read (window-inclusive)',
                  'scaled': 'S_max counts the pixels read at the scale read'}


def plot(result: dict[str, Any], rows: list[dict[str, Any]], path: Path, title: str) -> None:
    """One column per S_max reading; rows: detector time, share of the image read, MOTP, MOTA;
    median over trials with quartile bars, one line per K_max, dashed: the full frame."""
    base = result['baseline']
    areas = list(dict.fromkeys(r['area'] for r in rows))
    cpu = rows[0].get('speedup_on') == 'detector_cpu_ms_after_bootstrap'
    time_key = 'detector_cpu_ms_after_bootstrap' if cpu else 'detector_ms_after_bootstrap'
    panels = [(time_key, f"detector {'CPU ' if cpu else ''}time per frame [ms]",
               base.get(time_key)),
              ('read_fraction_planned_frames', 'image read on planned frames [fraction]', 1.0),
              ('motp', 'MOTP [% overlap]', base['motp']),
              ('mota', 'MOTA', base['mota'])]
    fig, axes = plt.subplots(len(panels), len(areas), figsize=(5.8 * len(areas), 13),
                             squeeze=False, sharex=True, sharey='row')
    ks = sorted({r['k_max'] for r in rows})
    for j, area in enumerate(areas):
        for i, (key, label, ref) in enumerate(panels):
            ax = axes[i, j]
            for k in ks:
                rs = [r for r in rows if r['k_max'] == k and r['area'] == area
                      and r.get(key + '_median') is not None]
                if not rs:
                    continue
                med = np.array([r[key + '_median'] for r in rs])
                err = np.array([[m - r[key + '_q1'], r[key + '_q3'] - m]
                                for m, r in zip(med, rs, strict=True)]).T
                ax.errorbar([r['s_max'] for r in rs], med, yerr=err, marker='o', ms=4,
                            capsize=3, label=f'K_max = {k}')
            if ref is not None:
                ax.axhline(ref, color='k', ls='--', label='full frame')
            if key == 'read_fraction_planned_frames':
                ax.plot([0, 1], [0, 1], color='0.5', ls=':', label='read = S_max')
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
            if i == len(panels) - 1:
                ax.set_xlabel('S_max [fraction of the image]')
        axes[0, j].set_yscale('log')
        axes[0, j].set_title(READING_TITLES.get(area, area), fontsize=10)
    axes[0, 0].legend(fontsize=8)
    axes[1, 0].legend(fontsize=8)
    fig.suptitle(f'{title}\nmedian over trials, bars: quartiles', fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument('--motchallenge', type=Path, help='sequence folder or folder of them')
    src.add_argument('--synthetic', action='store_true')
    src.add_argument('--sim', action='store_true',
                     help="the simulator's pedestrians scene, rendered to --cache")
    p.add_argument('--k-max', type=int, nargs='+', default=[1, 2, 3, 4])
    p.add_argument('--s-max', type=float, nargs='+',
                   default=[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0])
    p.add_argument('--trials', type=int, default=3)
    p.add_argument('--budget-ms', type=float, default=10.0)
    p.add_argument('--frames', type=int, default=None,
                   help='synthetic frames per trial (150) or sim frames (300)')
    p.add_argument('--fps', type=float, default=30.0, help='sim frame rate')
    p.add_argument('--people', type=int, default=6, help='sim walkers')
    p.add_argument('--seed', type=int, default=0, help='sim scene seed')
    p.add_argument('--cache', type=Path, default=CACHE, help='where sim sequences are rendered')
    p.add_argument('--name', default=None, help='output name (default: data set name)')
    p.add_argument('--new-tracks', choices=('none', 'periodic', 'budget'), default='none',
                   help="track births of the planner runs (MOTChallenge and sim): 'none' (the "
                        "thesis protocol), 'periodic' (a full frame every 30 frames, whose "
                        "detector time counts) or 'budget' (the deployed configuration: full "
                        "frames paid from the S_max budget); the full-frame baseline detects "
                        "everyone on every frame and starts tracks as the planner does")
    p.add_argument('--area', nargs='+', default=None, choices=('centres', 'pixels', 'scaled'),
                   help="what S_max counts, one or more readings run side by side: 'centres' "
                        "(thesis), 'pixels' (window-inclusive) or 'scaled' (default: 'centres', "
                        f"or {DEPLOYED['area']!r} with --new-tracks budget)")
    p.add_argument('--iterations', type=int, default=None,
                   help='plan with this many MCTS iterations instead of the wall-clock '
                        '--budget-ms (runs that do not depend on the load: use with --jobs)')
    p.add_argument('--jobs', type=int, default=1, help='worker processes (MOTChallenge, sim)')
    p.add_argument('--plot-only', action='store_true',
                   help='redraw the plot from the JSON of --name without recomputing')
    args = p.parse_args()
    budgeted = args.new_tracks == 'budget'
    areas = tuple(args.area or [DEPLOYED['area'] if budgeted else 'centres'])
    period = DEPLOYED['full_frame_period'] if budgeted else 30
    budget_ms = None if args.iterations else args.budget_ms

    if args.plot_only:
        name = args.name or ('synthetic' if args.synthetic else 'sim_pedestrians' if args.sim
                             else args.motchallenge.resolve().name)
        out = RESULTS / f'mot_budget_{name}.json'
        summary = json.loads(out.read_text())
        png = out.with_suffix('.png')
        plot({'baseline': summary['baseline'], 'cells': summary['runs']}, summary['grid'], png,
             summary['title'])
        print(f'wrote {png}', file=sys.stderr)
        return
    if args.synthetic:
        name = args.name or 'synthetic'
        frames = args.frames or 150
        result = synthetic_grid(args.k_max, args.s_max, args.trials, args.budget_ms, frames)
        title = f'Synthetic street, {frames} frames x {args.trials} trials (HOG timing)'
        areas = ('centres',)
    elif args.sim:
        frames = args.frames or 300
        # rendered in a child process: the GL threads of a renderer in this one would leave
        # their locks held in the workers that --jobs forks, which then wait on them for ever
        from multiprocessing import get_context
        with get_context('spawn').Pool(1) as pool:
            seq = pool.apply(render_sim_sequence,
                             (args.cache, args.seed, args.people, frames, args.fps))
        name = args.name or 'sim_pedestrians'
        result = motchallenge_grid(seq, args.k_max, args.s_max, args.trials, budget_ms,
                                   args.new_tracks, period, areas, args.iterations, args.jobs)
        title = (f'Simulated pedestrians (seed {args.seed}, {args.people} people), {frames} '
                 f'frames at {args.fps:g} fps, HOG, {args.trials} trials')
    else:
        name = args.name or args.motchallenge.resolve().name
        result = motchallenge_grid(args.motchallenge, args.k_max, args.s_max, args.trials,
                                   budget_ms, args.new_tracks, period, areas, args.iterations,
                                   args.jobs)
        title = (f'{name}: {len(result["sequences"])} sequences, {result["frames"]} frames, '
                 f'HOG, {args.trials} trials')
    rows = aggregate(result)
    RESULTS.mkdir(exist_ok=True)
    png, out = RESULTS / f'mot_budget_{name}.png', RESULTS / f'mot_budget_{name}.json'
    plot(result, rows, png, title)
    summary = {'name': name, 'title': title, 'sequences': result['sequences'],
               'frames': result['frames'], 'trials': args.trials, 'budget_ms': budget_ms,
               'iterations': args.iterations, 'baseline': result['baseline'], 'grid': rows,
               'thesis': THESIS, 'runs': [slim(c) for c in result['cells']],
               'new_tracks': None if args.synthetic else args.new_tracks,
               'areas': list(areas)}
    summary['protocol'] = protocol_of(summary, cpu_seconds())
    out.write_text(json.dumps(summary, indent=1, default=float) + '\n')
    at = [r for r in rows if abs(r['s_max'] - 0.1) < 1e-9]
    time_key = rows[0]['speedup_on']
    for r in at:
        print(f'{r["area"]} K_max={r["k_max"]} S_max=0.1: detector {r[time_key]:.1f} ms vs '
              f'{result["baseline"][time_key]:.1f} ms full frame ({r["speedup"]:.1f}x; thesis '
              f'12x), read {r.get("read_fraction_planned_frames") or float("nan"):.3f} of the '
              f'image, MOTP {r["motp"]:.2f} vs {result["baseline"]["motp"]:.2f}, MOTA '
              f'{r["mota"]:.3f} vs {result["baseline"]["mota"]:.3f}', file=sys.stderr)
    print(f'wrote {png} and {out}', file=sys.stderr)
    keys = ('area', 'k_max', time_key, 'speedup', 'read_fraction_planned_frames', 'motp', 'mota')
    print(json.dumps({'name': name, 'png': str(png), 'json': str(out),
                      'baseline_' + time_key: result['baseline'][time_key],
                      'at_smax_0.1': [{k: r.get(k) for k in keys} for r in at]}), flush=True)


if __name__ == '__main__':
    main()
