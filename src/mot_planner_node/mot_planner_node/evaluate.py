"""Evaluate the resource-constrained tracker on MOTChallenge-format sequences.

    evaluate SEQUENCE_OR_FOLDER [...] [--k-max 3] [--s-max 0.1] [--mode both] [...]
    evaluate SEQ --seed 0 --no-timing                             # reproducible JSON
    evaluate SEQ --wall-clock                                     # the node's 10 ms budget
    evaluate SEQ --protocol thesis                                # thesis section 5.4

``--protocol deployed`` (default) is the node's configuration: S_max binds the pixels the
detector reads every frame, and new tracks are born from full-frame detections paid from
what the tracks leave of the budget (core/tracker.py, ``new_tracks='budget'``).
``--protocol thesis``: tracks only from the first frame, S_max counting the centre boxes.
Planning makes ``--budget-iterations`` MCTS runs per frame (default: what the node's 10 ms buy
on a quiet 2-core machine at the protocol's horizon, DEFAULT_BUDGET_ITERATIONS: 600 deployed,
150 thesis): the same seed gives the same JSON,
given ``--no-timing``, which leaves out the timings, on any machine at any load. With
``--wall-clock`` it plans for ``--budget-ms`` of wall time per frame instead, as the node does
(optionally capped by ``--iterations``): results then vary with the machine's load.

Each argument is a sequence folder (``img1/``, ``gt/gt.txt``, optionally ``seqinfo.ini``) or a
folder of them. The tracker runs with the planner (given K_max, S_max) and/or with the
detector on every full frame (the baseline); CLEAR MOT metrics (MOTA, MOTP, IDF1 via
py-motmetrics) and timings are printed as one JSON object on the last line of stdout (a
table goes to stderr unless ``--quiet``).

Timing figures per mode: ``detector_ms_per_frame`` (all frames, including the first, which
is always a full-frame detection to start the tracks), ``detector_ms_after_bootstrap``
(frames 2..n: the figure the planner changes), ``plan_ms_p95``, ``frame_ms`` (the tracker's
whole step, detector included) and ``processed_fraction`` (image share the detector read).
``detector_speedup`` = full-frame / planner detector time after the bootstrap; ``motp_delta``
= planner MOTP - full-frame MOTP (percentage points of overlap, thesis Eq. 5.26).
``detector_cpu_ms_*``: the same in CPU time (all the detector's threads; steadier than wall
time on a shared machine). The share of the image the detector read, counted as the S_max
constraint counts it (``--area``; the union of its crops, overlaps once; with ``scaled`` each
pixel at the resolution the detector reads it, a crop shrunk by its smallest scale s_lo
costing 1/s_lo^2 per pixel): ``read_fraction_mean``/``_max`` over all frames,
``read_fraction_max_tracking`` over the frames that were no full frame (at most
``(1 - birth_share) S_max`` in the deployed protocol), ``read_fraction_mean_after_bootstrap``
(= ``processed_fraction``), ``full_frames``; per sequence also ``read_fraction_per_frame``.
``covered_fraction_mean``/``_max_tracking``: the share of the image the crops cover, at any
resolution (equal to the read fraction unless ``--area scaled``).

A frame that cannot be read or used (missing, corrupt, other size) is reported in
``bad_frames``; the tracker predicts through it. A malformed folder or gt file stops with a
message naming the file and line (exit status 2).
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import sys
from collections.abc import Callable
from collections.abc import Sequence as Seq
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, NoReturn, cast

import cv2
import numpy as np
from tqdm import tqdm

from .core.detector import Detector, HogDetector
from .core.kalman import MotionModel
from .core.metrics import MotEvaluator, summarize
from .core.motchallenge import MotFolderError, Sequence, find_sequences, load_sequence
from .core.planner import PlannerConfig
from .core.regions import AREA_MODES
from .core.tracker import (
    DEPLOYED,
    NEW_TRACKS,
    PROTOCOLS,
    THESIS,
    FrameError,
    MotTracker,
    TrackerConfig,
)

MODES = {'planner': 'planner', 'full': 'full_frame'}
# MCTS runs per frame by default, per protocol: about what the node's 10 ms wall-clock budget buys
# on a quiet 2-core machine at the protocol's horizon (median over a synthetic street: 608 at
# T = 1, 145 at T = 3), fixed so that a run gives the same figures on any machine at any load
DEFAULT_BUDGET_ITERATIONS = {'deployed': 600, 'thesis': 150}


@dataclass
class SequenceRun:
    """One sequence through one tracker: metrics accumulator and per-frame timings."""

    evaluator: MotEvaluator
    detector_s: list[float] = field(default_factory=list)
    plan_s: list[float] = field(default_factory=list)
    total_s: list[float] = field(default_factory=list)
    processed: list[float] = field(default_factory=list)
    detector_cpu_s: list[float] = field(default_factory=list)
    full: list[bool] = field(default_factory=list)
    covered: list[float] = field(default_factory=list)
    bad_frames: list[dict[str, Any]] = field(default_factory=list)


def read_frame(seq: Sequence, index: int) -> tuple[np.ndarray | None, str | None]:
    """Frame ``index`` (0-based) as a BGR array, or (None, why it cannot be used)."""
    path = seq.frame_paths[index]
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        return None, f'{path.name}: cannot be read or decoded'
    if seq.image_size is not None and (image.shape[1], image.shape[0]) != seq.image_size:
        return None, (f'{path.name}: {image.shape[1]}x{image.shape[0]}, but seqinfo.ini says '
                      f'{seq.image_size[0]}x{seq.image_size[1]}')
    return image, None


def run_sequence(seq: Sequence, tracker: MotTracker, max_frames: int | None = None,
                 images: Seq[np.ndarray | None] | None = None, progress: bool = True,
                 label: str = '') -> SequenceRun:
    """Track one sequence and accumulate its metrics (images may be given pre-loaded)."""
    tracker.reset()
    run = SequenceRun(MotEvaluator())
    n = len(seq) if max_frames is None else min(len(seq), max_frames)
    for i in tqdm(range(n), desc=f'{seq.name} {label}'.strip(), unit='frame', disable=not progress,
                  leave=False, file=sys.stderr):
        if images is not None and images[i] is not None:
            image, problem = images[i], None
        else:
            image, problem = read_frame(seq, i)
        result = None
        if image is not None:
            try:
                result = tracker.step(image)
            except FrameError as exc:
                problem = str(exc)
        if result is None:
            run.bad_frames.append({'sequence': seq.name, 'frame': i + 1, 'problem': problem})
            result = tracker.coast()
        run.detector_s.append(result.detector_s)
        run.plan_s.append(result.plan_s)
        run.total_s.append(result.total_s)
        run.processed.append(result.processed_fraction)
        run.detector_cpu_s.append(result.detector_cpu_s)
        run.full.append(bool(result.full_frame))
        run.covered.append(result.covered_fraction)
        gt_ids, gt_boxes, distractors = seq.gt.frame(i + 1)
        run.evaluator.update(i + 1, gt_ids, gt_boxes, result.ids, result.boxes, distractors)
    return run


def timing_summary(runs: Seq[SequenceRun]) -> dict[str, float | None]:
    """Timing figures (module docstring) over the frames of the given runs."""
    det = np.concatenate([np.asarray(r.detector_s) for r in runs]) if runs else np.zeros(0)
    after = np.concatenate([np.asarray(r.detector_s[1:]) for r in runs]) if runs else np.zeros(0)
    plan = np.concatenate([np.asarray(r.plan_s[1:]) for r in runs]) if runs else np.zeros(0)
    total = np.concatenate([np.asarray(r.total_s) for r in runs]) if runs else np.zeros(0)
    cpu = np.concatenate([np.asarray(r.detector_cpu_s) for r in runs]) if runs else np.zeros(0)
    cpu_after = (np.concatenate([np.asarray(r.detector_cpu_s[1:]) for r in runs]) if runs
                 else np.zeros(0))

    def ms(a: np.ndarray, f: Callable[[np.ndarray], float]) -> float | None:
        return round(1e3 * float(f(a)), 3) if a.size else None

    return {
        'detector_ms_per_frame': ms(det, np.mean),
        'detector_ms_after_bootstrap': ms(after, np.mean),
        'detector_cpu_ms_per_frame': ms(cpu, np.mean),
        'detector_cpu_ms_after_bootstrap': ms(cpu_after, np.mean),
        'plan_ms_mean': ms(plan, np.mean),
        'plan_ms_p95': ms(plan, lambda a: np.percentile(a, 95)),
        'frame_ms': ms(total, np.mean),
    }


TIMING_KEYS = ('detector_ms_per_frame', 'detector_ms_after_bootstrap',
               'detector_cpu_ms_per_frame', 'detector_cpu_ms_after_bootstrap', 'plan_ms_mean',
               'plan_ms_p95', 'frame_ms', 'detector_speedup', 'detector_cpu_speedup')


def read_summary(runs: Seq[SequenceRun]) -> dict[str, float | int | None]:
    """The share of the image the detector read (module docstring), deterministic."""
    proc = np.concatenate([np.asarray(r.processed, float) for r in runs]) if runs else np.zeros(0)
    after = (np.concatenate([np.asarray(r.processed[1:], float) for r in runs]) if runs
             else np.zeros(0))
    full = np.concatenate([np.asarray(r.full, bool) for r in runs]) if runs else np.zeros(0, bool)

    def r4(a: np.ndarray, f: Callable[[np.ndarray], float]) -> float | None:
        return round(float(f(a)), 4) if a.size else None

    return {
        'processed_fraction': r4(after, np.mean),
        'read_fraction_mean': r4(proc, np.mean),
        'read_fraction_max': r4(proc, np.max),
        'read_fraction_mean_after_bootstrap': r4(after, np.mean),
        'read_fraction_max_tracking': r4(proc[~full], np.max),
        'full_frames': int(full.sum()),
        'covered_fraction_mean': r4(np.concatenate([np.asarray(r.covered, float) for r in runs])
                                    if runs else np.zeros(0), np.mean),
        'covered_fraction_max_tracking': r4(np.concatenate(
            [np.asarray(r.covered, float) for r in runs])[~full] if runs else np.zeros(0), np.max),
    }


def make_detector(spec: str, args: argparse.Namespace) -> Detector:
    """'hog' or 'package.module:factory' (a callable returning a Detector)."""
    if spec == 'hog':
        return HogDetector(win_stride=args.win_stride, scale=args.scale,
                           hit_threshold=args.hit_threshold,
                           region_hit_threshold=args.region_hit_threshold,
                           upsample=args.read_upsample,
                           full_frame_scale=args.full_frame_scale)
    module, _, name = spec.partition(':')
    if not name:
        raise ValueError(f"--detector must be 'hog' or 'module:factory', got {spec!r}")
    try:
        factory = getattr(importlib.import_module(module), name)
    except ImportError as exc:     # a typo in --detector: one line, not a traceback
        raise ValueError(f'--detector {spec}: cannot import {module!r} ({exc})') from None
    except AttributeError:
        raise ValueError(f'--detector {spec}: module {module!r} has no {name!r}') from None
    if not callable(factory):
        raise ValueError(f'--detector {spec}: {name!r} is not callable')
    detector = factory()
    if not isinstance(detector, Detector):
        raise ValueError(f'{spec} did not return a detector (geometry, box_shrink, detect)')
    return detector


def resolve_protocol(args: argparse.Namespace) -> argparse.Namespace:
    """Fill the options left at None from ``--protocol`` (module docstring)."""
    base = PROTOCOLS[args.protocol]
    for name, key in (('new_tracks', 'new_tracks'), ('area', 'area'),
                      ('period', 'full_frame_period'), ('birth_share', 'birth_share'),
                      ('report_misses', 'report_misses'), ('birth_score', 'birth_score'),
                      ('keep_lost', 'keep_lost'), ('occluded_share', 'occluded_share'),
                      ('tentative_misses', 'tentative_misses'),
                      ('region_hit_threshold', 'region_hit_threshold'),
                      ('read_upsample', 'read_upsample'), ('horizon', 'horizon')):
        if getattr(args, name, None) is None:
            setattr(args, name, base[key])
    if getattr(args, 'budget_iterations', None) is None and not getattr(args, 'wall_clock', False):
        args.budget_iterations = DEFAULT_BUDGET_ITERATIONS[args.protocol]
    return args


def tracker_config(args: argparse.Namespace, mode: str) -> TrackerConfig:
    args = resolve_protocol(args)
    if getattr(args, 'wall_clock', False):   # wall clock, as the node (optionally capped)
        budget_ms, max_iterations = args.budget_ms, args.iterations
    else:                                      # deterministic: exactly this many MCTS runs
        budget_ms, max_iterations = None, args.budget_iterations
    planner = PlannerConfig(k_max=args.k_max, s_max=args.s_max, area=args.area,
                            alpha_c=args.alpha_c, alpha_s=args.alpha_s, depth=args.horizon,
                            budget_ms=budget_ms, max_iterations=max_iterations, seed=args.seed)
    # mode comes from the command line; TrackerConfig refuses anything but these two
    return TrackerConfig(mode=cast(Literal['planner', 'full'], mode),
                         new_tracks=args.new_tracks,
                         full_frame_period=args.period, birth_share=args.birth_share,
                         birth_score=args.birth_score, keep_lost=args.keep_lost,
                         occluded_share=args.occluded_share or None,
                         tentative_misses=args.tentative_misses,
                         report_misses=(None if args.report_misses is None
                                        or args.report_misses < 0 else args.report_misses),
                         init_scale_velocity_std=float(
                             PROTOCOLS[args.protocol]['init_scale_velocity_std']),
                         motion=MotionModel(accel_std=args.accel_std, scale_accel_std=float(
                             PROTOCOLS[args.protocol]['scale_accel_std'])), planner=planner)


def evaluate(paths: Seq[str | Path], args: argparse.Namespace,
             detector: Detector | None = None) -> dict[str, Any]:
    """Run every mode on every sequence and return the JSON-ready result."""
    resolve_protocol(args)
    for mode in ('planner', 'full'):
        tracker_config(args, mode)               # a bad combination fails before any work
    seq_paths: list[Path] = []
    for p in paths:
        seq_paths += find_sequences(p)
    sequences = [load_sequence(p) for p in seq_paths]
    detector = detector or make_detector(args.detector, args)
    modes = ['planner', 'full'] if args.mode == 'both' else [args.mode]
    out: dict[str, Any] = {'config': {k: v for k, v in vars(args).items() if k != 'paths'},
                           'sequences': {}, 'overall': {}, 'bad_frames': []}
    runs: dict[str, dict[str, SequenceRun]] = {m: {} for m in modes}
    progress = not args.quiet
    for seq in sequences:
        images: list[np.ndarray | None] | None = None
        if len(modes) > 1:                    # decode once for both modes
            images = [read_frame(seq, i)[0] for i in range(
                len(seq) if args.max_frames is None else min(len(seq), args.max_frames))]
        for mode in modes:
            tracker = MotTracker(detector, tracker_config(args, mode))
            runs[mode][seq.name] = run_sequence(seq, tracker, args.max_frames, images,
                                                progress, MODES[mode])
        out['bad_frames'] += runs[modes[0]][seq.name].bad_frames
    for mode in modes:
        metrics = summarize({n: r.evaluator for n, r in runs[mode].items()})
        for name, run in runs[mode].items():
            block = out['sequences'].setdefault(name, {'frames': len(run.detector_s)})
            block[MODES[mode]] = {**metrics[name], **timing_summary([run]), **read_summary([run]),
                                  'read_fraction_per_frame': [round(float(f), 4)
                                                              for f in run.processed]}
        out['overall'][MODES[mode]] = {**metrics['OVERALL'],
                                       **timing_summary(list(runs[mode].values())),
                                       **read_summary(list(runs[mode].values()))}
    if len(modes) == 2:
        for block in [*out['sequences'].values(), out['overall']]:
            p, f = block['planner'], block['full_frame']
            pd, fd = p['detector_ms_after_bootstrap'], f['detector_ms_after_bootstrap']
            block['detector_speedup'] = (round(fd / pd, 2) if pd and fd else None)
            pc, fc = p['detector_cpu_ms_after_bootstrap'], f['detector_cpu_ms_after_bootstrap']
            block['detector_cpu_speedup'] = (round(fc / pc, 2) if pc and fc else None)
            block['motp_delta'] = (round(p['motp'] - f['motp'], 3)
                                   if p['motp'] is not None and f['motp'] is not None else None)
    if getattr(args, 'no_timing', False):
        out = without_timing(out)
    return out


def without_timing(value: Any) -> Any:
    """value without the timing keys (at any depth): what is left is reproducible."""
    if isinstance(value, dict):
        return {k: without_timing(v) for k, v in value.items() if k not in TIMING_KEYS}
    if isinstance(value, list):
        return [without_timing(v) for v in value]
    return value


def finite_or_none(value: Any) -> Any:
    """value with every NaN or infinite float (at any depth) replaced by None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(v) for v in value]
    return value


