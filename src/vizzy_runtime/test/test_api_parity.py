"""API parity of the seam (issue 30, deliverable 2): every function, method and property the seam
(vizzy_runtime.ros) gives our nodes has, on the bundled runtime, the real rclpy's signature
(parameter names, kinds and defaults), and an unknown keyword is refused, never ignored.

The real signatures cannot be imported here (the bundled tier has no rclpy): they are read from
rclpy_7.1.6_signatures.json, written by scripts/rclpy_signatures.py under .venv-ros; the `live`
test at the end, run again on the real-rclpy tier (scripts/test_ros.sh), fails when that
snapshot no longer matches the installed rclpy. Deliberate deviations are listed below with why,
and in vizzy_runtime/rclpy_compat/README.md."""

from __future__ import annotations

import ast
import importlib.util
import json
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[3]
_spec = importlib.util.spec_from_file_location('rclpy_signatures',
                                               ROOT / 'scripts' / 'rclpy_signatures.py')
assert _spec and _spec.loader
sigs: Any = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(sigs)

SNAPSHOT = json.loads(sigs.SNAPSHOT.read_text())
REAL: dict[str, Any] = SNAPSHOT['surface']

# (seam name, member) whose signature deliberately differs from rclpy's: why.
SIGNATURE_DEVIATIONS = {
    ('Publisher', '(constructor)'): 'made by Node.create_publisher only (rclpy: an rcl handle)',
    ('Subscription', '(constructor)'): 'made by Node.create_subscription only (as Publisher)',
    ('Timer', '(constructor)'): 'made by Node.create_timer only (as Publisher)',
    ('QoSProfile', '(constructor)'): "rclpy takes **kwargs and asserts each is one of its slots; "
                                     "here the same keywords are named (checked against the "
                                     "slots below), so an unknown one is a TypeError",
}
# Public members only the bundled runtime has: why. A node must not call them (it would break
# on rclpy); test_nodes_use_no_bundled_extension checks the modules that import the seam.
BUNDLED_EXTENSIONS = {
    ('AsyncParameterClient', 'destroy'): 'the ros2 param CLI frees its service endpoints',
    ('AsyncParameterClient', 'forget'): 'the CLI drops a future that timed out',
    ('Clock', 'ros_time_is_active'): "rclpy's ROSClock property, on every clock here (False "
                                     "unless ROS time): the executor asks any timer's clock",
    ('Clock', 'set_ros_time_override'): "rclpy's ROSClock method, inherited here from Clock",
    ('Context', 'discovery'): 'the DDS graph view (topic lists, counts)',
    ('Context', 'notify'): 'wakes the executors (no rcl wait set here)',
    ('Context', 'request_shutdown'): 'what the SIGINT/SIGTERM handler does',
    ('Node', 'check_topic_types'): 'the executor warns about peers using another message type',
    ('Publisher', 'guid'): 'the DDS writer GUID (graph, ros_discovery_info)',
    ('Publisher', 'wait_for_subscribers'): 'bundled-only tools and benches wait for discovery',
    ('QoSProfile', 'to_dds'): 'the Cyclone DDS QoS of a profile',
    ('Subscription', 'guid'): 'the DDS reader GUID (as Publisher.guid)',
    ('Subscription', 'take_and_dispatch'): 'called by the executor',
    ('Subscription', 'wait_for_publishers'): 'as Publisher.wait_for_subscribers',
    ('Timer', 'call'): 'called by the executor',
}
# (file, bundled-only method) called through the seam where only the bundled runtime runs: why.
KNOWN_EXTENSION_CALLS = {
    ('bench/transport.py', 'wait_for_subscribers'): '`make bench` runs on .venv (bundled only); '
                                                    'on rclpy it would raise AttributeError',
}
# Names the seam exports that are not rclpy classes or functions (or are messages, which the
# message tests hold to the .msg definitions).
SEAM_OWN = {'USING_REAL_ROS', 'message', 'warm_up', 'qos_profile_latched', 'rclpy', 'RCLError',
            'InvalidHandle', 'FloatingPointRange', 'IntegerRange', 'ParameterDescriptor',
            'ParameterType', 'SetParametersResult', 'qos_profile_sensor_data',
            'qos_profile_system_default'}


