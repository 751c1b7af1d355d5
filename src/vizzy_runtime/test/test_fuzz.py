"""Fuzz every node of the graph (bounded and seeded): each one alone, every input topic it
subscribes to fed FUZZ_PER_TOPIC bad messages (well-typed bad content, type-aware cases, malformed
CDR; vizzy_runtime.fuzz), then: still running, still spinning (a fresh /diagnostics status), the
refusals counted, and a clean exit on SIGINT. bench/fuzz.py runs the same at >= 10,000 per topic.
Bundled runtime (the malformed CDR reaches the node's decoder only there)."""

from __future__ import annotations

import os

import pytest

from vizzy_runtime.fuzz import Mutator, fuzz_node
from vizzy_runtime.launcher import default_graph_file, load_graph
from vizzy_runtime.testing import STOP_GRACE_S

FUZZ_PER_TOPIC = int(os.environ.get('VIZZY_FUZZ_PER_TOPIC', '2000'))
NODES = [n.name for n in load_graph(default_graph_file()).nodes]


def test_mutations_are_reproducible_and_varied():
    """Same seed, same mutations (the templates carry the current time, so compare kinds and
    sizes); all three kinds occur and almost every message differs."""
    first = Mutator('sensor_msgs/msg/Image', 7)
    second = Mutator('sensor_msgs/msg/Image', 7)
    draws = [first.next() for _ in range(300)]
    assert [(k, len(d)) for k, d in draws] == [(k, len(d))
                                               for k, d in (second.next() for _ in range(300))]
    assert {kind for kind, _ in draws} == {'field', 'type-aware', 'malformed CDR'}
    assert len({data for _, data in draws}) > 250


@pytest.mark.slow
@pytest.mark.parametrize('name', NODES)
def test_a_node_survives_bad_input_on_every_topic(name, tmp_path):
    report = fuzz_node(name, FUZZ_PER_TOPIC, seed=1, log_dir=tmp_path, grace_s=STOP_GRACE_S)
    where = f'{name}: {report.as_dict()}\n{report.log_tail}'
    assert report.topics, f'no input topics found: {where}'
    assert all(t.sent == FUZZ_PER_TOPIC for t in report.topics), where
    assert not report.crashed and not report.hung and report.exit_code == 0, where
    assert sum(report.refusals.values()) > 0, where  # bad input is counted, not silently dropped
