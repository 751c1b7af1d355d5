"""The graph's resource budget: CPU time per output, cores at the configured rates, memory.

Runs the shipped graph (src/vizzy_runtime/config/graph.yaml, bundled runtime, as `vizzy launch`
runs it: each respawn_standby node forked by its zygote, vizzy_runtime/zygote.py) and, once every
node is up and every zygote has done its imports, measures a window of --seconds:

- per node: CPU seconds (user + system, /proc/<pid>/stat) and messages on each output topic;
  `cpu_ms_per_output` is the node's CPU over the messages of its primary output (the sim: a stereo
  pair; gaze_controller: a /gaze/state; foveation and mot_planner: a camera frame; stereo_ses: a
  point cloud; cylinder_detector: an RGB-D cloud; object_map: a map), and
  `cores_at_configured_rate` that cost times the primary output's configured rate (from the
  nodes' own parameters, read through their parameter services): what the node would take at the
  rates it is configured for, whether or not this machine reached them;
- per output: `achieved_rate_fraction` = messages per second over the configured rate (on a quiet
  machine, whether the graph keeps up; foveation drops the frames of saccades on purpose);
- memory: each node's peak RSS and PSS over the window (/proc/<pid>/status, smaps_rollup), their
  sums `graph_rss_mb` / `graph_pss_mb`, and the zygotes' (the standbys') `standby_pss_mb` (PSS
  counts the pages they share with their nodes once between them: half of each shared page is
  the zygote's) and `standby_uss_mb` (Private_Clean + Private_Dirty: what their end would free);
- the machine: the share of all cores idle over the window (/proc/stat).

With --lockstep the sim advances only as fast as every node consumes its frames
(vizzy_runtime.lockstep), so every node serves every frame at the configured rates in simulated
time: cores_at_configured_rate is then simply CPU seconds per simulated second, independent of the
machine's load (no standbys in that mode). Its figures are higher than a wall-clock run's (a 10 s
window: robot 1.09 cores against 0.83): every tick is a /clock step the nodes wait on and the
sim renders on demand; use it to compare two versions, not as the budget.

    .venv/bin/python bench/graph_budget.py [--seconds 60] [--lockstep] [--no-standby]
        [--set node.param=value ...] [--out bench/results/graph_budget.json]

Prints, last, one JSON object: per node {cpu_ms_per_output, cores_at_configured_rate,
cores_measured, rss_mb, pss_mb, outputs: {topic: {configured_hz, achieved_hz,
achieved_rate_fraction}}}, and the totals robot_cores_at_configured_rates (every node but the
sim), sim_cores_at_configured_rate, graph_rss_mb, graph_pss_mb, standby_pss_mb, standby_uss_mb,
standby_import_cpu_s (the zygotes' CPU: the imports, once), machine_idle_fraction,
min_achieved_rate_fraction.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random().randint(100, 200)))
os.environ.setdefault('VIZZY_RUNTIME', 'bundled')

import yaml  # noqa: E402

from vizzy_runtime.launcher import (  # noqa: E402
    Launcher,
    default_graph_file,
    load_graph,
    parse_parameter_sets,
)
from vizzy_runtime.lockstep import Conductor, process_cpu_seconds, spun_node  # noqa: E402
from vizzy_runtime.ros import (  # noqa: E402
    AsyncParameterClient,
    Context,
    Node,
    message,
    parameter_value_to_python,
    qos_profile_sensor_data,
)

Params = dict[str, dict[str, Any]]
RateOf = Callable[[Params], float | None]     # None: no fixed rate (on demand)

# (node, topic, type, configured rate from the nodes' parameters, primary output of the node)
OUTPUTS: list[tuple[str, str, str, RateOf, bool]] = [
    ('sim', '/vizzy/left/camera_info', 'sensor_msgs/msg/CameraInfo',
     lambda p: p['sim']['rate_hz'], True),
    ('sim', '/vizzy/rgbd/camera_info', 'sensor_msgs/msg/CameraInfo',
     lambda p: p['sim']['rgbd_rate_hz'], False),
    # at joint_state_rate_hz and at every stereo pair's stamp (where the two do not coincide)
    ('sim', '/joint_states', 'sensor_msgs/msg/JointState',
     lambda p: p['sim']['joint_state_rate_hz'] + p['sim']['rate_hz'], False),
    ('sim', '/clock', 'rosgraph_msgs/msg/Clock', lambda p: p['sim']['clock_rate_hz'], False),
    ('gaze_controller', '/gaze/state', 'active_vision_msgs/msg/GazeState',
     lambda p: p['gaze_controller']['state_rate_hz'], True),
    # control_rate_hz while the head moves, HOLD_RESEND_S while it holds: no fixed rate
    ('gaze_controller', '/vizzy/joint_commands', 'sensor_msgs/msg/JointState',
     lambda p: None, False),
    ('foveation', '/foveation/image/compressed', 'sensor_msgs/msg/CompressedImage',
     lambda p: p['sim']['rate_hz'], True),
    ('foveation', '/foveation/detections_2d', 'vision_msgs/msg/Detection2DArray',
     lambda p: p['foveation']['recognition_rate_hz'], False),
    ('stereo_ses', '/stereo/points', 'sensor_msgs/msg/PointCloud2',
     lambda p: min(p['stereo_ses']['max_rate_hz'] or p['sim']['rate_hz'], p['sim']['rate_hz']),
     True),
    ('stereo_ses', '/ses/cells', 'sensor_msgs/msg/PointCloud2',
     lambda p: p['stereo_ses']['cells_rate_hz'], False),
    ('cylinder_detector', '/cylinders', 'active_vision_msgs/msg/CylinderArray',
     lambda p: p['sim']['rgbd_rate_hz'], True),
    ('mot_planner', '/mot/tracks', 'active_vision_msgs/msg/TrackArray',
     lambda p: min(p['mot_planner']['max_rate_hz'] or p['sim']['rate_hz'], p['sim']['rate_hz']),
     True),
    ('object_map', '/objects', 'vision_msgs/msg/Detection3DArray',
     lambda p: 1.0 / p['object_map']['publish_period_s'], True),
]
RATE_PARAMS = {
    'sim': ['rate_hz', 'rgbd_rate_hz', 'joint_state_rate_hz', 'clock_rate_hz'],
    'gaze_controller': ['control_rate_hz', 'state_rate_hz'],
    'foveation': ['recognition_rate_hz'],
    'stereo_ses': ['max_rate_hz', 'cells_rate_hz'],
    'mot_planner': ['max_rate_hz'],
    'object_map': ['publish_period_s'],
}
START_TIMEOUT_S = 180.0
STANDBY_TIMEOUT_S = 300.0
MEMORY_PERIOD_S = 2.0


class BudgetNode(Node):
    """Counts the messages on every output topic (callbacks in the executor thread)."""

    def __init__(self, context: Context) -> None:
        super().__init__('graph_budget_bench', context=context, start_parameter_services=False)
        self.lock = threading.Lock()
        self.counts: dict[str, int] = {}
        for _, topic, typename, _, _ in OUTPUTS:
            self.counts[topic] = 0
            qos = qos_profile_sensor_data if 'camera_info' in topic or 'image' in topic else 10
            self.create_subscription(message(typename), topic, self._counter(topic), qos)

    def _counter(self, topic: str) -> Callable[[Any], None]:
        def count(_msg: Any) -> None:
            with self.lock:
                self.counts[topic] += 1
        return count

    def snapshot(self) -> dict[str, int]:
        with self.lock:
            return dict(self.counts)


def graph_file(out_dir: Path, lockstep: bool, standby: bool, extra: Params) -> Path:
    """The shipped graph with extra parameters (and the sim lock-stepped) in a params file given
    to every node after its own."""
    params: dict[str, Any] = {}
    overrides = dict(extra)
    if lockstep:
        overrides.setdefault('sim', {})['lockstep'] = True
    for node, values in overrides.items():
        params.setdefault(node, {'ros__parameters': {}})['ros__parameters'].update(values)
    graph = yaml.safe_load(default_graph_file().read_text())
    if lockstep or not standby:
        graph.update(respawn_standby=False)
    if params:
        path = out_dir / 'budget_params.yaml'
        path.write_text(yaml.safe_dump(params))
        graph['nodes'] = [dict(n, parameters=[*n.get('parameters', []), str(path)])
                          for n in graph['nodes']]
    out = out_dir / 'budget_graph.yaml'
    out.write_text(yaml.safe_dump(graph))
    return out


def memory_mb(pid: int) -> tuple[float, float] | None:
    """(RSS, PSS) of process pid [MB], None when it is gone."""
    try:
        with open(f'/proc/{pid}/status') as f:
            rss = next(int(line.split()[1]) for line in f if line.startswith('VmRSS:'))
        with open(f'/proc/{pid}/smaps_rollup') as f:
            pss = next(int(line.split()[1]) for line in f if line.startswith('Pss:'))
    except (OSError, StopIteration, ValueError):
        return None
    return rss / 1024.0, pss / 1024.0


def uss_mb(pid: int) -> float | None:
    """Private_Clean + Private_Dirty of process pid [MB] (smaps_rollup): the memory its end would
    free; None when it is gone."""
    try:
        with open(f'/proc/{pid}/smaps_rollup') as f:
            kb = sum(int(line.split()[1]) for line in f
                     if line.startswith(('Private_Clean:', 'Private_Dirty:')))
    except (OSError, ValueError):
        return None
    return kb / 1024.0


def machine_cpu() -> tuple[int, int]:
    """(idle, total) jiffies of all cores so far (/proc/stat)."""
    with open('/proc/stat') as f:
        fields = [int(v) for v in f.readline().split()[1:]]
    return fields[3] + fields[4], sum(fields[:8])     # idle + iowait; user..steal


def read_rates(node: BudgetNode, launcher: Launcher, timeout_s: float = 20.0) -> Params:
    """The rate parameters of every node, through its parameter services."""
    out: Params = {}
    for name, params in RATE_PARAMS.items():
        if name not in launcher.procs:
            continue
        client = AsyncParameterClient(node, f'/{name}')
        if not client.wait_for_services(timeout_s):
            raise RuntimeError(f'node /{name}: no parameter services within {timeout_s:g} s')
        out[name] = {}
        for param in params:     # one by one: a node without the parameter answers nothing
            future = client.get_parameters([param])
            deadline = time.monotonic() + timeout_s
            while not future.done() and time.monotonic() < deadline:
                time.sleep(0.05)
            if not future.done():
                raise RuntimeError(f'node /{name}: no reply to get_parameters within '
                                   f'{timeout_s:g} s')
            values = future.result().values
            out[name][param] = parameter_value_to_python(values[0]) if values else None
    return out


def wait_for_graph(node: BudgetNode, launcher: Launcher, conductor: Conductor | None) -> None:
    """Until every node subscribes to its inputs, then a moment for discovery to settle."""
    deadline = time.monotonic() + START_TIMEOUT_S
    sim_time_nodes = sum(1 for n in launcher.graph.nodes if n.name != 'sim')
    while time.monotonic() < deadline:
        dead = {n: c for n, c in launcher.poll().items() if c is not None}
        if dead:
            raise RuntimeError(f'nodes exited at start-up: {dead}')
        if (conductor is None or conductor.connected()) \
                and node.count_subscribers('/clock') >= sim_time_nodes \
                and node.count_subscribers('/vizzy/left/image_raw') >= 3 \
                and node.count_publishers('/objects') >= 1:
            time.sleep(3.0)
            return
        time.sleep(0.2)
    raise RuntimeError(f'the graph did not come up within {START_TIMEOUT_S:g} s')


def wait_for_standbys(launcher: Launcher) -> dict[str, float]:
    """Until every node's zygote has done its imports (it has forked the node); their CPU seconds
    so far."""
    expected = {s.name for s in launcher.graph.nodes if launcher.graph.standby(s)}
    deadline = time.monotonic() + STANDBY_TIMEOUT_S
    while time.monotonic() < deadline:
        ready = {n for n, p in launcher.standbys.items() if p.pid in launcher.ready_standbys}
        if ready >= expected:
            break
        time.sleep(0.5)
    else:
        raise RuntimeError(f'standbys not ready within {STANDBY_TIMEOUT_S:g} s: '
                           f'{sorted(expected - ready)}')
    return {n: round(process_cpu_seconds(p.pid) or 0.0, 2) for n, p in launcher.standbys.items()}


def measure(node: BudgetNode, launcher: Launcher, seconds: float,
            conductor: Conductor | None) -> dict[str, Any]:
    """CPU, messages and memory over one window: `seconds` of wall time, or of simulated time
    in lockstep."""
    peak: dict[str, list[float]] = {n: [0.0, 0.0] for n in launcher.procs}

    def sample_memory() -> None:
        for name, proc in list(launcher.procs.items()):
            mem = memory_mb(proc.pid)
            if mem is not None:
                peak[name] = [max(peak[name][0], mem[0]), max(peak[name][1], mem[1])]

    cpu0, counts0, idle0 = launcher.cpu_seconds(), node.snapshot(), machine_cpu()
    t0 = time.monotonic()
    if conductor is None:
        while time.monotonic() - t0 < seconds:
            dead = {n: c for n, c in launcher.poll().items() if c is not None}
            if dead:
                raise RuntimeError(f'nodes exited during the window: {dead}')
            sample_memory()
            time.sleep(min(MEMORY_PERIOD_S, max(0.0, seconds - (time.monotonic() - t0))))
        duration = time.monotonic() - t0
    else:
        next_sample = [0.0]

        def on_tick(t: float) -> None:
            if t >= next_sample[0]:
                next_sample[0] = t + MEMORY_PERIOD_S
                sample_memory()
        start = conductor.reached
        conductor.step_to(start + seconds, on_tick=on_tick)
        duration = seconds
    wall = time.monotonic() - t0
    sample_memory()
    cpu1, counts1, idle1 = launcher.cpu_seconds(), node.snapshot(), machine_cpu()
    return {'duration_s': duration, 'wall_s': wall,
            'cpu_s': {n: cpu1.get(n, 0.0) - cpu0.get(n, 0.0) for n in cpu0},
            'messages': {t: counts1[t] - counts0[t] for t in counts0},
            'peak_mb': peak,
            'idle_fraction': (idle1[0] - idle0[0]) / max(1, idle1[1] - idle0[1])}


def summarize(window: dict[str, Any], rates: Params, standby_mb: dict[str, float],
              standby_cpu: dict[str, float],
              standby_uss: dict[str, float] | None = None) -> dict[str, Any]:
    duration = window['duration_s']
    nodes: dict[str, Any] = {}
    for name, cpu in window['cpu_s'].items():
        outputs = {}
        primary = None
        for owner, topic, _, rate_of, is_primary in OUTPUTS:
            if owner != name:
                continue
            try:
                rate = rate_of(rates)
            except (KeyError, TypeError, ZeroDivisionError):
                continue
            configured = None if rate is None else float(rate)
            achieved = window['messages'][topic] / duration
            outputs[topic] = {'configured_hz': None if configured is None else round(configured, 3),
                              'achieved_hz': round(achieved, 3),
                              'achieved_rate_fraction': round(achieved / configured, 3)
                              if configured else None}
            if is_primary and configured:
                primary = (topic, configured)
        entry: dict[str, Any] = {'cpu_s': round(cpu, 3),
                                 'cores_measured': round(cpu / window['wall_s'], 3),
                                 'rss_mb': round(window['peak_mb'][name][0], 1),
                                 'pss_mb': round(window['peak_mb'][name][1], 1),
                                 'outputs': outputs}
        if primary is not None:
            n = window['messages'][primary[0]]
            per = 1000.0 * cpu / n if n else None
            entry.update(primary_output=primary[0],
                         cpu_ms_per_output=round(per, 2) if per is not None else None,
                         cores_at_configured_rate=round(per * primary[1] / 1000.0, 3)
                         if per is not None else None)
        nodes[name] = entry

    def cores(names: list[str]) -> float | None:
        values = [nodes[n].get('cores_at_configured_rate') for n in names]
        return None if any(v is None for v in values) else round(sum(values), 3)

    fractions = [o['achieved_rate_fraction'] for n in nodes.values()
                 for o in n['outputs'].values() if o['achieved_rate_fraction'] is not None]
    return {
        'nodes': nodes,
        'robot_cores_at_configured_rates': cores([n for n in nodes if n != 'sim']),
        'sim_cores_at_configured_rate': cores(['sim']) if 'sim' in nodes else None,
        'robot_cores_measured': round(sum(v['cores_measured'] for n, v in nodes.items()
                                          if n != 'sim'), 3),
        'graph_rss_mb': round(sum(v['rss_mb'] for v in nodes.values()), 1),
        'graph_pss_mb': round(sum(v['pss_mb'] for v in nodes.values()), 1),
        'standby_pss_mb': round(sum(standby_mb.values()), 1) if standby_mb else None,
        'standby_pss_mb_by_node': standby_mb or None,
        'standby_uss_mb': round(sum(standby_uss.values()), 1) if standby_uss else None,
        'standby_uss_mb_by_node': standby_uss or None,
        'standby_import_cpu_s': round(sum(standby_cpu.values()), 2) if standby_cpu else None,
        'machine_idle_fraction': round(window['idle_fraction'], 3),
        'machine_cores': os.cpu_count(),
        'min_achieved_rate_fraction': round(min(fractions), 3) if fractions else None,
        'window_s': round(duration, 1), 'window_wall_s': round(window['wall_s'], 1),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=60.0,
                        help='the measured window [s] (simulated seconds with --lockstep)')
    parser.add_argument('--warmup', type=float, default=10.0,
                        help='seconds run before the window (after the standbys are ready)')
    parser.add_argument('--lockstep', action='store_true',
                        help='the sim waits for every node: load-independent, no standbys')
    parser.add_argument('--no-standby', action='store_true',
                        help='no zygotes (respawn_standby off: each node started directly)')
    parser.add_argument('--set', nargs='+', default=[], metavar='NODE.PARAM=VALUE',
                        help='a parameter for the run, e.g. mot_planner.scale=1.1')
    parser.add_argument('--out', type=Path, default=None,
                        help='also write the JSON object (and the launch log beside it)')
    ns = parser.parse_args()
    if ns.seconds <= 0 or ns.warmup < 0:
        parser.error('--seconds must be positive and --warmup not negative')
    try:
        extra = parse_parameter_sets(ns.set)
    except ValueError as exc:
        parser.error(str(exc))

    with spun_node(BudgetNode, 'graph_budget_bench') as node, \
            tempfile.TemporaryDirectory(prefix='graph_budget_') as tmp:
        graph = load_graph(graph_file(Path(tmp), ns.lockstep, not ns.no_standby, extra))
        log_path = (ns.out.with_suffix('.log') if ns.out is not None
                    else Path(tmp) / 'launch.log')
        log_path.parent.mkdir(parents=True, exist_ok=True)
        with open(log_path, 'w') as log:
            launcher = Launcher(graph, output=log, grace_s=5.0)
            conductor = (Conductor(node, lambda: [p.pid for p in launcher.procs.values()
                                                  if p.poll() is None])
                         if ns.lockstep else None)
            launcher.start()
            try:
                print('graph_budget: starting the graph', file=sys.stderr, flush=True)
                wait_for_graph(node, launcher, conductor)
                rates = read_rates(node, launcher)
                standby_cpu: dict[str, float] = {}
                standby_mb: dict[str, float] = {}
                standby_uss: dict[str, float] = {}
                if any(graph.standby(s) for s in graph.nodes) and conductor is None:
                    print('graph_budget: waiting for the zygotes\' imports',
                          file=sys.stderr, flush=True)
                    standby_cpu = wait_for_standbys(launcher)
                if conductor is None:
                    time.sleep(ns.warmup)
                else:
                    conductor.step_to(conductor.reached + ns.warmup)
                print(f'graph_budget: measuring {ns.seconds:g} s', file=sys.stderr,
                      flush=True)
                window = measure(node, launcher, ns.seconds, conductor)
                for name, proc in launcher.standbys.items():
                    mem, uss = memory_mb(proc.pid), uss_mb(proc.pid)
                    if mem is not None and uss is not None:
                        standby_mb[name] = round(mem[1], 1)
                        standby_uss[name] = round(uss, 1)
            finally:
                launcher.stop()
    summary = summarize(window, rates, standby_mb, standby_cpu, standby_uss)
    summary.update(lockstep=ns.lockstep, rates=rates, set=ns.set or None)
    if ns.out is not None:
        ns.out.write_text(json.dumps(summary, indent=1))
    print(json.dumps(summary))
    return 0


if __name__ == '__main__':
    sys.exit(main())