def _bundled() -> dict[str, Any]:
    return sigs.surface('bundled')


def _differences(name: str, real: dict[str, Any], mine: dict[str, Any]) -> list[str]:
    """What differs between rclpy's description of `name` and the bundled one's."""
    if real['kind'] != mine['kind']:
        return [f'{name}: rclpy has a {real["kind"]}, the bundled runtime a {mine["kind"]}']
    if real['kind'] == 'enum':   # a subset with rclpy's values (rclpy adds UNKNOWN, ...)
        return [f'{name}.{m}: {v} here, {real["members"].get(m)} in rclpy'
                for m, v in mine['members'].items() if real['members'].get(m) != v]
    if real['kind'] == 'function':
        return _signature_differences(name, real['signature'], mine['signature'])
    out = []
    for member, desc in mine['members'].items():
        where = f'{name}.{member}'
        if member not in real['members']:
            if (name, member) not in BUNDLED_EXTENSIONS:
                out.append(f'{where}: not in rclpy (add it to BUNDLED_EXTENSIONS with why, or '
                           'make it private)')
            continue
        if (name, member) in SIGNATURE_DEVIATIONS:
            continue
        theirs = real['members'][member]
        if theirs['kind'] != desc['kind']:
            out.append(f'{where}: a {desc["kind"]} here, a {theirs["kind"]} in rclpy')
        elif 'signature' in desc:
            out += _signature_differences(where, theirs['signature'], desc['signature'])
    return out


def _signature_differences(where: str, real: list | None, mine: list | None) -> list[str]:
    if real is None or mine is None:
        return [] if real == mine else [f'{where}: no readable signature on one side']

    def norm(params: list) -> list:   # a **kwargs / *args's own name does not matter to callers
        return [(('*' if kind.startswith('VAR') else name), kind, default)
                for name, kind, default in params]

    if norm(real) == norm(mine):
        return []
    return [f'{where}: rclpy {_text(real)} != bundled {_text(mine)}']


def _text(params: list) -> str:
    parts = []
    for name, kind, default in params:
        prefix = {'VAR_POSITIONAL': '*', 'VAR_KEYWORD': '**'}.get(kind, '')
        suffix = f'={default[0]}' if default else ''
        parts.append(f'{prefix}{name}{suffix}' + (' (kw-only)' if kind == 'KEYWORD_ONLY' else ''))
    return '(' + ', '.join(parts) + ')'


def test_snapshot_tracks_the_documented_rclpy():
    assert SNAPSHOT['rclpy_version'] == sigs.RCLPY_VERSION
    readme = (ROOT / 'src/vizzy_runtime/vizzy_runtime/rclpy_compat/README.md').read_text()
    assert f'rclpy {sigs.RCLPY_VERSION}' in readme
    assert sigs.SNAPSHOT.name == f'rclpy_{sigs.RCLPY_VERSION}_signatures.json'
    assert set(REAL) == set(sigs.TARGETS)


@pytest.mark.parametrize('name', sorted(sigs.TARGETS))
def test_bundled_signature_matches_rclpy(name):
    """Same parameter names, kinds and defaults as rclpy 7.1.6 (allow-lists above)."""
    problems = _differences(name, REAL[name], _bundled()[name])
    assert not problems, '\n'.join(problems)


def test_allow_lists_are_not_stale():
    """Every allow-listed deviation still exists (fixed ones leave the list)."""
    bundled = _bundled()
    for name, member in BUNDLED_EXTENSIONS:
        assert member in bundled[name]['members'], (name, member)
        assert member not in REAL[name]['members'], (name, member)
    for name, member in SIGNATURE_DEVIATIONS:
        assert bundled[name]['members'][member] != REAL[name]['members'][member], (name, member)


def test_qos_profile_keywords_are_rclpys():
    """rclpy's QoSProfile(**kwargs) accepts its slots; the bundled one names the same ones."""
    params = _bundled()['QoSProfile']['members']['(constructor)']['signature']
    assert sorted(p[0] for p in params) == REAL['QoSProfile']['slots']
    assert all(p[1] == 'KEYWORD_ONLY' for p in params)