def print_table(result: dict[str, Any]) -> None:
    cols = ('mota', 'motp', 'idf1', 'num_switches', 'detector_cpu_ms_after_bootstrap',
            'read_fraction_mean', 'read_fraction_max_tracking')
    blocks = [*result['sequences'].items(), ('OVERALL', result['overall'])]
    rows = [(name, mode, block[mode]) for name, block in blocks
            for mode in ('planner', 'full_frame') if mode in block]
    print(f'{"sequence":18s} {"mode":10s} ' + ' '.join(f'{c[:12]:>12s}' for c in cols),
          file=sys.stderr)
    for name, mode, m in rows:
        cells = ' '.join(f'{m[c]:12.3f}' if isinstance(m.get(c), (int, float))
                         else f'{"-":>12s}' for c in cols)
        print(f'{name:18s} {mode:10s} {cells}', file=sys.stderr)
    for problem in result['bad_frames']:
        print(f'bad frame: {problem["sequence"]} {problem["frame"]}: {problem["problem"]}',
              file=sys.stderr)


class OneLineParser(argparse.ArgumentParser):
    """argparse whose usage errors are one line on stderr (exit status 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f'{self.prog}: error: {message} (see --help)\n')


class DefaultsFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows defaults, except None (those options say what they default to)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        if action.default is None:
            return action.help or ''
        return super()._get_help_string(action) or ''


def parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog='evaluate', description=__doc__.split('\n\n')[0],
        formatter_class=DefaultsFormatter)
    p.add_argument('paths', nargs='+', help='MOTChallenge sequence folders or folders of them')
    p.add_argument('--mode', choices=('planner', 'full', 'both'), default='both',
                   help='planner, full-frame baseline, or both')
    p.add_argument('--protocol', choices=tuple(PROTOCOLS), default='deployed',
                   help="'deployed' (the node's configuration: births paid from the S_max "
                        "budget, S_max counting the pixels read) or 'thesis' (section 5.4: no "
                        'births, S_max counting the centre boxes); sets the defaults of '
                        '--new-tracks, --area, --horizon, --period, --birth-share, '
                        '--birth-score, --keep-lost, --report-misses and the other options '
                        "whose help names both")
    p.add_argument('--k-max', type=int, default=3, help='K_max: regions per frame')
    p.add_argument('--s-max', type=float, default=0.1,
                   help="S_max: the share of the image's pixels the detector may read per frame "
                        '(as --area counts them)')
    p.add_argument('--area', choices=AREA_MODES, default=None,
                   help="what S_max counts (docs/mot_planner.md); default: the protocol's "
                        f"({DEPLOYED['area']} deployed, {THESIS['area']} thesis)")
    p.add_argument('--alpha-c', type=float, default=1.0, help='centre width of a region (Eq. 5.18)')
    p.add_argument('--alpha-s', type=float, default=1.0, help='scale width of a region (Eq. 5.19)')
    p.add_argument('--horizon', type=int, default=None,
                   help='planning horizon T in frames, the MCTS depth (section 5.3.5; default '
                        f"{DEPLOYED['horizon']} deployed, {THESIS['horizon']} thesis)")
    p.add_argument('--budget-iterations', type=int, default=None,
                   help='MCTS runs per frame (deterministic for a given --seed; default: what '
                        'the node\'s 10 ms buy on a quiet 2-core machine at the protocol\'s '
                        'horizon, ' + ', '.join(f'{n} {p}' for p, n in
                                               DEFAULT_BUDGET_ITERATIONS.items()) + ')')
    p.add_argument('--wall-clock', action='store_true',
                   help='plan for --budget-ms of wall time per frame instead, as the node does '
                        '(results vary with the load)')
    p.add_argument('--budget-ms', type=float, default=10.0,
                   help='with --wall-clock: planning time per frame [ms]')
    p.add_argument('--iterations', type=int, default=None,
                   help='with --wall-clock: MCTS iteration cap on top of --budget-ms')
    p.add_argument('--seed', type=int, default=0, help='MCTS random seed')
    p.add_argument('--new-tracks', choices=NEW_TRACKS, default=None,
                   help="track births after the first frame: 'budget' (deployed), 'none' "
                        "(thesis), 'periodic'/'sweep' (not charged to S_max); default: the "
                        "protocol's")
    p.add_argument('--period', type=int, default=None,
                   help="'budget': fewest frames between full-frame detections; 'periodic': "
                        f"frames between them (default: {DEPLOYED['full_frame_period']} "
                        f"deployed, {THESIS['full_frame_period']} thesis)")
    p.add_argument('--birth-share', type=float, default=None,
                   help="'budget': share of S_max saved for full-frame detections "
                        f"(default {DEPLOYED['birth_share']})")
    p.add_argument('--birth-score', type=float, default=None,
                   help='tracks are born only from detections scoring at least this (default '
                        f"{DEPLOYED['birth_score']} deployed, on HOG's SVM margin; any, thesis)")
    p.add_argument('--keep-lost', type=int, default=None,
                   help='frames a deleted track is remembered and can come back under its id '
                        f"(default {DEPLOYED['keep_lost']} deployed, 0 thesis)")
    p.add_argument('--occluded-share', type=float, default=None,
                   help='a track whose box a nearer track covers by at least this share is '
                        'not looked for and not missed (0: no occlusion reasoning; default '
                        f"{DEPLOYED['occluded_share']} deployed, none thesis)")
    p.add_argument('--tentative-misses', type=int, default=None,
                   help='consecutive misses a new track survives before it is confirmed '
                        f"(default {DEPLOYED['tentative_misses']} deployed, 0 thesis)")
    p.add_argument('--report-misses', type=int, default=None,
                   help='report a track while it has at most this many consecutive misses '
                        f"(-1: always; default {DEPLOYED['report_misses']} deployed, always "
                        'thesis)')
    p.add_argument('--accel-std', type=float, default=MotionModel().accel_std,
                   help='motion model acceleration std, px/frame^2 at scale 1')
    p.add_argument('--detector', default='hog', help="'hog' or 'package.module:factory'")
    p.add_argument('--win-stride', type=int, default=8, help='HOG window stride')
    p.add_argument('--scale', type=float, default=1.05, help='HOG pyramid scale step')
    p.add_argument('--full-frame-scale', type=float, default=None,
                   help='HOG pyramid scale step on full frames only (default: --scale)')
    p.add_argument('--hit-threshold', type=float, default=0.0, help='HOG SVM threshold')
    p.add_argument('--region-hit-threshold', type=float, default=None,
                   help="HOG SVM threshold inside the tracks' regions (default "
                        f"{DEPLOYED['region_hit_threshold']} deployed, "
                        f"{THESIS['region_hit_threshold']} thesis)")
    p.add_argument('--read-upsample', type=float, default=None,
                   help='regions are read at this many times their smallest scale and enlarged '
                        f"back (default {DEPLOYED['read_upsample']} deployed, "
                        f"{THESIS['read_upsample']} thesis)")
    p.add_argument('--max-frames', type=int, default=None, help='first n frames of each sequence')
    p.add_argument('--output', type=Path, default=None, help='also write the JSON here')
    p.add_argument('--quiet', action='store_true', help='no progress bars or table')
    p.add_argument('--no-timing', action='store_true',
                   help='leave the timings out of the JSON (what is left is then the same '
                        'run after run, unless --wall-clock)')
    return p


def main(argv: Seq[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        result = evaluate(args.paths, args)
    except (MotFolderError, ValueError) as exc:
        print(f'evaluate: error: {exc}', file=sys.stderr)
        return 2
    objects = [b['num_objects'] for b in result['overall'].values()
               if isinstance(b, dict) and 'num_objects' in b]
    if objects and not any(objects):
        print('evaluate: error: the ground truth has no target objects to score (every row '
              'ignored: conf 0 or a class that is not a pedestrian)', file=sys.stderr)
        return 2
    if not args.quiet:
        print_table(result)
    result = finite_or_none(result)  # JSON has no -inf/NaN (MOTA is -inf with no objects)
    text = json.dumps(result, default=str, allow_nan=False)
    if args.output is not None:
        args.output.write_text(json.dumps(result, indent=2, default=str, allow_nan=False) + '\n')
    print(text, flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
