"""The task parameter files (config/tasks/*.yaml): each value is one its node declares and
accepts, so a task given with params_file changes what it says and nothing is refused."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest
import yaml

from vizzy_runtime.launcher import default_graph_file, find_entry_point
from vizzy_runtime.node_tools import Param

TASKS = sorted((Path(__file__).resolve().parents[1] / 'config' / 'tasks').glob('*.yaml'))


def node_tables() -> dict[str, list[Param]]:
    """The graph's node names -> their parameter tables (the node module's PARAMETERS)."""
    graph = yaml.safe_load(default_graph_file().read_text())
    tables = {}
    for node in graph['nodes']:
        module = find_entry_point(node['package'], node['executable']).value.split(':')[0]
        table = getattr(importlib.import_module(module), 'PARAMETERS', None)
        if table is not None:
            tables[node['name']] = [Param.of(row) for row in table]
    return tables


def test_there_is_a_task_file() -> None:
    assert [t.stem for t in TASKS] == ['nearest_object']


@pytest.mark.parametrize('task', TASKS, ids=[t.stem for t in TASKS])
def test_task_values_are_declared_and_accepted(task: Path) -> None:
    tables = node_tables()
    data = yaml.safe_load(task.read_text())
    assert data, f'{task.name} is empty'
    for node, section in data.items():
        assert node in tables, f'{task.name}: {node!r} is no node of the graph ({sorted(tables)})'
        values = section['ros__parameters']
        params = {p.name: p for p in tables[node]}
        for name, value in values.items():
            assert name in params, f'{task.name}: {node} declares no parameter {name!r}'
            p = params[name]
            assert type(value) is type(p.default), (          # a float given as 1, say
                f'{task.name}: {node}.{name} = {value!r}, {type(p.default).__name__} expected')
            assert p.refusal(value) is None, p.refusal(value)
            if p.range is not None:
                lo, hi = p.descriptor_bounds()
                assert lo <= value <= hi, f'{task.name}: {node}.{name} = {value} {p.range_rule()}'