def _project_files() -> list[Path]:
    skip = ('rclpy_compat', '.venv', 'build', 'node_modules')
    return [p for folder in ('src', 'bench', 'experiments', 'scripts')
            for p in sorted((ROOT / folder).rglob('*.py'))
            if not any(part in skip for part in p.relative_to(ROOT).parts)]


def _seam_imports(tree: ast.AST) -> set[str]:
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (
                node.module == 'vizzy_runtime.ros' or (node.module == 'ros' and node.level)):
            names |= {alias.name for alias in node.names}
    return names


@pytest.mark.slow
def test_every_seam_name_the_project_uses_is_checked():
    """The names imported from the seam anywhere in the project are in the snapshot (or are the
    seam's own), and so are the rclpy.<function>s called on its rclpy."""
    used: dict[str, str] = {}
    rclpy_calls: dict[str, str] = {}
    for path in _project_files():
        tree = ast.parse(path.read_text(), str(path))
        names = _seam_imports(tree)
        for name in names:
            used.setdefault(name, str(path.relative_to(ROOT)))
        if 'rclpy' in names:
            for node in ast.walk(tree):
                if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                        and node.value.id == 'rclpy'):
                    rclpy_calls.setdefault(node.attr, str(path.relative_to(ROOT)))
    assert len(used) > 10      # the scan found the project's imports
    unchecked = {n: f for n, f in used.items() if n not in sigs.TARGETS and n not in SEAM_OWN}
    assert not unchecked, f'seam names with no signature check: {unchecked}'
    unchecked = {n: f for n, f in rclpy_calls.items() if n not in sigs.RCLPY_FUNCTIONS}
    assert not unchecked, f'rclpy functions with no signature check: {unchecked}'


@pytest.mark.slow
def test_nodes_use_no_bundled_extension():
    """Modules that import the seam call none of the bundled-only methods (they would raise
    AttributeError on rclpy)."""
    real_names = {m for d in REAL.values() for m in d.get('members', {})}
    # the scan matches by name only: names common on other objects (Condition.notify, a
    # cache's forget, ...) are left out
    extensions = {member for _, member in BUNDLED_EXTENSIONS} - real_names - {
        'notify', 'forget', 'call'}
    found = []
    for path in _project_files():
        tree = ast.parse(path.read_text(), str(path))
        if not _seam_imports(tree):
            continue
        for node in ast.walk(tree):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr in extensions):
                where = str(path.relative_to(ROOT))
                if (where, node.func.attr) not in KNOWN_EXTENSION_CALLS:
                    found.append(f'{where}:{node.lineno}: .{node.func.attr}()')
    assert not found, '\n'.join(found)


# --- keywords: rclpy's are accepted (or refused with a reason), unknown ones are TypeErrors ---

@pytest.fixture
def node(context):
    from vizzy_runtime.rclpy_compat.node import Node
    n = Node('parity', context=context)
    yield n
    n.destroy_node()


def _string() -> Any:
    from vizzy_runtime import msgs
    return msgs.get_message('std_msgs/msg/String')


def _outcomes(calls: dict[str, Any]) -> dict[str, str]:
    """What each call raised, in a few words (every call is made, so one report names all)."""
    out = {}
    for what, call in calls.items():
        try:
            call()
            out[what] = 'accepted'
        except TypeError as err:
            out[what] = ('TypeError: unexpected keyword argument'
                         if 'unexpected keyword argument' in str(err) else f'TypeError: {err}')
        except NotImplementedError as err:
            text = str(err)
            ok = '\n' not in text and 'bundled' in text
            out[what] = ('NotImplementedError: one line, says bundled' if ok
                         else f'NotImplementedError: {text}')
    return out


