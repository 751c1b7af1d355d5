"""vizzy_runtime/config/vizzy.rviz names only topics the graph publishes, with matching QoS.

The graph's publishers are read from the source, without importing any node (no dependency on
the other packages): for each node of config/graph.yaml, its module (from its package's
setup.py console script) is parsed; every `create_publisher(Type, TOPIC, QOS)` call gives a
topic, evaluated from the module's constants and resolved as rcl does at the graph's namespace
(`~/x` -> /<node>/x, `x` -> /x, then the graph's remappings), and whether its QoS is the sensor
data profile (best effort) or latched (transient local).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import Any

import yaml

from vizzy_runtime.tf import TF_STATIC_TOPIC, TF_TOPIC
from vizzy_vision.kinematics import FRAME_NAMES

SRC = Path(__file__).resolve().parents[2]
RVIZ = SRC / 'vizzy_runtime' / 'config' / 'vizzy.rviz'
GRAPH = SRC / 'vizzy_runtime' / 'config' / 'graph.yaml'
# names a node module may import rather than define
IMPORTED = {'TF_TOPIC': TF_TOPIC, 'TF_STATIC_TOPIC': TF_STATIC_TOPIC}


def _node_module(package: str, executable: str) -> Path:
    setup = (SRC / package / 'setup.py').read_text()
    match = re.search(rf"""['"]{re.escape(executable)}\s*=\s*([\w.]+):\w+['"]""", setup)
    assert match, f'{package}/setup.py has no console script {executable}'
    return SRC / package / (match.group(1).replace('.', '/') + '.py')


def _constants(tree: ast.Module, names: dict[str, Any] | None = None) -> dict[str, Any]:
    """Module-level NAME = <expression of constants> assignments, evaluated in order (on top of
    names)."""
    names = dict(IMPORTED if names is None else names)
    for stmt in tree.body:
        if isinstance(stmt, ast.Assign) and all(isinstance(t, ast.Name) for t in stmt.targets):
            try:
                value = eval(compile(ast.Expression(stmt.value), '<constant>', 'eval'),
                             {'__builtins__': {}}, dict(names))
            except Exception:   # calls, classes, anything not made of constants
                continue
            for target in stmt.targets:
                names[target.id] = value
    return names


def _topics(expr: ast.expr, names: dict[str, Any]) -> list[str]:
    """The topic names an argument expression can take (a dict lookup: each value)."""
    def value(e: ast.expr) -> Any:
        return eval(compile(ast.Expression(e), '<topic>', 'eval'), {'__builtins__': {}},
                    dict(names))
    try:
        v = value(expr)
        return [v] if isinstance(v, str) else []
    except Exception:
        pass
    if isinstance(expr, ast.Subscript):
        try:
            v = value(expr.value)
        except Exception:
            return []
        if isinstance(v, dict):
            return [t for t in v.values() if isinstance(t, str)]
    return []   # e.g. f-strings over a loop variable: ground-truth topics, not in the view


def _resolve(topic: str, node: str, namespace: str, remappings: dict[str, str]) -> str:
    topic = remappings.get(topic, topic)
    ns = '/' + namespace.strip('/') if namespace.strip('/') else ''
    if topic.startswith('~/'):
        return f'{ns}/{node}/{topic[2:]}'
    return topic if topic.startswith('/') else f'{ns}/{topic}'


def graph_publishers() -> dict[str, dict[str, Any]]:
    """{resolved topic: {'node': name, 'best_effort': bool, 'latched': bool, 'source': path}}."""
    graph = yaml.safe_load(GRAPH.read_text())
    out: dict[str, dict[str, Any]] = {}
    for spec in graph['nodes']:
        path = _node_module(spec['package'], spec['executable'])
        tree = ast.parse(path.read_text(), str(path))
        # a node imports its topic names from its package's modules (parameters.py, ...)
        names: dict[str, Any] = dict(IMPORTED)
        for module in sorted(path.parent.glob('*.py')):
            if module != path:
                names = _constants(ast.parse(module.read_text(), str(module)), names)
        names = _constants(tree, names)
        for call in ast.walk(tree):
            if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Attribute)
                    and call.func.attr == 'create_publisher'):
                continue
            args = list(call.args) + [k.value for k in call.keywords if k.arg in ('topic',
                                                                                 'qos_profile')]
            if len(args) < 3:
                continue
            qos = ast.unparse(args[2])
            for topic in _topics(args[1], names):
                resolved = _resolve(topic, spec['name'], spec.get('namespace', ''),
                                    spec.get('remappings') or {})
                out[resolved] = {'node': spec['name'], 'best_effort': 'sensor_data' in qos,
                                 'latched': 'latched' in qos, 'source': path}
    return out


def _displays(displays: list[dict[str, Any]]) -> list[dict[str, Any]]:
    out = []
    for d in displays:
        out.append(d)
        out += _displays(d.get('Displays', []))   # groups
    return out


def _topic_properties(display: dict[str, Any]) -> list[dict[str, Any]]:
    return [v for k, v in display.items()
            if 'Topic' in k and isinstance(v, dict) and isinstance(v.get('Value'), str)]


def test_every_topic_in_the_rviz_config_is_published_by_the_graph() -> None:
    config = yaml.safe_load(RVIZ.read_text())
    manager = config['Visualization Manager']
    displays = _displays(manager['Displays'])
    published = graph_publishers()
    # the graph's outputs this view is about (a sanity check of the source reader itself)
    assert {'/vizzy/left/image_raw', '/stereo/points', '/ses/cells', '/cylinders/markers',
            '/mot/overlay', '/robot_description', '/tf', '/tf_static'} <= set(published)
    named = {}
    for d in displays:
        for prop in _topic_properties(d):
            named[prop['Value']] = (d, prop)
    assert set(named) >= {
        '/vizzy/left/image_raw', '/vizzy/right/image_raw', '/foveation/overlay', '/mot/overlay',
        '/stereo/points', '/ses/cells', '/cylinders/markers', '/robot_description'}
    missing = sorted(set(named) - set(published))
    assert not missing, f'vizzy.rviz names topics no node of graph.yaml publishes: {missing}'
    for topic, (display, prop) in named.items():
        pub = published[topic]
        if prop['Reliability Policy'] == 'Reliable':   # a reliable reader needs a reliable writer
            assert not pub['best_effort'], f'{topic}: {pub["node"]} publishes best effort'
        if prop['Durability Policy'] == 'Transient Local':
            assert pub['latched'], f'{topic}: {pub["node"]} does not publish transient local'
        if display.get('Color Transformer') == 'Intensity':   # colour by a field of the cloud
            field = display['Channel Name']
            sources = sorted(pub['source'].parent.rglob('*.py'))   # the node's package
            assert any(re.search(rf"""\(\s*['"]{field}['"]\s*,""", f.read_text())
                       for f in sources), f'{topic}: no field {field!r} in {pub["node"]}'


def test_the_view_is_in_a_head_frame_and_shows_the_head() -> None:
    manager = yaml.safe_load(RVIZ.read_text())['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == 'base_link' in FRAME_NAMES
    classes = [d['Class'] for d in _displays(manager['Displays'])]
    for cls in ('Grid', 'TF', 'RobotModel', 'PointCloud2', 'MarkerArray', 'Image'):
        assert f'rviz_default_plugins/{cls}' in classes
    # both cameras, foveation, tracks, cylinders
    assert classes.count('rviz_default_plugins/Image') == 5
    model = next(d for d in manager['Displays'] if d['Class'].endswith('/RobotModel'))
    assert model['Description Source'] == 'Topic'
    assert model['Description Topic']['Durability Policy'] == 'Transient Local'
