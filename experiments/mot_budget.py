#!/usr/bin/env python3
"""Thesis Fig. 5.3: detector time and MOTP against the attention budget (K_max, S_max).

    .venv/bin/python experiments/mot_budget.py --motchallenge ../shared/data/mot17-mini
    .venv/bin/python experiments/mot_budget.py --synthetic [--frames 150]
    .venv/bin/python experiments/mot_budget.py --sim --new-tracks periodic \
        --s-max 0.1 0.2 0.4 0.7 1.0 --trials 2          # the run in docs/mot_planner.md

For every K_max in {1, 2, 3, 4} and S_max in [0.1, 1.0] the planner tracks the sequences
``--trials`` times (different MCTS seeds; the thesis ran 100), against the full-frame
baseline (detector on every full frame). By default tracking follows the thesis protocol:
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

Writes experiments/results/mot_budget_<name>.png (2x2: detector time and speed-up against
S_max, MOTP and MOTA against S_max, one line per K_max, dashed: full frame) and .json.
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
from mot_planner_node.core.tracker import DEPLOYED, PROTOCOLS, MotTracker, TrackerConfig  # noqa: E402
from mot_planner_node.evaluate import read_frame, run_sequence, timing_summary  # noqa: E402

RESULTS = Path(__file__).resolve().parent / 'results'
CACHE = Path(__file__).resolve().parent / 'cache'
THESIS = {'dataset': 'TUD-Stadtmitte, 640x480, 179 frames', 'detector_s_at_smax_0.1': 0.02,
          'full_frame_detector_s': 0.24, 'speedup_at_smax_0.1': 12.0}
THESIS_TRIALS = 100
THESIS_S_MAX = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]


def protocol_of(summary: dict, cpu_s: float | None = None, new_tracks: str | None = None,
                area: str | None = None) -> dict:
    """The protocol object of a result (issue 16), from the result's own fields (new_tracks and
    area are stored in results written since issue 16; pass them for older files)."""
    new_tracks = new_tracks or summary.get('new_tracks')
    area = area or summary.get('area')
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
    if area not in (None, 'centres'):
        differs.append(f"S_max counts '{area}' (thesis reading: 'centres')")
    return make_protocol(
        data=f"{summary['name']}: {', '.join(summary['sequences'])}, {summary['frames']} frames",
        repetitions=summary['trials'], thesis_repetitions=THESIS_TRIALS,
        models='OpenCV HOG people detector (default SVM); MCTS planner',
        differs_from_thesis=differs, cpu_s=cpu_s, new_tracks=new_tracks, s_max_reading=area)


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


def motchallenge_grid(path: Path, k_values: list[int], s_values: list[float], trials: int,
                      budget_ms: float, new_tracks: str = 'none',
                      period: int = 30, area: str = 'centres') -> dict[str, Any]:
    protocol = 'deployed' if new_tracks == 'budget' else 'thesis'
    seqs = [load_sequence(p) for p in find_sequences(path)]
    images = {s.name: [read_frame(s, i)[0] for i in range(len(s))] for s in seqs}
    hog = HogDetector()
    shared = SharedFullFrames(hog)

    def run_all(cfg: TrackerConfig, detector: Any, full_ms: float | None = None
                ) -> dict[str, Any]:
        runs = {s.name: run_sequence(s, MotTracker(detector, cfg), images=images[s.name],
                                     progress=False) for s in seqs}
        m = summarize({n: r.evaluator for n, r in runs.items()})['OVERALL']
        out = {**m, **timing_summary(list(runs.values()))}
        if cfg.mode == 'planner':
            # Frames 2..n: planned frames as measured; full frames after the first (births,
            # 'periodic' or 'budget') are charged at the baseline's full-frame time, since
            # SharedFullFrames answers them from its cache.
            full = [i > 0 and f for r in runs.values() for i, f in enumerate(r.full)]
            first = [i == 0 for r in runs.values() for i in range(len(r.detector_s))]
            det = np.concatenate([r.detector_s for r in runs.values()])
            planned = det[~np.array(full) & ~np.array(first)]
            n_full = int(np.sum(full))
            out['detector_ms_planned_frames'] = 1e3 * float(planned.mean())
            out['detector_ms_after_bootstrap'] = (1e3 * float(planned.sum()) + n_full * full_ms) / (
                len(planned) + n_full)
            out['full_frames_after_bootstrap'] = n_full
        return out

    print('full-frame baseline ...', file=sys.stderr, flush=True)
    baseline = run_all(TrackerConfig(mode='full', new_tracks=new_tracks,
                                     report_misses=PROTOCOLS[protocol]['report_misses'],
                                     birth_score=PROTOCOLS[protocol]['birth_score'],
                                     keep_lost=PROTOCOLS[protocol]['keep_lost']), hog)
    full_ms = baseline['detector_ms_after_bootstrap']
    for s in seqs:                      # seed the cache with the full frames of every run
        for i, image in enumerate(images[s.name]):
            if i == 0 or (new_tracks == 'periodic' and i % period == 0):
                shared.detect(image)
    cells = []
    grid = [(k, s, t) for k in k_values for s in s_values for t in range(trials)]
    for k, s, t in tqdm(grid, desc='K_max x S_max x trial', file=sys.stderr):
        cfg = TrackerConfig(mode='planner', new_tracks=new_tracks, full_frame_period=period,
                            birth_share=PROTOCOLS[protocol]['birth_share'],
                            report_misses=PROTOCOLS[protocol]['report_misses'],
                            birth_score=PROTOCOLS[protocol]['birth_score'],
                            keep_lost=PROTOCOLS[protocol]['keep_lost'],
                            planner=PlannerConfig(k_max=k, s_max=s, budget_ms=budget_ms, seed=t,
                                                  area=area))
        cells.append({'k_max': k, 's_max': s, 'trial': t, **run_all(cfg, shared, full_ms)})
    return {'sequences': [s.name for s in seqs], 'frames': sum(len(s) for s in seqs),
            'baseline': baseline, 'cells': cells}


def render_sim_sequence(root: Path, seed: int, people: int, frames: int, fps: float,
                        start_s: float = 0.0) -> Path:
    """Render the simulator's pedestrians scene to a MOTChallenge folder (module docstring);
    returns the folder. Reuses a complete folder rendered with the same parameters."""
    import cv2
    import mujoco

    from vizzy_sim_bridge.core.model import EYE_CAMERA, compile_model
    from vizzy_sim_bridge.core.render import CameraRenderer
    from vizzy_sim_bridge.core.scenes import build_scene
    from vizzy_vision.camera import EYE_HFOV_DEG, camera_matrix, project
    from vizzy_vision.kinematics import CAMERA_FRAMES, JOINT_NAMES, frames_in_base

    params = {'scene': 'pedestrians', 'seed': seed, 'people': people, 'frames': frames,
              'fps': fps, 'start_s': start_s, 'camera': 'left, head at rest'}
    name = f'sim-pedestrians-s{seed}-p{people}-{frames}f-{fps:g}fps'
    seq = root / name
    stamp = seq / 'render.json'
    if stamp.is_file() and json.loads(stamp.read_text()) == params:
        return seq
    (seq / 'img1').mkdir(parents=True, exist_ok=True)
    (seq / 'gt').mkdir(exist_ok=True)
    scene = build_scene('pedestrians', seed, count=people)
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
                uv = project(k, pose, box['corners'])
                if np.isnan(uv).any():                     # partly behind the camera
                    continue
                (u0, v0), (u1, v1) = uv.min(axis=0), uv.max(axis=0)
                cu0, cv0 = max(u0, 0.0), max(v0, 0.0)
                cu1, cv1 = min(u1, float(width)), min(v1, float(height))
                if cu1 - cu0 < 4 or cv1 - cv0 < 16:        # out of view
                    continue
                visible = (cu1 - cu0) * (cv1 - cv0) / ((u1 - u0) * (v1 - v0))
                rows.append(f'{f + 1},{box["id"] + 1},{cu0:.2f},{cv0:.2f},{cu1 - cu0:.2f},'
                            f'{cv1 - cv0:.2f},1,1,{visible:.3f}')
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


def aggregate(result: dict[str, Any]) -> list[dict[str, Any]]:
    """Mean and std over trials per (K_max, S_max)."""
    out = []
    keys = sorted({(c['k_max'], c['s_max']) for c in result['cells']})
    base_ms = result['baseline']['detector_ms_after_bootstrap']
    for k, s in keys:
        cs = [c for c in result['cells'] if (c['k_max'], c['s_max']) == (k, s)]
        row: dict[str, Any] = {'k_max': k, 's_max': s, 'trials': len(cs)}
        for m in ('detector_ms_after_bootstrap', 'motp', 'mota', 'idf1', 'plan_ms_p95',
                  'detector_ms_planned_frames', 'num_matches'):
            v = np.array([c[m] for c in cs if c.get(m) is not None], dtype=float)
            row[m] = float(v.mean()) if v.size else None
            row[m + '_std'] = float(v.std()) if v.size else None
        row['speedup'] = base_ms / row['detector_ms_after_bootstrap']
        out.append(row)
    return out


def plot(result: dict[str, Any], rows: list[dict[str, Any]], path: Path, title: str) -> None:
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    base = result['baseline']
    ks = sorted({r['k_max'] for r in rows})
    panels = [(axes[0, 0], 'detector_ms_after_bootstrap', 'detector time per frame [ms]',
               base['detector_ms_after_bootstrap']),
              (axes[0, 1], 'speedup', 'detector speed-up vs full frame', 1.0),
              (axes[1, 0], 'motp', 'MOTP [% overlap]', base['motp']),
              (axes[1, 1], 'mota', 'MOTA', base['mota'])]
    for ax, key, label, ref in panels:
        for k in ks:
            rs = [r for r in rows if r['k_max'] == k]
            err = [r.get(key + '_std') or 0.0 for r in rs]
            ax.errorbar([r['s_max'] for r in rs], [r[key] for r in rs], yerr=err, marker='o',
                        capsize=3, label=f'K_max = {k}')
        if ref is not None:
            ax.axhline(ref, color='k', ls='--', label='full frame')
        ax.set_xlabel('S_max (fraction of the image)')
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0, 0].set_yscale('log')
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
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
    p.add_argument('--area', default=None,
                   help="what S_max counts: 'centres' (thesis), 'pixels' or 'scaled' (default: "
                        f"'centres', or {DEPLOYED['area']!r} with --new-tracks budget)")
    args = p.parse_args()
    budgeted = args.new_tracks == 'budget'
    area = args.area or (DEPLOYED['area'] if budgeted else 'centres')
    period = DEPLOYED['full_frame_period'] if budgeted else 30

    if args.synthetic:
        name = args.name or 'synthetic'
        frames = args.frames or 150
        result = synthetic_grid(args.k_max, args.s_max, args.trials, args.budget_ms, frames)
        title = f'Synthetic street, {frames} frames x {args.trials} trials (HOG timing)'
    elif args.sim:
        frames = args.frames or 300
        seq = render_sim_sequence(args.cache, args.seed, args.people, frames, args.fps)
        name = args.name or 'sim_pedestrians'
        result = motchallenge_grid(seq, args.k_max, args.s_max, args.trials, args.budget_ms,
                                   args.new_tracks, period, area)
        title = (f'Simulated pedestrians (seed {args.seed}, {args.people} people), {frames} '
                 f'frames at {args.fps:g} fps, HOG, {args.trials} trials')
    else:
        name = args.name or args.motchallenge.resolve().name
        result = motchallenge_grid(args.motchallenge, args.k_max, args.s_max, args.trials,
                                   args.budget_ms, args.new_tracks, period, area)
        title = (f'{name}: {len(result["sequences"])} sequences, {result["frames"]} frames, '
                 f'HOG, {args.trials} trials')
    rows = aggregate(result)
    RESULTS.mkdir(exist_ok=True)
    png, out = RESULTS / f'mot_budget_{name}.png', RESULTS / f'mot_budget_{name}.json'
    plot(result, rows, png, title)
    summary = {'name': name, 'sequences': result['sequences'], 'frames': result['frames'],
               'trials': args.trials, 'budget_ms': args.budget_ms,
               'baseline': result['baseline'], 'grid': rows, 'thesis': THESIS,
               'runs': result['cells'],
               'new_tracks': None if args.synthetic else args.new_tracks,
               'area': None if args.synthetic else area}
    summary['protocol'] = protocol_of(summary, cpu_seconds())
    out.write_text(json.dumps(summary, indent=1, default=float) + '\n')
    at = [r for r in rows if abs(r['s_max'] - 0.1) < 1e-9]
    for r in at:
        print(f'K_max={r["k_max"]} S_max=0.1: detector {r["detector_ms_after_bootstrap"]:.1f} ms '
              f'vs {result["baseline"]["detector_ms_after_bootstrap"]:.1f} ms full frame '
              f'({r["speedup"]:.1f}x; thesis 12x), MOTP {r["motp"]:.2f} vs '
              f'{result["baseline"]["motp"]:.2f}', file=sys.stderr)
    print(f'wrote {png} and {out}', file=sys.stderr)
    print(json.dumps({'name': name, 'png': str(png), 'json': str(out),
                      'at_smax_0.1': at}), flush=True)


if __name__ == '__main__':
    main()