def test_unknown_keywords_are_type_errors(context, node):
    from vizzy_runtime import rclpy_compat
    from vizzy_runtime.rclpy_compat.node import Node
    from vizzy_runtime.rclpy_compat.qos import QoSProfile
    calls = {
        'Node': lambda: Node('other', context=context, bogus=1),
        'create_node': lambda: rclpy_compat.create_node('other', context=context, bogus=1),
        'create_publisher': lambda: node.create_publisher(_string(), 't', 1, bogus=1),
        'create_subscription': lambda: node.create_subscription(_string(), 't', print, 1,
                                                                bogus=1),
        'create_subscription(direct)': lambda: node.create_subscription(_string(), 't', print,
                                                                        1, direct=True),
        'create_timer': lambda: node.create_timer(1.0, print, bogus=1),
        'QoSProfile': lambda: QoSProfile(depth=1, bogus=1),
        'init': lambda: rclpy_compat.init(context=context, bogus=1),
        'try_shutdown': lambda: rclpy_compat.try_shutdown(context=context, uninstall_handlers=1),
    }
    assert _outcomes(calls) == {what: 'TypeError: unexpected keyword argument' for what in calls}
    with pytest.raises(TypeError, match='not one of the recognized logging options'):
        node.get_logger().info('x', bogus=1)
    assert len(node.publishers) == 2 and not node.subscriptions and not node.timers
    assert context.ok()


def test_unsupported_rclpy_keywords_are_refused_with_a_reason(context, node):
    from vizzy_runtime.rclpy_compat.node import Node
    from vizzy_runtime.rclpy_compat.parameter_client import AsyncParameterClient
    from vizzy_runtime.rclpy_compat.qos import QoSProfile
    marker = object()
    calls = {
        'create_publisher(event_callbacks)': lambda: node.create_publisher(
            _string(), 't', 1, event_callbacks=marker),
        'create_publisher(qos_overriding_options)': lambda: node.create_publisher(
            _string(), 't', 1, qos_overriding_options=marker),
        'create_publisher(publisher_class)': lambda: node.create_publisher(
            _string(), 't', 1, publisher_class=type('Mine', (), {})),
        'create_subscription(event_callbacks)': lambda: node.create_subscription(
            _string(), 't', print, 1, event_callbacks=marker),
        'create_subscription(qos_overriding_options)': lambda: node.create_subscription(
            _string(), 't', print, 1, qos_overriding_options=marker),
        'Node(enable_logger_service)': lambda: Node('other', context=context,
                                                    enable_logger_service=True),
        'QoSProfile(avoid_ros_namespace_conventions)': lambda: QoSProfile(
            depth=1, avoid_ros_namespace_conventions=True),
        'AsyncParameterClient(qos_profile)': lambda: AsyncParameterClient(
            node, 'x', qos_profile=QoSProfile(depth=3)),
        'log(throttle_time_source_type)': lambda: node.get_logger().info(
            'x', throttle_duration_sec=1.0, throttle_time_source_type='RCUTILS_ROS_TIME'),
    }
    assert _outcomes(calls) == {what: 'NotImplementedError: one line, says bundled'
                                for what in calls}
    assert len(node.publishers) == 2 and not node.subscriptions      # /rosout, /parameter_events


def test_rclpy_keywords_the_runtime_honours(context, node):
    from vizzy_runtime.rclpy_compat import create_node
    from vizzy_runtime.rclpy_compat.executors import Future
    from vizzy_runtime.rclpy_compat.node import Publisher
    pub = node.create_publisher(_string(), 't', 1, callback_group=object(),
                                event_callbacks=None, qos_overriding_options=None,
                                publisher_class=Publisher)
    sub = node.create_subscription(_string(), 't', print, 1, callback_group=object(), raw=True)
    timer = node.create_timer(1.0, print, callback_group=object(), autostart=False)
    assert sub.raw and timer.is_canceled() and pub.topic == '/t'
    other = create_node('other', context=context, namespace='/ns', enable_logger_service=False)
    assert other.get_fully_qualified_name() == '/ns/other'
    other.destroy_node()
    assert node.get_logger().info('once', once=True, name='parity.other')
    assert Future(executor=None).done() is False


@pytest.mark.live
def test_snapshot_is_current():
    """On the real-rclpy tier: the committed snapshot is what the installed rclpy says (else
    rerun scripts/rclpy_signatures.py under .venv-ros)."""
    from vizzy_runtime.ros import USING_REAL_ROS
    if not USING_REAL_ROS:
        pytest.skip('reads the real rclpy: runs on the real-rclpy tier (scripts/test_ros.sh)')
    assert sigs.snapshot() == SNAPSHOT, ('rclpy_7.1.6_signatures.json is not current: rerun '
                                         'VIZZY_RUNTIME=ros .venv-ros/bin/python '
                                         'scripts/rclpy_signatures.py')
