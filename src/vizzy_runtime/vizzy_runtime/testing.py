"""Helpers for tests of nodes: wait on conditions (never sleep-and-hope), check parameter tables."""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, NoReturn

# check(name, value): why value is not acceptable for parameter name, or None if it is.
Check = Callable[[str, Any], 'str | None']


# --- deadlines: every deadline a test waits on state with goes through scaled() ---

TIME_SCALE_ENV = 'VIZZY_TEST_TIME_SCALE'


def time_scale() -> float:
    """VIZZY_TEST_TIME_SCALE (default 1): the factor on every test deadline, for a slow or loaded
    machine (e.g. 3 under valgrind or at load average 8 on 2 cores). Raises ValueError, in one
    line, for a value that is not a number > 0."""
    raw = os.environ.get(TIME_SCALE_ENV, '').strip()
    if not raw:
        return 1.0
    try:
        scale = float(raw)
    except ValueError:
        raise ValueError(f'{TIME_SCALE_ENV}={raw!r} is not a number; use a factor > 0 '
                         'such as 2') from None
    if not (scale > 0.0 and math.isfinite(scale)):
        raise ValueError(f'{TIME_SCALE_ENV}={raw!r} must be a finite number > 0 (1: as written)')
    return scale


def scaled(seconds: float) -> float:
    """A test's deadline of seconds (on an unloaded machine), times VIZZY_TEST_TIME_SCALE.
    Only for deadlines of waiting on state; durations that are part of a test's scenario
    (a period, how long a node runs) stay as written."""
    return seconds * time_scale()


# --- tests that need offscreen OpenGL (MuJoCo on EGL or OSMesa) ---

REQUIRE_RENDER_ENV = 'VIZZY_REQUIRE_RENDER'


def no_renderer(reason: str) -> NoReturn:
    """The one place a test that found no offscreen renderer ends: skipped, or failed with reason
    where VIZZY_REQUIRE_RENDER=1 (CI installs Mesa, so there a render that does not work is a
    fault, not a machine without OpenGL)."""
    import pytest

    require = os.environ.get(REQUIRE_RENDER_ENV, '').strip()
    if require not in ('', '0', '1'):
        pytest.fail(f'{REQUIRE_RENDER_ENV}={require!r}: use 1 (a missing renderer fails the '
                    'test) or 0 (it skips the test)', pytrace=False)
    if require == '1':
        pytest.fail(f'no offscreen rendering, and {REQUIRE_RENDER_ENV}=1: {reason}', pytrace=False)
    pytest.skip(f'no offscreen rendering: {reason}')


# How long a test's launcher waits for its nodes to stop after SIGINT before SIGTERM (Launcher
# grace_s). The launcher's own default (5 s) is a deployment figure, and stop times are measured in
# bench/lifecycle.py; a test asserts only that every node ends cleanly, on a loaded machine too
# (a node of the two-head graph needed more than 5 s at load average 7 on 2 cores).
STOP_GRACE_S = scaled(30.0)


def wait_until(predicate: Callable[[], bool], timeout: float | None = None,
               spin: Any = None) -> bool:
    """Poll predicate (spinning an executor if given) until it holds; False on timeout (s, as
    given: a test passes scaled(s); by default scaled(10))."""
    deadline = time.monotonic() + (scaled(10.0) if timeout is None else timeout)
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


def fastdds_profile() -> Path:
    """The Fast DDS profile of the real-rclpy tier (the loopback-only counterpart of
    dds.loopback_config(); scripts/test_ros.sh uses the same file)."""
    return Path(__file__).resolve().parents[1] / 'config' / 'fastdds_loopback.xml'


def real_rclpy_env(**extra: str) -> dict[str, str]:
    """The environment for a .venv-ros process: the caller's, with VIZZY_RUNTIME=ros (the
    real rclpy or an error) and the same ROS_DOMAIN_ID."""
    env = dict(os.environ, VIZZY_RUNTIME='ros', PYTHONUNBUFFERED='1')
    # Fast DDS on 127.0.0.1 only, unicast discovery, 8 MiB receive buffer: see the profile
    # (SYSTEM_DEFAULT: rmw_fastrtps then takes the transports from it; LOCALHOST would add its own)
    env.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(fastdds_profile()))
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'SYSTEM_DEFAULT')
    env.pop('PYTHONPATH', None)
    env.update(extra)
    return env


# --- a node's parameter table (node_tools.Param rows), checked on a bare node that declares it ---

