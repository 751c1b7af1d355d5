"""Issue 29 item 5: launch arguments. `vizzy launch [graph.yaml] key:=value` and `ros2 launch
vizzy_runtime graph.launch.py key:=value` take scene, seed, params_file, namespace and use_sim_time
(and rviz under ros2 launch) with one meaning, through vizzy_runtime.launch_args.

No graph is started: the launcher's command lines are captured and each node's parameters read
from them by the bundled runtime's own --ros-args parser (what the node itself does at start-up).
The launch files run against stand-ins for launch / launch_ros (no launch wheels here), their
OpaqueFunction given the argument values a `ros2 launch ... key:=value` would give it.
"""

from __future__ import annotations

import ast
import importlib.util
import subprocess
import sys
import tempfile
import types
from pathlib import Path
from typing import Any

import pytest

from vizzy_runtime import cli, launcher
from vizzy_runtime.launch_args import (
    GRAPH_ARGUMENTS,
    NODE_ARGUMENTS,
    SCENES,
    VIZZY_LAUNCH_KEYS,
    LaunchArgs,
    LaunchError,
    launch_args,
    node_parameters,
)
from vizzy_runtime.rclpy_compat import arguments
from vizzy_runtime.testing import scaled

REPO = Path(__file__).resolve().parents[3]
NODES = {'sim', 'gaze_controller', 'foveation', 'stereo_ses', 'cylinder_detector', 'mot_planner',
         'object_map'}
PARAMS = '''\
/**:
  ros__parameters:
    probe: 7
foveation:
  ros__parameters:
    levels: 3
sim:
  ros__parameters:
    scene: pedestrians
    pedestrian_count: 6
'''


def _params_file(tmp_path: Path) -> Path:
    path = tmp_path / 'my.yaml'
    path.write_text(PARAMS)
    return path


def _overrides(cmd: list[str]) -> dict[str, Any]:
    """The parameter values the node started by cmd gets (later sources win, as in rcl)."""
    args = arguments.parse(cmd)
    return args.parameter_overrides(f"{args.namespace('?', '')}/{args.node_name('?')}")


def _vizzy_launch(monkeypatch, argv: list[str]) -> tuple[int, dict[str, list[str]],
                                                          dict[str, dict[str, Any]]]:
    """cli.main(['launch', *argv]) with the node processes not started: (exit code, each node's
    command line, the parameters each would get, read while its params files exist)."""
    commands: dict[str, list[str]] = {}
    params: dict[str, dict[str, Any]] = {}

    def spawn(self: launcher.Launcher, name: str) -> None:
        commands[name] = self._commands[name][1]
        params[name] = _overrides(commands[name])

    monkeypatch.setattr(launcher.Launcher, '_spawn', spawn)
    monkeypatch.setattr(launcher, 'names_taken', lambda names, wait_s=0.0: [])
    code = cli.main(['launch', *argv, '--no-view', '--duration', '0.1'])
    return code, commands, params


def test_vizzy_launch_gives_the_sim_the_scene_and_every_node_the_params_file(monkeypatch,
                                                                             tmp_path):
    mine = _params_file(tmp_path)
    code, _, params = _vizzy_launch(monkeypatch, [
        str(REPO / 'src/vizzy_runtime/config/graph.yaml'), 'scene:=visual_search', 'seed:=3',
        f'params_file:={mine}'])
    assert code == 0 and set(params) == NODES
    # the explicit scene:= wins over the file's sim: scene; the file's other sim values apply
    assert params['sim']['scene'] == 'visual_search' and params['sim']['seed'] == 3
    assert params['sim']['pedestrian_count'] == 6       # config/sim.yaml says 4
    assert params['foveation']['levels'] == 3           # config/foveation.yaml says 5
    assert all(p['probe'] == 7 for p in params.values()), params    # the /** section: every node
    assert all('scene' not in p for name, p in params.items() if name != 'sim')
    # use_sim_time stays the graph's: the sim on wall time, the rest following its /clock
    assert params['sim']['use_sim_time'] is False
    assert all(p['use_sim_time'] is True for name, p in params.items() if name != 'sim')

    # without arguments: sim.yaml's scene and seed, no probe
    code, _, params = _vizzy_launch(monkeypatch, [])
    sim = params['sim']
    assert code == 0 and (sim['scene'], sim['seed']) == ('tabletop', 0) and 'probe' not in sim


def test_namespace_and_use_sim_time_keys(monkeypatch, tmp_path):
    mine = _params_file(tmp_path)
    code, commands, params = _vizzy_launch(monkeypatch, [
        'namespace:=/head2', 'use_sim_time:=false', f'params_file:={mine}'])
    assert code == 0 and all('__ns:=/head2' in cmd for cmd in commands.values())
    # the file's bare `foveation:` section still reaches /head2/foveation (a /**/foveation copy)
    assert params['foveation']['levels'] == 3 and params['sim']['pedestrian_count'] == 6
    assert all(p['use_sim_time'] is False for p in params.values())
    # --namespace keeps working, and agrees with namespace:=
    code, commands, _ = _vizzy_launch(monkeypatch, ['--namespace', '/head3', 'namespace:=/head3'])
    assert code == 0 and all('__ns:=/head3' in cmd for cmd in commands.values())


