"""Fuzz benchmark: every node of the graph, alone, fed bad input on every topic it subscribes to.

For each node of src/vizzy_runtime/config/graph.yaml (or those given with --nodes): start it on
its own (its parameters and remappings, sim time with a valid /clock running), find its input
topics by discovery, send --per-topic messages to each (well-typed bad content, type-aware cases
and malformed CDR: vizzy_runtime.fuzz), then check it is still alive and spinning (a fresh
/diagnostics status) and that it stops cleanly on SIGINT. Prints, last, one JSON object:
  messages_sent       total, and per node per topic
  crashes, hangs      nodes that died / stopped reporting (or needed SIGTERM to stop)
  refusals            per node: '<topic>: <reason>' -> count, as the node reported them
  seconds             wall time

    .venv/bin/python bench/fuzz.py [--per-topic 10000] [--seed 1] [--nodes sim foveation ...]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random().randint(100, 200)))
os.environ.setdefault('VIZZY_RUNTIME', 'bundled')

from vizzy_runtime.fuzz import fuzz_node  # noqa: E402
from vizzy_runtime.launcher import default_graph_file, load_graph  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--per-topic', type=int, default=10_000)
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--nodes', nargs='+', help='node names of graph.yaml (default: all)')
    ns = parser.parse_args()
    names = ns.nodes or [n.name for n in load_graph(default_graph_file()).nodes]
    start = time.monotonic()
    reports = {}
    with tempfile.TemporaryDirectory(prefix='vizzy_fuzz_') as tmp:
        for name in names:
            report = fuzz_node(name, ns.per_topic, ns.seed, log_dir=Path(tmp),
                               progress=lambda line: print(line, file=sys.stderr, flush=True))
            reports[name] = report
            print(f'{name}: sent {sum(t.sent for t in report.topics)} '
                  f'on {len(report.topics)} topics, '
                  f'crashed={report.crashed} hung={report.hung} exit={report.exit_code}',
                  file=sys.stderr, flush=True)
            if report.crashed or report.hung:
                print(report.log_tail, file=sys.stderr)
    result = {
        'per_topic': ns.per_topic, 'seed': ns.seed,
        'messages_sent': sum(t.sent for r in reports.values() for t in r.topics),
        'messages_sent_by_node': {n: {t.topic: t.sent for t in r.topics}
                                  for n, r in reports.items()},
        'crashes': sorted(n for n, r in reports.items() if r.crashed),
        'hangs': sorted(n for n, r in reports.items() if r.hung),
        'refusals': {n: r.refusals for n, r in reports.items()},
        'seconds': round(time.monotonic() - start, 1),
    }
    print(json.dumps(result))
    return 0


if __name__ == '__main__':
    sys.exit(main())
