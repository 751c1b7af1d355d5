"""Soak benchmark: the whole graph for --duration seconds (default 600), each node's memory and
each output's rate, early against late.

Starts the graph of src/vizzy_runtime/config/graph.yaml with the launcher, waits --warmup seconds
(models loaded, caches filled), then samples every node's RSS (its process tree, /proc) and
counts messages on the main outputs over the first and the last --window seconds. Prints, last, one
JSON object:
  rss_mb_start / rss_mb_end / rss_growth_pct   per node
  rate_hz_first / rate_hz_last                 per output topic
  respawned, exit_codes                         what the launcher saw
  stop_seconds_after_sigint                     per node, from the launcher's SIGINT to its exit

    .venv/bin/python bench/soak.py [--duration 600] [--warmup 60] [--window 60]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import sys
import tempfile
import time

os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random().randint(100, 200)))
os.environ.setdefault('VIZZY_RUNTIME', 'bundled')

from vizzy_runtime import dds  # noqa: E402
from vizzy_runtime.launcher import Launcher, default_graph_file, load_graph  # noqa: E402

OUTPUTS = {'/vizzy/left/image_raw': 'sensor_msgs/msg/Image',
           '/gaze/state': 'active_vision_msgs/msg/GazeState',
           '/foveation/image': 'sensor_msgs/msg/Image', '/ses/cells': 'sensor_msgs/msg/PointCloud2',
           '/cylinders': 'active_vision_msgs/msg/CylinderArray',
           '/mot/tracks': 'active_vision_msgs/msg/TrackArray'}


def rss_mb(pid: int) -> float:
    """Resident memory of pid and its children [MiB]."""
    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        try:
            with open(f'/proc/{p}/status') as f:
                total += next(int(line.split()[1]) for line in f if line.startswith('VmRSS:'))
            with open(f'/proc/{p}/task/{p}/children') as f:
                todo += [int(c) for c in f.read().split()]
        except (OSError, StopIteration, ValueError):
            continue
    return total / 1024


def count_for(readers: dict[str, dds.RawReader], seconds: float) -> dict[str, float]:
    for r in readers.values():
        r.take(1000)
    counts = dict.fromkeys(readers, 0)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        for topic, r in readers.items():
            counts[topic] += len(r.take(1000))
        time.sleep(0.05)
    return {t: round(c / seconds, 2) for t, c in counts.items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=600.0)
    parser.add_argument('--warmup', type=float, default=60.0)
    parser.add_argument('--window', type=float, default=60.0)
    ns = parser.parse_args()
    # the launcher writes to it for the whole run; kept (delete=False): its name is reported
    log = tempfile.NamedTemporaryFile('w+', prefix='vizzy_soak_', suffix='.log',  # noqa: SIM115
                                      delete=False)
    launcher = Launcher(load_graph(default_graph_file()), output=log)
    readers = {t: dds.RawReader(t, ty, dds.QoS(reliable=False, depth=100))
               for t, ty in OUTPUTS.items()}
    try:
        launcher.start()
        time.sleep(ns.warmup)
        start_rss = {n: rss_mb(p.pid) for n, p in launcher.procs.items()}
        first = count_for(readers, ns.window)
        time.sleep(max(0.0, ns.duration - ns.warmup - 2 * ns.window))
        last = count_for(readers, ns.window)
        end_rss = {n: rss_mb(p.pid) for n, p in launcher.procs.items()}
    finally:
        codes = launcher.stop()
    result = {
        'duration_s': ns.duration, 'warmup_s': ns.warmup, 'window_s': ns.window,
        'rss_mb_start': {n: round(v, 1) for n, v in start_rss.items()},
        'rss_mb_end': {n: round(v, 1) for n, v in end_rss.items()},
        'rss_growth_pct': {n: round(100 * (end_rss[n] - start_rss[n]) / start_rss[n], 2)
                           for n in start_rss if start_rss[n]},
        'rate_hz_first': first, 'rate_hz_last': last,
        'respawned': launcher.respawned, 'exit_codes': codes,
        'stop_seconds_after_sigint': launcher.stop_seconds, 'launch_log': log.name,
    }
    print(json.dumps(result))
    return 0


if __name__ == '__main__':
    sys.exit(main())