@pytest.mark.parametrize('argv, message', [
    (['bogus:=1'], "vizzy: unknown launch argument 'bogus' (known: scene, seed, params_file, "
                   'namespace, use_sim_time)'),
    (['scene:=moon'], 'vizzy: scene:=moon: expected one of tabletop, visual_search, pedestrians'),
    (['seed:=x'], 'vizzy: seed:=x: expected an integer >= 0'),
    (['use_sim_time:=maybe'], 'vizzy: use_sim_time:=maybe: expected true or false'),
    (['params_file:=/nonexistent/my.yaml'],
     'vizzy: params_file:=/nonexistent/my.yaml: no such file'),
    (['--namespace', '/a', 'namespace:=/b'],
     'vizzy: launch: --namespace /a and namespace:=/b disagree: give one'),
    (['a.yaml', 'b.yaml'],
     'vizzy: launch: one graph file, got 2 (a.yaml, b.yaml); launch arguments read key:=value'),
])
def test_bad_launch_arguments_are_refused_in_one_line(monkeypatch, capsys, argv, message):
    code, commands, _ = _vizzy_launch(monkeypatch, argv)
    assert (code, commands) == (2, {})
    assert capsys.readouterr().err == message + '\n'


def test_a_params_file_that_is_no_parameters_file_is_refused(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('levels: 3\n')
    with pytest.raises(LaunchError, match=r'params_file:=.*bad\.yaml: expected `<node name'):
        launch_args({'params_file': str(bad)})


def test_vizzy_launch_refuses_an_unknown_key_before_starting_anything():
    done = subprocess.run([sys.executable, '-m', 'vizzy_runtime.cli', 'launch', 'rviz:=true'],
                          capture_output=True, text=True, timeout=scaled(120))
    assert done.returncode == 2 and done.stdout == ''
    assert done.stderr.splitlines() == [
        "vizzy: unknown launch argument 'rviz' (known: scene, seed, params_file, namespace, "
        'use_sim_time)']


def test_node_parameters_order_and_defaults(tmp_path):
    own = tmp_path / 'sim.yaml'
    own.write_text('sim: {ros__parameters: {scene: tabletop}}\n')
    mine = _params_file(tmp_path)
    args = launch_args({'scene': 'pedestrians', 'seed': '4', 'params_file': str(mine),
                        'namespace': '/', 'use_sim_time': '', 'rviz': 'false'})
    assert args == LaunchArgs(namespace='', use_sim_time=None, scene='pedestrians', seed=4,
                              params_file=mine.resolve(), rviz=False)
    # own files, use_sim_time, the params_file, then the sim's explicit scene and seed
    assert node_parameters('vizzy_sim_bridge', 'sim', [own], False, args) == [
        own, {'use_sim_time': False}, mine.resolve(), {'scene': 'pedestrians', 'seed': 4}]
    assert node_parameters('foveation_node', 'foveation', [own], True, args) == [
        own, {'use_sim_time': True}, mine.resolve()]
    # namespaced: copies keyed /**/<name>
    proofed = node_parameters('foveation_node', 'foveation', [own], True, args, tmp_path / 'p')
    assert all(p.parent == tmp_path / 'p' for p in proofed if isinstance(p, Path))
    assert launch_args({}) == LaunchArgs()
    assert set(VIZZY_LAUNCH_KEYS) == set(GRAPH_ARGUMENTS) - {'rviz'}


def test_scenes_are_the_simulators():
    from vizzy_sim_bridge.core.scenes import SCENE_NAMES
    assert SCENES == SCENE_NAMES


# --- the launch files, against stand-ins for launch and launch_ros --------------------------------

class _Recorded:
    """Stands in for a launch / launch_ros class: keeps its arguments."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args, self.kwargs = args, kwargs


class _Configuration(_Recorded):
    def perform(self, context: dict[str, str]) -> str:
        return context[self.args[0]]


def _fake_launch_modules(monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setattr(tempfile, 'tempdir', str(tmp_path))  # the launch files' params copies
    fakes: dict[str, dict[str, Any]] = {
        'ament_index_python': {}, 'launch_ros': {},
        'ament_index_python.packages': {
            'get_package_share_directory': lambda pkg: str(REPO / 'src' / pkg)},
        'launch': {'LaunchDescription': lambda actions: list(actions)},
        'launch.actions': {name: _Recorded for name in (
            'DeclareLaunchArgument', 'GroupAction', 'IncludeLaunchDescription', 'OpaqueFunction')},
        'launch.launch_description_sources': {'PythonLaunchDescriptionSource': _Recorded},
        'launch.substitutions': {'LaunchConfiguration': _Configuration},
        'launch_ros.actions': {name: _Recorded for name in (
            'Node', 'PushROSNamespace', 'SetRemap')},
        'launch_ros.parameter_descriptions': {'ParameterValue': _Recorded},
    }
    for name, attrs in fakes.items():
        module = types.ModuleType(name)
        module.__dict__.update(attrs)
        monkeypatch.setitem(sys.modules, name, module)


def _run_launch_file(path: Path, given: dict[str, str]) -> tuple[dict[str, str], list[Any]]:
    """(declared arguments with their defaults, top-level actions + the OpaqueFunction's Nodes)
    for `ros2 launch <path> key:=value...`."""
    spec = importlib.util.spec_from_file_location(path.stem.replace('.', '_'), path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    actions = module.generate_launch_description()
    declared = {a.args[0]: a.kwargs['default_value'] for a in actions
                if a.kwargs.get('description')}
    context = {**declared, **given}
    out = []
    for action in actions:
        inner = action.args[0] if action.args and isinstance(action.args[0], list) else [action]
        for a in inner:
            if 'function' in a.kwargs:
                out += a.kwargs['function'](context, *a.kwargs.get('args', []))
            else:
                out.append(a)
    return declared, out


def test_graph_launch_file_declares_and_passes_the_arguments(monkeypatch, tmp_path):
    _fake_launch_modules(monkeypatch, tmp_path)
    mine = _params_file(tmp_path)
    path = REPO / 'src/vizzy_runtime/launch/graph.launch.py'
    declared, actions = _run_launch_file(path, {
        'scene': 'visual_search', 'seed': '3', 'params_file': str(mine)})
    assert declared == {'use_sim_time': 'true', 'namespace': '/', 'scene': '', 'seed': '',
                        'params_file': '', 'rviz': 'false'}
    nodes = {a.kwargs['name']: a.kwargs for a in actions if 'executable' in a.kwargs}
    assert set(nodes) == NODES
    sim = nodes['sim']['parameters']
    assert sim[-1] == {'scene': 'visual_search', 'seed': 3} and {'use_sim_time': False} in sim
    for name, node in nodes.items():
        files = [p for p in node['parameters'] if isinstance(p, str)]
        # the params_file (a namespace-proof copy) comes after the node's own config
        assert len(files) == 2 and f'/**/{name}:' in Path(files[0]).read_text()
        assert '/**/foveation:' in Path(files[1]).read_text()
        assert 'probe: 7' in Path(files[1]).read_text()
        assert node['respawn'] is True and node['additional_env']['OMP_NUM_THREADS']
    assert {'use_sim_time': True} in nodes['foveation']['parameters']
    assert not [a for a in actions if 'launch_arguments' in a.kwargs]      # rviz: false
    # rviz:=true includes vizzy_sim_bridge's rviz.launch.py, with the graph's use_sim_time;
    # use_sim_time:=false reaches the nodes that follow the graph's value
    _, actions = _run_launch_file(path, {'use_sim_time': 'false', 'rviz': 'true'})
    fov = next(a.kwargs for a in actions if a.kwargs.get('name') == 'foveation')
    assert {'use_sim_time': False} in fov['parameters']
    (rviz,) = [a for a in actions if 'launch_arguments' in a.kwargs]
    assert rviz.args[0].args[0].endswith('vizzy_sim_bridge/launch/rviz.launch.py')
    assert [(k, v.args) for k, v in rviz.kwargs['launch_arguments']] == [
        ('use_sim_time', ('use_sim_time',))]
    with pytest.raises(LaunchError, match='rviz:=maybe: expected true or false'):
        _run_launch_file(path, {'rviz': 'maybe'})
    # the same argument list as launch_args declares (checked without the stand-ins too)
    assert "GRAPH_ARGUMENTS" in path.read_text() and ast.parse(path.read_text())


NODE_LAUNCH_FILES = sorted(p for p in REPO.glob('src/*/launch/*.launch.py')
                           if p.parent.parent.name not in ('vizzy_runtime', 'vizzy_sim_bridge'))


@pytest.mark.parametrize('path', NODE_LAUNCH_FILES, ids=lambda p: p.name)
def test_node_launch_files_take_namespace_and_params_file(monkeypatch, tmp_path, path):
    _fake_launch_modules(monkeypatch, tmp_path)
    mine = _params_file(tmp_path)
    declared, actions = _run_launch_file(path, {
        'namespace': '/head2', 'params_file': str(mine), 'use_sim_time': 'true'})
    assert declared == {key: default for key, (default, _) in NODE_ARGUMENTS.items()}
    (node,) = [a.kwargs for a in actions if 'executable' in a.kwargs]
    assert node['namespace'] == '/head2'
    own, sim_time, extra = node['parameters']
    assert sim_time == {'use_sim_time': True}
    assert f"/**/{node['name']}" in Path(own).read_text()      # proofed for the namespace
    assert 'probe: 7' in Path(extra).read_text()
    _, actions = _run_launch_file(path, {})
    (node,) = [a.kwargs for a in actions if 'executable' in a.kwargs]
    assert node['namespace'] is None and node['parameters'][1] == {'use_sim_time': False}
    assert len(node['parameters']) == 2
