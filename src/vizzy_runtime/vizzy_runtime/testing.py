"""Helpers for tests of nodes: wait on conditions (never sleep-and-hope), check parameter tables."""

from __future__ import annotations

import contextlib
import os
import time
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

# check(name, value): why value is not acceptable for parameter name, or None if it is.
Check = Callable[[str, Any], 'str | None']


def wait_until(predicate: Callable[[], bool], timeout: float = 10.0, spin: Any = None) -> bool:
    """Poll predicate (spinning an executor if given) until it holds; False on timeout."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        if spin is not None:
            spin.spin_once(0.01)
        else:
            time.sleep(0.005)
    return predicate()


def repo_root() -> Path:
    """The source checkout (tests run from it; .venv-ros lives at its top)."""
    return Path(__file__).resolve().parents[3]


def real_rclpy_python() -> Path:
    """The interpreter of the real-rclpy tier (.venv-ros/bin/python), for tests that start
    processes on the real rclpy beside bundled-runtime ones; skips the test, with the reason
    setup recorded, where that tier could not be set up."""
    import pytest

    python = repo_root() / '.venv-ros' / 'bin' / 'python'
    if python.is_file() and os.access(python, os.X_OK):
        return python
    skipped = repo_root() / '.venv-ros.skipped'
    reason = skipped.read_text().strip() if skipped.is_file() else 'run `make setup` to create it'
    pytest.skip(f'no .venv-ros (the real rclpy): {reason}')


def real_rclpy_env(**extra: str) -> dict[str, str]:
    """The environment for a .venv-ros process: the caller's, with VIZZY_RUNTIME=ros (the
    real rclpy or an error) and the same ROS_DOMAIN_ID."""
    env = dict(os.environ, VIZZY_RUNTIME='ros', PYTHONUNBUFFERED='1')
    env.pop('PYTHONPATH', None)
    env.update(extra)
    return env


# --- a node's parameter table (PARAMETERS: (name, default, description) rows, and its check) ----

def check_parameters_described_and_unique(parameters: Sequence[tuple[str, Any, str]]) -> None:
    """Every parameter has a description, and no name is declared twice."""
    names = [name for name, _, _ in parameters]
    assert len(names) == len(set(names)), f'declared more than once: {names}'
    for name, _, description in parameters:
        assert description.strip(), f'{name} has no description'


def check_defaults_valid(parameters: Sequence[tuple[str, Any, str]], check: Check) -> None:
    """check accepts every default."""
    for name, default, _ in parameters:
        problem = check(name, default)
        assert problem is None, f'default of {name}: {problem}'


def check_out_of_range_refused(parameters: Sequence[tuple[str, Any, str]], check: Check) -> None:
    """At least one numeric parameter has a range: check refuses -1e9 for it."""
    refused = [name for name, default, _ in parameters
               if isinstance(default, (int, float)) and not isinstance(default, bool)
               and check(name, -1e9) is not None]
    assert refused, 'at least one numeric parameter has a range'


def check_config(parameters: Sequence[tuple[str, Any, str]], check: Check,
                 config_path: str | Path, node_name: str) -> None:
    """The YAML at config_path is for node_name only and sets declared parameters to valid values
    of the declared types (use_sim_time aside)."""
    import yaml

    doc = yaml.safe_load(Path(config_path).read_text())
    assert list(doc) == [node_name], f'the config is for node {node_name} only, not {list(doc)}'
    params = doc[node_name]['ros__parameters']
    declared = {name: default for name, default, _ in parameters}
    undeclared = set(params) - {'use_sim_time'} - set(declared)
    assert not undeclared, f'{config_path} sets undeclared parameters {sorted(undeclared)}'
    for name, value in params.items():
        if name == 'use_sim_time':
            continue
        # ROS 2 parameters are typed: 15 (integer) does not override 15.0 (double).
        assert type(value) is type(declared[name]), (f'{name}: {type(value).__name__} in the '
                                                     f'config, {type(declared[name]).__name__} declared')
        problem = check(name, value)
        assert problem is None, f'{name} in the config: {problem}'


def check_parameter_table(parameters: Sequence[tuple[str, Any, str]], check: Check,
                          config_path: str | Path | None = None,
                          node_name: str | None = None) -> None:
    """All the checks above: described and unique, defaults valid, a range refused, and (given
    config_path and node_name) the config YAML."""
    check_parameters_described_and_unique(parameters)
    check_defaults_valid(parameters, check)
    check_out_of_range_refused(parameters, check)
    if config_path is not None:
        assert node_name, 'check_parameter_table: config_path needs node_name'
        check_config(parameters, check, config_path, node_name)


@contextlib.contextmanager
def node_under_test(node_factory: Callable[[], Any]) -> Iterator[Any]:
    """rclpy.init(), then node_factory() (not spun); destroys the node and shuts down after."""
    from vizzy_runtime.ros import rclpy

    rclpy.init()
    try:
        ros_node = node_factory()
        try:
            yield ros_node
        finally:
            ros_node.destroy_node()
    finally:
        rclpy.try_shutdown()


def publish_until(publish: Callable[[], Any], done: Callable[[], bool], spin: Any,
                  timeout: float = 10.0, period: float = 0.2) -> bool:
    """Call publish() every period s while spinning until done() (best-effort QoS, such as sensor
    data, may drop a sample: send it again); False if done() never held within timeout."""
    for _ in range(max(1, int(timeout / period))):
        publish()
        if wait_until(done, period, spin=spin):
            return True
    return False


@contextlib.contextmanager
def spinning(context: Any, nodes: Sequence[Any], ready: Callable[[], bool],
             timeout: float = 10.0) -> Iterator[Any]:
    """A SingleThreadedExecutor over nodes in context, once ready() holds (e.g. every publisher
    matched); yields the executor and afterwards removes and destroys the nodes (last first)."""
    from vizzy_runtime.ros import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=context)
    for node in nodes:
        executor.add_node(node)
    try:
        assert wait_until(ready, timeout, spin=executor), f'not ready within {timeout} s'
        yield executor
    finally:
        for node in reversed(nodes):
            executor.remove_node(node)
            node.destroy_node()


def check_node_parameters(ros_node: Any, parameters: Sequence[tuple[str, Any, str]],
                          bad_name: str, bad_value: Any) -> None:
    """A running node declares every parameter at its default and refuses bad_name=bad_value,
    naming bad_name in the reason."""
    from vizzy_runtime.ros import Parameter

    for name, default, _ in parameters:
        value = ros_node.get_parameter(name).value
        value = list(value) if isinstance(default, list) else value
        assert value == default, f'{name} is {value!r}, declared default {default!r}'
    result = ros_node.set_parameters([Parameter(bad_name, value=bad_value)])[0]
    assert not result.successful, f'{bad_name}={bad_value!r} was accepted'
    assert bad_name in result.reason, f'the reason does not name {bad_name}: {result.reason!r}'
