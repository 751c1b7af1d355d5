"""End-to-end active perception: the whole graph, lock-stepped, scored against the simulator.

Runs the shipped graph (src/vizzy_runtime/config/graph.yaml, bundled runtime) headless, scene by
scene, for --seconds of simulated time over --seeds (scene layouts), in lockstep: the sim
advances one /clock tick at a time and only once every node has finished with the last one
(vizzy_runtime.lockstep), so the figures do not depend on the machine's load. Each scene's job:

- tabletop: the object map (/objects/map, confirmed objects) against the scene's objects: recall
  and precision of objects with the right label within 5 cm (and 10 cm), false objects (no true
  object within 10 cm), as curves over simulated time and over the graph's cumulative CPU;
- visual_search: simulated seconds and saccades until the left camera first fixates the target
  (its optical axis within TARGET_DEG of the target, the eyes still), the nearest object, out of
  view at the start; the graph runs the nearest-object task (TASKS: config/tasks/
  nearest_object.yaml of vizzy_runtime, every configuration);
- pedestrians: MOTA / IDF1 of /mot/tracks against the sim's ground-truth boxes (left camera).

Configurations, on the same seeds:
- deployed: the shipped graph;
- uniform: no space-variant processing, the same nodes and gaze policy: recognition on the
  unfoveated frame (foveation space_variant false), Cartesian stereo at 512 x 512 receptive
  fields, full-frame HOG on every frame the tracker takes (mot_planner full_frame_period 1,
  s_max 1; both configurations track at the graph's max_rate_hz, 7.5 Hz);
- random_gaze: every gaze source off; this bench sends a saccade to a random direction in the
  head's reach every RANDOM_PERIOD_S (the lower bound for any gaze policy);
- fixed_gaze: every gaze source off; the head keeps its start posture.

CPU: each node process's user + system time from /proc (the sim's reported apart: it is the
world, not the robot). Bytes from the eyes: the JPEG bytes of /foveation/image/compressed.

    .venv/bin/python bench/active_perception.py [--scenes tabletop visual_search pedestrians]
        [--configs deployed uniform random_gaze fixed_gaze] [--seeds 0 1 ...] [--seconds 30]
        [--quick] [--out bench/results/active_perception]

Writes <out>.json (every run's figures and curves) and <out>.png (the curves); prints, last, one
JSON object with deployed_recall_30s, deployed_precision_30s, deployed_false_objects_30s,
uniform_recall_30s, random_gaze_recall_30s, fixed_gaze_recall_30s, cpu_ratio_deployed_vs_uniform,
search_s_to_target, seeds and more (the suffix is the run length: _30s for --seconds 30).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random().randint(100, 200)))
os.environ.setdefault('VIZZY_RUNTIME', 'bundled')

import numpy as np  # noqa: E402
import yaml  # noqa: E402

from vizzy_runtime.convert import stamp_seconds  # noqa: E402
from vizzy_runtime.launcher import (  # noqa: E402
    Launcher,
    default_graph_file,
    load_graph,
    parse_parameter_sets,
    share_dir,
)
from vizzy_runtime.lockstep import Conductor, spun_node  # noqa: E402
from vizzy_runtime.ros import (  # noqa: E402
    Context,
    Node,
    message,
    qos_profile_latched,
    qos_profile_sensor_data,
)
from vizzy_sim_bridge.core.scenes import build_scene  # noqa: E402
from vizzy_vision.kinematics import CAMERA_FRAMES, JOINT_NAMES, frames_in_base  # noqa: E402
from vizzy_vision.object_scoring import Labelled, score  # noqa: E402

MapObjectArray = message('active_vision_msgs/msg/MapObjectArray')
GazeState = message('active_vision_msgs/msg/GazeState')
GazeCommand = message('active_vision_msgs/msg/GazeCommand')
TrackArray = message('active_vision_msgs/msg/TrackArray')
JointState = message('sensor_msgs/msg/JointState')
CompressedImage = message('sensor_msgs/msg/CompressedImage')

SCENES = ('tabletop', 'visual_search', 'pedestrians')
CONFIGS = ('deployed', 'uniform', 'random_gaze', 'fixed_gaze')
GAZE_OFF = {'foveation': {'saccades_enabled': False}, 'stereo_ses': {'publish_gaze': False},
            'mot_planner': {'publish_gaze': False}, 'object_map': {'looks_enabled': False}}
OVERRIDES: dict[str, dict[str, dict[str, Any]]] = {
    'deployed': {},
    'uniform': {'foveation': {'space_variant': False},
                'stereo_ses': {'sensor': 'cartesian', 'n_rf': 512},
                'mot_planner': {'full_frame_period': 1, 's_max': 1.0}},
    'random_gaze': GAZE_OFF,
    'fixed_gaze': GAZE_OFF,
}
# each scene's task, a parameters file given to every node after its own (the graph's default,
# mapping the scene, for the others): config/tasks/ of vizzy_runtime
TASKS = {'visual_search': 'nearest_object'}
RADII_M = (0.05, 0.10)
FALSE_RADIUS_M = 0.10
SAMPLE_PERIOD_S = 0.5          # curves: one point per half second of simulated time
TARGET_DEG = 5.0               # visual search: the optical axis this close to the target
RANDOM_PERIOD_S = 1.5          # random_gaze: a saccade this often
RANDOM_AZIMUTH_DEG = 60.0
RANDOM_ELEVATION_DEG = (-40.0, 30.0)   # below / above the horizon, from the ego frame
START_TIMEOUT_S = 180.0


@dataclass
class Run:
    """What one run saw (the bench node's callbacks fill it)."""

    scene: str
    config: str
    seed: int
    last_map: Any = None
    in_saccade: bool = False
    saccades: int = 0
    joints: np.ndarray | None = None
    eye_bytes: int = 0
    eye_images: int = 0
    tracks: dict[int, Any] = field(default_factory=dict)        # stamp ns -> TrackArray
    truth_boxes: dict[int, Any] = field(default_factory=dict)
    samples: list[dict[str, Any]] = field(default_factory=list)
    found_target_s: float | None = None
    saccades_to_target: int | None = None
    saccades_by_source: dict[str, int] = field(default_factory=dict)
    # per saccade: [t, source, x, y, z] of /gaze/state's fixation point (its frame_id's)
    fixations: list[list[Any]] = field(default_factory=list)
    min_target_deg: float | None = None      # visual search: the axis's closest approach


class BenchNode(Node):
    """The bench's eyes on the graph (its callbacks run in the executor thread)."""

    def __init__(self, context: Context) -> None:
        super().__init__('active_perception_bench', context=context,
                         start_parameter_services=False)
        self.run: Run | None = None
        self.lock = threading.Lock()
        self.create_subscription(MapObjectArray, '/objects/map', self._on_map, qos_profile_latched)
        self.create_subscription(GazeState, '/gaze/state', self._on_gaze, 10)
        self.create_subscription(JointState, '/joint_states', self._on_joints, 10)
        self.create_subscription(CompressedImage, '/foveation/image/compressed', self._on_eye,
                                 qos_profile_sensor_data)
        self.create_subscription(TrackArray, '/mot/tracks', self._on_tracks, 10)
        self.create_subscription(TrackArray, '/sim/ground_truth/left/pedestrians',
                                 self._on_truth_boxes, 10)
        self.gaze_pub = self.create_publisher(GazeCommand, '/gaze/command', 10)

    def _on_map(self, msg: Any) -> None:
        with self.lock:
            if self.run is not None:
                self.run.last_map = msg

    def _on_gaze(self, msg: Any) -> None:
        with self.lock:
            run = self.run
            if run is None:
                return
            if msg.in_saccade and not run.in_saccade:
                run.saccades += 1
                source = str(msg.active_source) or '?'
                run.saccades_by_source[source] = run.saccades_by_source.get(source, 0) + 1
                p = msg.fixation_point
                run.fixations.append([round(stamp_seconds(msg.header.stamp), 2), source,
                                      round(p.x, 3), round(p.y, 3), round(p.z, 3)])
            run.in_saccade = bool(msg.in_saccade)

    def _on_joints(self, msg: Any) -> None:
        names = list(msg.name)
        if not all(n in names for n in JOINT_NAMES):
            return
        q = np.array([float(msg.position[names.index(n)]) for n in JOINT_NAMES])
        with self.lock:
            if self.run is not None:
                self.run.joints = q

    def _on_eye(self, msg: Any) -> None:
        with self.lock:
            if self.run is not None:
                self.run.eye_bytes += len(msg.data)
                self.run.eye_images += 1

    @staticmethod
    def _stamp_ns(msg: Any) -> int:
        return int(msg.header.stamp.sec) * 10 ** 9 + int(msg.header.stamp.nanosec)

    def _on_tracks(self, msg: Any) -> None:
        with self.lock:
            if self.run is not None:
                self.run.tracks[self._stamp_ns(msg)] = msg

    def _on_truth_boxes(self, msg: Any) -> None:
        with self.lock:
            if self.run is not None:
                self.run.truth_boxes[self._stamp_ns(msg)] = msg


def graph_file(out_dir: Path, scene: str, config: str, seed: int,
               extra: dict[str, dict[str, Any]] | None = None) -> Path:
    """The shipped graph, lock-stepped, without respawns or standbys, with the configuration's
    parameters (then extra, from --set) in a params file given to every node after its own."""
    params: dict[str, Any] = {'sim': {'ros__parameters': {'lockstep': True, 'scene': scene,
                                                          'seed': int(seed)}}}
    for overrides in (OVERRIDES[config], extra or {}):
        for node, values in overrides.items():
            params.setdefault(node, {'ros__parameters': {}})['ros__parameters'].update(values)
    path = out_dir / f'{scene}_{config}_{seed}_params.yaml'
    path.write_text(yaml.safe_dump(params))
    graph = yaml.safe_load(default_graph_file().read_text())
    graph.update(respawn=False, respawn_standby=False)
    task = [str(task_file(scene))] if scene in TASKS else []
    graph['nodes'] = [dict(n, parameters=[*n.get('parameters', []), *task, str(path)])
                      for n in graph['nodes']]
    out = out_dir / f'{scene}_{config}_{seed}_graph.yaml'
    out.write_text(yaml.safe_dump(graph))
    return out


def task_file(scene: str) -> Path:
    """The parameters file of the scene's task (TASKS)."""
    return share_dir('vizzy_runtime') / 'config' / 'tasks' / f'{TASKS[scene]}.yaml'


def truths(scene: str, seed: int) -> list[Any]:
    """The scene's objects but its supports (table, stands)."""
    return [o for o in build_scene(scene, seed).objects if o.role != 'support']


def map_score(last_map: Any, truth: list[Any]) -> dict[str, Any]:
    """The confirmed objects of a MapObjectArray against the true objects, at each radius."""
    reported = [Labelled(o.label, (o.position.x, o.position.y, o.position.z))
                for o in (last_map.objects if last_map is not None else []) if o.confirmed]
    labelled = [Labelled(o.kind, tuple(o.position)) for o in truth]
    out: dict[str, Any] = {'objects': 0 if last_map is None else len(last_map.objects)}
    for r in RADII_M:
        s = score(reported, labelled, r, FALSE_RADIUS_M)
        cm = int(round(100 * r))
        out[f'recall_{cm}cm'] = s.recall
        out[f'precision_{cm}cm'] = s.precision
        out['false_objects'] = s.false_objects
        out['reported'] = s.reported
    return out


def map_objects(last_map: Any, truth: list[Any]) -> list[dict[str, Any]]:
    """Every object of the last map with the nearest true object: what went right or wrong."""
    out = []
    centres = np.array([o.position for o in truth]).reshape(-1, 3)
    for o in (last_map.objects if last_map is not None else []):
        p = np.array([o.position.x, o.position.y, o.position.z])
        d = np.linalg.norm(centres - p, axis=1) if len(centres) else np.array([np.inf])
        i = int(np.argmin(d))
        out.append({'label': o.label, 'share': round(o.label_share, 3),
                    'labels': dict(zip(o.labels, (round(v, 3) for v in o.shares),
                                       strict=False)),
                    'confirmed': o.confirmed, 'recognitions': o.recognitions,
                    'geometry': o.geometry_observations,
                    'position': [round(float(v), 3) for v in p],
                    'nearest': truth[i].kind if len(truth) else None,
                    'nearest_name': truth[i].name if len(truth) else None,
                    'distance_m': round(float(d[i]), 3)})
    return out


def target_deg(joints: np.ndarray, target: np.ndarray) -> float:
    """The angle [deg] between the left camera's optical axis and the direction to target
    (base_link); the target is fixated when it is within TARGET_DEG."""
    pose = frames_in_base(joints.tolist())[CAMERA_FRAMES['left']]
    d = target - pose[:3, 3]
    cos = float(pose[:3, 2] @ d / max(np.linalg.norm(d), 1e-9))
    return math.degrees(math.acos(min(max(cos, -1.0), 1.0)))


def random_saccade(node: BenchNode, rng: np.random.Generator) -> None:
    """A saccade to a random direction in the head's reach, 1.5 m from the ego frame."""
    az = math.radians(rng.uniform(-RANDOM_AZIMUTH_DEG, RANDOM_AZIMUTH_DEG))
    el = math.radians(rng.uniform(*RANDOM_ELEVATION_DEG))
    cmd = GazeCommand(mode=GazeCommand.MODE_FIXATION_POINT, motion=GazeCommand.MOTION_SACCADE,
                      source='random_gaze', priority=100, hold_time=0.0)
    cmd.header.frame_id = 'ego'
    cmd.header.stamp = node.get_clock().now().to_msg()
    d = 1.5
    (cmd.fixation_point.x, cmd.fixation_point.y,
     cmd.fixation_point.z) = (d * math.cos(el) * math.cos(az), d * math.cos(el) * math.sin(az),
                              d * math.sin(el))
    node.gaze_pub.publish(cmd)


def wait_for_graph(node: BenchNode, conductor: Conductor, launcher: Launcher) -> None:
    """Until the sim listens for steps and every node subscribes to /clock (they all have
    their subscriptions by then), then a moment for discovery to settle."""
    deadline = time.monotonic() + START_TIMEOUT_S
    sim_time_nodes = sum(1 for n in launcher.graph.nodes if n.name != 'sim')
    while time.monotonic() < deadline:
        dead = {n: c for n, c in launcher.poll().items() if c is not None}
        if dead:
            raise RuntimeError(f'nodes exited at start-up: {dead}')
        if conductor.connected() and node.count_subscribers('/clock') >= sim_time_nodes \
                and node.count_subscribers('/vizzy/left/image_raw') >= 3:
            time.sleep(3.0)
            return
        time.sleep(0.2)
    raise RuntimeError('the graph did not come up within '
                       f'{START_TIMEOUT_S:g} s (see the launch log)')


def one_run(node: BenchNode, scene: str, config: str, seed: int, seconds: float,
            out_dir: Path, extra: dict[str, dict[str, Any]] | None = None) -> dict[str, Any]:
    """Launch, step through `seconds` of sim time sampling the figures, stop; the run's
    figures."""
    graph = load_graph(graph_file(out_dir, scene, config, seed, extra))
    log_path = out_dir / f'{scene}_{config}_{seed}_launch.log'
    run = Run(scene, config, seed)
    truth = truths(scene, seed)
    target = next((np.array(o.position) for o in truth if o.role == 'target'), None)
    rng = np.random.default_rng(seed + 7919)
    with open(log_path, 'w') as log:
        launcher = Launcher(graph, output=log, grace_s=5.0)
        conductor = Conductor(node, lambda: [p.pid for p in launcher.procs.values()
                                             if p.poll() is None])
        wall0 = time.monotonic()
        launcher.start()
        try:
            wait_for_graph(node, conductor, launcher)
            with node.lock:
                node.run = run
            cpu0 = launcher.cpu_seconds()
            start_wall = time.monotonic()
            next_sample = [0.0]
            next_random = [0.5]

            def on_tick(t: float) -> None:
                with node.lock:
                    joints, moving = run.joints, run.in_saccade
                if target is not None and joints is not None and not moving:
                    deg = target_deg(joints, target)
                    if run.min_target_deg is None or deg < run.min_target_deg:
                        run.min_target_deg = deg
                    if run.found_target_s is None and deg <= TARGET_DEG:
                        run.found_target_s, run.saccades_to_target = t, run.saccades
                if config == 'random_gaze' and t >= next_random[0]:
                    next_random[0] = t + RANDOM_PERIOD_S
                    random_saccade(node, rng)
                if t + 1e-9 >= next_sample[0]:
                    next_sample[0] += SAMPLE_PERIOD_S
                    cpu = launcher.cpu_seconds()
                    used = {n: cpu.get(n, 0.0) - cpu0.get(n, 0.0) for n in cpu0}
                    with node.lock:
                        sample = {'t': round(t, 3), 'saccades': run.saccades,
                                  'eye_bytes': run.eye_bytes,
                                  'cpu_robot_s': sum(v for n, v in used.items() if n != 'sim'),
                                  'cpu_sim_s': used.get('sim', 0.0),
                                  **map_score(run.last_map, truth)}
                    run.samples.append(sample)

            conductor.step_to(seconds, on_tick=on_tick)
            wall = time.monotonic() - start_wall
            cpu = launcher.cpu_seconds()
        finally:
            with node.lock:
                node.run = None
            codes = launcher.stop()
    used = {n: round(cpu.get(n, 0.0) - cpu0.get(n, 0.0), 3) for n in cpu0}
    result: dict[str, Any] = {
        'scene': scene, 'config': config, 'seed': seed, 'seconds': seconds,
        'wall_s': round(wall, 1), 'start_s': round(start_wall - wall0, 1),
        'late_ticks': conductor.late_ticks, 'exit_codes': codes,
        'cpu_s_by_node': used, 'cpu_robot_s': round(sum(v for n, v in used.items()
                                                        if n != 'sim'), 3),
        'saccades': run.saccades, 'saccades_by_source': run.saccades_by_source,
        'fixations': run.fixations,
        'eye_bytes': run.eye_bytes, 'eye_images': run.eye_images,
        'samples': run.samples,
    }
    result['final_objects'] = map_objects(run.last_map, truth)
    if scene == 'tabletop':
        result.update(map_score(run.last_map, truth))
        result['truths'] = len(truth)
    if scene == 'visual_search':
        result['s_to_target'] = run.found_target_s
        result['saccades_to_target'] = run.saccades_to_target
        result['min_target_deg'] = (None if run.min_target_deg is None
                                    else round(run.min_target_deg, 2))
    if scene == 'pedestrians':
        result.update(mot_scores(run))
    return result


def mot_scores(run: Run) -> dict[str, Any]:
    """MOTA / IDF1 of the tracks against the ground-truth boxes of the same stamps, over the
    frames the tracker took (it runs at its max_rate_hz, every other camera frame in the
    graph: a frame it skipped by design is no miss); mot_truth_frames: all the truth frames."""
    from mot_planner_node.core.metrics import MotEvaluator, summarize

    ev = MotEvaluator()
    frames = 0
    taken = [stamp for stamp in sorted(run.truth_boxes) if stamp in run.tracks]
    for frame, stamp in enumerate(taken):
        truth = run.truth_boxes[stamp]
        hyp = run.tracks.get(stamp)
        gt_boxes = np.array([[t.center_u - t.width / 2, t.center_v - t.height / 2, t.width,
                              t.height] for t in truth.tracks]).reshape(-1, 4)
        hyp_tracks = [] if hyp is None else list(hyp.tracks)
        hyp_boxes = np.array([[t.center_u - t.width / 2, t.center_v - t.height / 2, t.width,
                               t.height] for t in hyp_tracks]).reshape(-1, 4)
        ev.update(frame, np.array([t.id for t in truth.tracks], np.int64), gt_boxes,
                  np.array([t.id for t in hyp_tracks], np.int64), hyp_boxes)
        frames += 1
    if not frames:
        return {'mota': None, 'idf1': None, 'mot_frames': 0,
                'mot_truth_frames': len(run.truth_boxes)}
    overall = summarize({'run': ev})['OVERALL']
    return {'mota': overall['mota'], 'idf1': overall['idf1'], 'mot_frames': frames,
            'mot_truth_frames': len(run.truth_boxes)}


def mean(values: list[float | None]) -> float | None:
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    return round(float(np.mean(vals)), 4) if vals else None


def cpu_to_reach(samples: list[dict[str, Any]], recall: float) -> float | None:
    """Robot CPU seconds when a run's recall at 5 cm first reached recall (None: never)."""
    for s in samples:
        if s['recall_5cm'] >= recall - 1e-9:
            return float(s['cpu_robot_s'])
    return None


def summarize_runs(results: list[dict[str, Any]], seconds: float) -> dict[str, Any]:
    """The printed JSON: per configuration means over seeds, and the ratios."""
    tag = f'{int(round(seconds))}s'
    out: dict[str, Any] = {}
    by = {(r['scene'], r['config']): [] for r in results}
    for r in results:
        by[(r['scene'], r['config'])].append(r)
    for (scene, config), runs in by.items():
        prefix = config if scene == 'tabletop' else f'{scene}_{config}'
        if scene == 'tabletop':
            for key in ('recall_5cm', 'precision_5cm', 'recall_10cm', 'precision_10cm',
                        'false_objects'):
                name = {'recall_5cm': 'recall', 'precision_5cm': 'precision',
                        'false_objects': 'false_objects'}.get(key, key)
                out[f'{prefix}_{name}_{tag}'] = mean([r[key] for r in runs])
        if scene == 'visual_search':
            out[f'{prefix}_s_to_target'] = mean([r['s_to_target'] for r in runs])
            out[f'{prefix}_saccades_to_target'] = mean([r['saccades_to_target'] for r in runs])
            out[f'{prefix}_found_target'] = sum(r['s_to_target'] is not None for r in runs)
            out[f'{prefix}_min_target_deg'] = mean([r.get('min_target_deg') for r in runs])
        if scene == 'pedestrians':
            out[f'{prefix}_mota'] = mean([r['mota'] for r in runs])
            out[f'{prefix}_idf1'] = mean([r['idf1'] for r in runs])
        out[f'{prefix}_cpu_robot_s'] = mean([r['cpu_robot_s'] for r in runs])
        out[f'{prefix}_eye_bytes'] = mean([r['eye_bytes'] for r in runs])
        out[f'{prefix}_saccades'] = mean([r['saccades'] for r in runs])
    if ('tabletop', 'deployed') in by and ('tabletop', 'uniform') in by:
        # per seed: robot CPU seconds until recall at 5 cm first reached the uniform run's final
        # recall, deployed and uniform (the uniform run reaches its own final recall early: it
        # names every object in view at once); pooled over the seeds where deployed reaches it
        per_seed: dict[str, float | None] = {}
        spent_d = spent_u = 0.0
        uniform = {r['seed']: r for r in by[('tabletop', 'uniform')]}
        for r in sorted(by[('tabletop', 'deployed')], key=lambda r: r['seed']):
            u = uniform.get(r['seed'])
            if u is None:
                continue
            reach_d = cpu_to_reach(r['samples'], u['recall_5cm'])
            reach_u = cpu_to_reach(u['samples'], u['recall_5cm'])
            if reach_d is None or not reach_u:
                per_seed[str(r['seed'])] = None
                continue
            per_seed[str(r['seed'])] = round(reach_d / reach_u, 4)
            spent_d += reach_d
            spent_u += reach_u
        out['cpu_ratio_deployed_vs_uniform'] = (round(spent_d / spent_u, 4) if spent_u > 0
                                                else None)
        out['cpu_ratio_runs_reaching_uniform'] = sum(x is not None for x in per_seed.values())
        out['cpu_ratio_per_seed'] = per_seed
        d_cpu = mean([r['cpu_robot_s'] for r in by[('tabletop', 'deployed')]])
        u_cpu = mean([r['cpu_robot_s'] for r in by[('tabletop', 'uniform')]])
        out[f'cpu_ratio_{tag}_deployed_vs_uniform'] = (round(d_cpu / u_cpu, 4)
                                                       if d_cpu is not None and u_cpu else None)
    if ('visual_search', 'deployed') in by:
        out['search_s_to_target'] = out.get('visual_search_deployed_s_to_target')
    out['seeds'] = sorted({r['seed'] for r in results})
    out['seconds'] = seconds
    return out


def plot(results: list[dict[str, Any]], path: Path) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    table = [r for r in results if r['scene'] == 'tabletop' and r['samples']]
    if not table:
        return
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.6))
    colours = {'deployed': 'tab:green', 'uniform': 'tab:blue', 'random_gaze': 'tab:orange',
               'fixed_gaze': 'tab:grey'}
    for config in CONFIGS:
        runs = [r for r in table if r['config'] == config]
        if not runs:
            continue
        n = min(len(r['samples']) for r in runs)
        t = np.array([runs[0]['samples'][i]['t'] for i in range(n)])
        rec = np.array([[r['samples'][i]['recall_5cm'] for i in range(n)] for r in runs])
        prec = np.array([[r['samples'][i]['precision_5cm'] for i in range(n)] for r in runs])
        cpu = np.array([[r['samples'][i]['cpu_robot_s'] for i in range(n)] for r in runs])
        label = f'{config} ({len(runs)} seed{"s" if len(runs) > 1 else ""})'
        axes[0].plot(t, rec.mean(axis=0), color=colours[config], label=label)
        axes[1].plot(cpu.mean(axis=0), rec.mean(axis=0), color=colours[config], label=label)
        axes[2].plot(t, prec.mean(axis=0), color=colours[config], label=label)
    axes[0].set(xlabel='simulated time [s]', ylabel='recall (right label, 5 cm)',
                title='tabletop: objects found over time', ylim=(0, 1.02))
    axes[1].set(xlabel="robot's CPU time, all nodes but the sim [s]",
                ylabel='recall (right label, 5 cm)', title='... over the CPU spent',
                ylim=(0, 1.02))
    axes[2].set(xlabel='simulated time [s]', ylabel='precision (right label, 5 cm)',
                title='precision of the confirmed objects', ylim=(0, 1.02))
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(loc='lower right', fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scenes', nargs='+', choices=SCENES, default=list(SCENES))
    parser.add_argument('--configs', nargs='+', choices=CONFIGS, default=list(CONFIGS))
    parser.add_argument('--seeds', nargs='+', type=int, default=list(range(10)))
    parser.add_argument('--seconds', type=float, default=30.0)
    parser.add_argument('--quick', action='store_true',
                        help='tabletop with every configuration and visual_search deployed, '
                             'seed 0, 30 s each (6 minutes on 2 cores)')
    parser.add_argument('--out', type=Path,
                        default=Path('bench/results/active_perception'))
    parser.add_argument('--from-json', type=Path, metavar='JSON',
                        help='no runs: summarize and plot the runs of an earlier <out>.json')
    parser.add_argument('--set', nargs='+', default=[], metavar='NODE.PARAM=VALUE',
                        help='a parameter for every run and configuration (after the '
                             'configuration\'s own), e.g. object_map.dwell_s=0.5')
    ns = parser.parse_args()
    if ns.seconds <= 0:
        parser.error('--seconds must be positive')
    try:
        extra = parse_parameter_sets(ns.set)
    except ValueError as exc:
        parser.error(str(exc))
    plan = [(scene, config, seed) for scene in ns.scenes for config in ns.configs
            for seed in ns.seeds
            if scene == 'tabletop' or config in ('deployed', 'uniform')]
    if ns.quick:
        ns.seconds = 30.0
        plan = ([('tabletop', c, 0) for c in CONFIGS]
                + [('visual_search', 'deployed', 0)])
    ns.out.parent.mkdir(parents=True, exist_ok=True)
    if ns.from_json is not None:
        try:
            earlier = json.loads(ns.from_json.read_text())
            results, seconds = earlier['runs'], float(earlier['summary']['seconds'])
        except (OSError, ValueError, KeyError, TypeError) as exc:
            parser.error(f'--from-json {ns.from_json}: not a bench result ({exc})')
        summary = summarize_runs(results, seconds)
        for key in ('set',):
            if key in earlier['summary']:
                summary[key] = earlier['summary'][key]
        ns.out.with_suffix('.json').write_text(json.dumps({'summary': summary, 'runs': results},
                                                          indent=1))
        plot(results, ns.out.with_suffix('.png'))
        print(json.dumps(summary))
        return 0
    from tqdm import tqdm

    results = []
    with spun_node(BenchNode, 'active_perception_bench') as node, \
            tempfile.TemporaryDirectory(prefix='active_perception_') as tmp:
        for scene, config, seed in tqdm(plan, desc='runs', unit='run', file=sys.stderr):
            r = one_run(node, scene, config, seed, ns.seconds, Path(tmp), extra)
            results.append(r)
            print(json.dumps({k: v for k, v in r.items() if k != 'samples'}),
                  file=sys.stderr, flush=True)
    summary = summarize_runs(results, ns.seconds)
    if extra:
        summary['set'] = ns.set
    ns.out.with_suffix('.json').write_text(json.dumps({'summary': summary, 'runs': results},
                                                      indent=1))
    plot(results, ns.out.with_suffix('.png'))
    print(json.dumps(summary))
    return 0


if __name__ == '__main__':
    sys.exit(main())