@contextlib.contextmanager
def parameter_table_node(parameters: Sequence[Any], check: Check | None = None,
                         check_all: Any = None, overrides: dict[str, Any] | None = None,
                         node_name: str = 'parameter_table') -> Iterator[Any]:
    """A bare node, on the runtime under test with a context of its own, that declares
    parameters as the real node does (node_tools.declare_parameters, overrides as start-up
    values); raises what declare_parameters raises. The node's parameters' rules are then the
    middleware's (descriptor ranges, types, read-only) and the table's own, as a user meets them."""
    from vizzy_runtime.node_tools import declare_parameters
    from vizzy_runtime.ros import Context, Node, Parameter

    context = Context()
    context.init(['parameter_table_node'])
    try:
        node = Node(node_name, context=context, start_parameter_services=False,
                    parameter_overrides=[Parameter(n, value=v)
                                         for n, v in (overrides or {}).items()])
        try:
            declare_parameters(node, parameters, check, check_all=check_all)
            yield node
        finally:
            node.destroy_node()
    finally:
        context.try_shutdown()


@contextlib.contextmanager
def parameter_refusals(parameters: Sequence[Any], check: Check | None = None,
                       check_all: Any = None) -> Iterator[Callable[[str, Any], str | None]]:
    """refused(name, value): why a node declaring parameters refuses to set name to value (the
    SetParametersResult's reason), or None if it accepts (the old value is then set back)."""
    from vizzy_runtime.ros import Parameter

    with parameter_table_node(parameters, check, check_all) as node:
        def refused(name: str, value: Any) -> str | None:
            old = node.get_parameter(name).value
            result = node.set_parameters([Parameter(name, value=value)])[0]
            if not result.successful:
                return result.reason or '(no reason given)'
            node.set_parameters([Parameter(name, value=old)])
            return None
        yield refused


def startup_problem(parameters: Sequence[Any], check: Check | None = None,
                    check_all: Any = None, **overrides: Any) -> str | None:
    """The one line of the ParameterError a node declaring parameters raises when started with
    overrides (-p name:=value), or None if it starts."""
    from vizzy_runtime.node_tools import ParameterError

    try:
        with parameter_table_node(parameters, check, check_all, overrides):
            return None
    except ParameterError as err:
        return str(err)


def _params(parameters: Sequence[Any]) -> list[Any]:
    from vizzy_runtime.node_tools import Param

    return [Param.of(row) for row in parameters]


def _outside(spec: Any) -> list[Any]:
    """Values just outside spec's range (and its excluded bounds), to be refused."""
    from vizzy_runtime.node_tools import INT64_MAX, INT64_MIN

    if spec.range is None:
        return []
    lo, hi, lo_open, hi_open = spec.bounds()
    if isinstance(spec.default, int):
        d_lo, d_hi = spec.descriptor_bounds()
        return [v for v, ok in ((d_lo - 1, d_lo > INT64_MIN), (d_hi + 1, d_hi < INT64_MAX)) if ok]
    out = []
    for bound, excluded, sign in ((lo, lo_open, -1.0), (hi, hi_open, 1.0)):
        if math.isfinite(bound):
            out.append(bound + sign * max(1e-3, 1e-3 * abs(bound)))
            if excluded:
                out.append(float(bound))
        elif excluded:
            out.append(bound)        # (-inf, ...: -inf itself
    return out


def check_parameter_table(parameters: Sequence[Any], check: Check | None = None,
                          config_path: str | Path | None = None,
                          node_name: str | None = None, check_all: Any = None) -> None:
    """A node's table: Param rows, described, unique; a node declaring it starts with the
    defaults and refuses, through the middleware, values just outside every range, the excluded
    bounds, values outside the choices and changes to read-only parameters; at least one numeric
    parameter has a range; and (given config_path and node_name) the config YAML is for node_name
    only, sets declared parameters to values of the declared types, and the node starts with it."""
    from vizzy_runtime.node_tools import Param

    assert all(isinstance(row, Param) for row in parameters), 'rows must be node_tools.Param'
    specs = _params(parameters)
    names = [spec.name for spec in specs]
    assert len(names) == len(set(names)), f'declared more than once: {names}'
    for spec in specs:
        assert spec.description.strip(), f'{spec.name} has no description'
        spec.descriptor()  # builds
    assert any(spec.range for spec in specs), 'at least one numeric parameter has a range'
    with parameter_refusals(specs, check, check_all) as refused:   # the defaults start the node
        for spec in specs:
            bad = _outside(spec) + (['not-one-of-the-choices'] if spec.choices else [])
            if spec.read_only:
                bad = [spec.default]
            for value in bad:
                assert refused(spec.name, value), f'{spec.name}={value!r} was accepted'
    if config_path is not None:
        assert node_name, 'check_parameter_table: config_path needs node_name'
        check_config(specs, check, config_path, node_name, check_all)


