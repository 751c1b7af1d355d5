"""Stop and respawn benchmark: how long each node of the running graph takes to stop on SIGINT
(with its work in flight), and to be back with its output flowing after a SIGKILL.

Starts the shipped graph (src/vizzy_runtime/config/graph.yaml; it respawns every node, each
forked by its zygote, vizzy_runtime/zygote.py) with the launcher, waits until every output flows,
then, node by node, --rounds times:
  1. SIGINT to the node's process while it works: seconds until the process has exited
     (issue 12's bound: 2 s);
  2. wait until the respawned process publishes (and until its zygote is ready: imports and
     warm-up done), then SIGKILL it: seconds from the kill until its output flows again from the
     next process. From the zygote: the launcher's respawn_delay, a fork, node construction, the
     first result; with --cold (no zygotes, as ros2 launch respawns): also the interpreter's
     start-up and the imports (torch, Open3D, MuJoCo).
Prints, last, one JSON object: stop_after_sigint_s and back_after_sigkill_s per node (max and
median over the rounds), and their maxima over nodes.

    .venv/bin/python bench/lifecycle.py [--rounds 3] [--cold]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import statistics
import sys
import tempfile
import time

os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random().randint(100, 200)))
os.environ.setdefault('VIZZY_RUNTIME', 'bundled')

from vizzy_runtime import dds  # noqa: E402
from vizzy_runtime.launcher import Launcher, default_graph_file, load_graph  # noqa: E402
from vizzy_runtime.testing import wait_until  # noqa: E402

# each node's main output: it flows again only when that node is back
OUTPUT = {
    'sim': ('/vizzy/left/image_raw', 'sensor_msgs/msg/Image'),
    'gaze_controller': ('/gaze/state', 'active_vision_msgs/msg/GazeState'),
    'foveation': ('/foveation/image', 'sensor_msgs/msg/Image'),
    'stereo_ses': ('/ses/cells', 'sensor_msgs/msg/PointCloud2'),
    'cylinder_detector': ('/cylinders', 'active_vision_msgs/msg/CylinderArray'),
    'mot_planner': ('/mot/tracks', 'active_vision_msgs/msg/TrackArray'),
    'object_map': ('/objects/map', 'active_vision_msgs/msg/MapObjectArray'),
}
TIMEOUT_S = 120.0


def summary(values: list[float]) -> dict[str, float]:
    return {'max': round(max(values), 3), 'median': round(statistics.median(values), 3)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--cold', action='store_true',
                        help='no standbys: every respawn starts cold')
    ns = parser.parse_args()
    # the launcher writes to it for the whole run; kept (delete=False): its name is reported
    log = tempfile.NamedTemporaryFile('w+', prefix='vizzy_lifecycle_', suffix='.log',  # noqa: SIM115
                                      delete=False)
    graph = load_graph(default_graph_file())
    graph.respawn_standby = not ns.cold
    for spec in graph.nodes:
        spec.respawn_standby = None
    launcher = Launcher(graph, output=log)
    readers = {n: dds.RawReader(t, ty, dds.QoS(reliable=False, depth=50))
               for n, (t, ty) in OUTPUT.items()}
    stop_s: dict[str, list[float]] = {n: [] for n in OUTPUT}
    back_s: dict[str, list[float]] = {n: [] for n in OUTPUT}

    def standby_ready(name: str) -> bool:
        """The node's standby has finished its imports and warm-up (it said so)."""
        spare = launcher.standbys.get(name)
        if ns.cold:
            return True
        return spare is not None and spare.poll() is None and spare.pid in launcher.ready_standbys

    def flowing_from_new(name: str, old: object) -> bool:
        return launcher.procs[name] is not old and launcher.procs[name].poll() is None \
            and bool(readers[name].take(50))

    try:
        launcher.start()
        if not wait_until(lambda: all(bool(r.take(50)) for r in readers.values()), TIMEOUT_S):
            raise SystemExit('bench/lifecycle: the graph never had every output flowing')
        for name in OUTPUT:
            for _ in range(ns.rounds):
                proc = launcher.procs[name]
                wait_until(lambda name=name: standby_ready(name), TIMEOUT_S)
                t0 = time.monotonic()
                proc.send_signal(signal.SIGINT)
                if not wait_until(lambda proc=proc: proc.poll() is not None, 30):
                    raise SystemExit(f'bench/lifecycle: {name} still running 30 s after SIGINT')
                stop_s[name].append(time.monotonic() - t0)
                readers[name].take(1000)
                if not wait_until(lambda name=name, proc=proc: flowing_from_new(name, proc),
                                  TIMEOUT_S):
                    raise SystemExit(f'bench/lifecycle: {name} did not come back after SIGINT')
                proc = launcher.procs[name]
                wait_until(lambda name=name: standby_ready(name), TIMEOUT_S)
                t0 = time.monotonic()
                os.killpg(proc.pid, signal.SIGKILL)
                wait_until(lambda proc=proc: proc.poll() is not None, 30)
                readers[name].take(1000)
                if not wait_until(lambda name=name, proc=proc: flowing_from_new(name, proc),
                                  TIMEOUT_S):
                    raise SystemExit(f'bench/lifecycle: {name} did not come back after SIGKILL')
                back_s[name].append(time.monotonic() - t0)
                print(f'{name}: stopped {stop_s[name][-1]:.2f} s after SIGINT, '
                      f'back {back_s[name][-1]:.2f} s after SIGKILL', file=sys.stderr, flush=True)
    finally:
        codes = launcher.stop()
        for r in readers.values():
            dds.delete(r)
    result = {
        'rounds': ns.rounds, 'standby': not ns.cold,
        'respawn_delay_s': {n.name: graph.respawns(n)[1] for n in graph.nodes},
        'stop_after_sigint_s': {n: summary(v) for n, v in stop_s.items()},
        'back_after_sigkill_s': {n: summary(v) for n, v in back_s.items()},
        'stop_after_sigint_s_max': round(max(max(v) for v in stop_s.values()), 3),
        'back_after_sigkill_s_max': round(max(max(v) for v in back_s.values()), 3),
        'stop_seconds_at_launcher_stop': launcher.stop_seconds, 'exit_codes': codes,
        'launch_log': log.name,
    }
    print(json.dumps(result))
    return 0


if __name__ == '__main__':
    sys.exit(main())