def check_config(parameters: Sequence[Any], check: Check | None, config_path: str | Path,
                 node_name: str, check_all: Any = None) -> None:
    """The YAML at config_path is for node_name only and sets declared parameters to values of
    the declared types (use_sim_time aside), which a node declaring parameters starts with."""
    import yaml

    doc = yaml.safe_load(Path(config_path).read_text())
    assert list(doc) == [node_name], f'the config is for node {node_name} only, not {list(doc)}'
    params = doc[node_name]['ros__parameters']
    declared = {spec.name: spec.default for spec in _params(parameters)}
    undeclared = set(params) - {'use_sim_time'} - set(declared)
    assert not undeclared, f'{config_path} sets undeclared parameters {sorted(undeclared)}'
    values = {name: value for name, value in params.items() if name != 'use_sim_time'}
    for name, value in values.items():
        # ROS 2 parameters are typed: 15 (integer) does not override 15.0 (double).
        assert type(value) is type(declared[name]), (
            f'{name}: {type(value).__name__} in the config, {type(declared[name]).__name__} '
            'declared')
    problem = startup_problem(parameters, check, check_all, **values)
    assert problem is None, f'{config_path}: {problem}'


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
                  timeout: float | None = None, period: float = 0.2) -> bool:
    """Call publish() every period s while spinning until done() (best-effort QoS, such as sensor
    data, may drop a sample: send it again); False if done() never held within timeout (s, as
    given; by default scaled(10))."""
    timeout = scaled(10.0) if timeout is None else timeout
    for _ in range(max(1, int(timeout / period))):
        publish()
        if wait_until(done, period, spin=spin):
            return True
    return False


def refused_once(node: Any, spin: Any, publish: Callable[[], Any], key: tuple[str, str],
                 timeout: float | None = None, period: float = 2.0) -> bool:
    """publish() until node.input_health's count of key (topic, reason) rose by one, within
    timeout (s, as given; by default scaled(20)); sent again only after period s without it
    (best-effort QoS may drop a sample)."""
    timeout = scaled(20.0) if timeout is None else timeout
    before = node.input_health.refused().get(key, 0)
    return publish_until(publish, lambda: node.input_health.refused().get(key, 0) > before,
                         spin, timeout, period=period)


def reported_status(reports: Sequence[Any], node_name: str) -> dict[str, str]:
    """key -> value of the latest DiagnosticStatus named node_name in the DiagnosticArrays
    received (reports), {} before the first."""
    for array in reversed(reports):
        for status in array.status:
            if status.name == node_name:
                return {kv.key: kv.value for kv in status.values}
    return {}


@contextlib.contextmanager
def spinning(context: Any, nodes: Sequence[Any], ready: Callable[[], bool],
             timeout: float | None = None) -> Iterator[Any]:
    """A SingleThreadedExecutor over nodes in context, once ready() holds (e.g. every publisher
    matched) within timeout (s, as given; by default scaled(10)); yields the executor and
    afterwards removes and destroys the nodes (last first)."""
    from vizzy_runtime.ros import SingleThreadedExecutor

    timeout = scaled(10.0) if timeout is None else timeout

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


def check_node_parameters(ros_node: Any, parameters: Sequence[Any],
                          bad_name: str, bad_value: Any) -> None:
    """A running node declares every parameter at its default with the descriptor its row
    describes (range, read_only, additional_constraints, description), and refuses
    bad_name=bad_value, naming bad_name in the reason."""
    from vizzy_runtime.ros import Parameter

    for spec in _params(parameters):
        value = ros_node.get_parameter(spec.name).value
        value = list(value) if isinstance(spec.default, list) else value
        assert value == spec.default, f'{spec.name} is {value!r}, declared default {spec.default!r}'
        want, got = spec.descriptor(), ros_node.describe_parameter(spec.name)
        for field in ('description', 'additional_constraints', 'read_only'):
            assert getattr(got, field) == getattr(want, field), f'{spec.name}: {field} differs'
        for field in ('integer_range', 'floating_point_range'):
            ranges = [(r.from_value, r.to_value, r.step) for r in getattr(got, field)]
            assert ranges == [(r.from_value, r.to_value, r.step) for r in getattr(want, field)], (
                f'{spec.name}: {field} {ranges}')
    result = ros_node.set_parameters([Parameter(bad_name, value=bad_value)])[0]
    assert not result.successful, f'{bad_name}={bad_value!r} was accepted'
    assert bad_name in result.reason, f'the reason does not name {bad_name}: {result.reason!r}'


def bound_addresses(pid: int) -> list[tuple[str, str, int]]:
    """The inet sockets a process holds, as (protocol, local address, port), read from /proc (the
    process's fds and its network namespace's udp/tcp tables)."""
    import ipaddress
    import os
    inodes = set()
    for fd in os.listdir(f'/proc/{pid}/fd'):
        try:
            link = os.readlink(f'/proc/{pid}/fd/{fd}')
        except OSError:
            continue  # closed meanwhile
        if link.startswith('socket:['):
            inodes.add(link[8:-1])
    found = []
    for proto in ('udp', 'udp6', 'tcp', 'tcp6'):
        with open(f'/proc/{pid}/net/{proto}') as table:
            next(table)
            for row in table:
                cols = row.split()
                if cols[9] not in inodes:
                    continue
                hex_ip, hex_port = cols[1].split(':')
                raw = bytes.fromhex(hex_ip)
                # the kernel prints each 32-bit word in host (little-endian) order
                words = b''.join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
                found.append((proto, str(ipaddress.ip_address(words)), int(hex_port, 16)))
    return found
