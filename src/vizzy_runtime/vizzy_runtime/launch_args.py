"""Launch arguments of the Vizzy graph, shared by `ros2 launch vizzy_runtime graph.launch.py` (and
each node's own launch file) and `vizzy launch` (launcher.py), so both read `scene:=`, `seed:=`,
`params_file:=`, `namespace:=` and `use_sim_time:=` the same way.

Pure and ROS-free: the launch files resolve their LaunchConfigurations in an OpaqueFunction and
hand the strings to launch_args(); node_parameters() then gives each node's parameters in the
order rcl applies them (later wins): the node's own files, use_sim_time, the params_file (so a
`/**:` or `<node name>:` section of it overrides the defaults), then scene and seed for the sim
(explicit arguments win over any file).
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml


class LaunchError(ValueError):
    """A graph description or node that cannot be launched (the message says which and why)."""


# vizzy_sim_bridge.core.scenes.SCENE_NAMES (not imported: the sim depends on this package, not
# the other way round; a test keeps the two equal)
SCENES: tuple[str, ...] = ('tabletop', 'visual_search', 'pedestrians')
# the node that takes scene and seed (package, executable)
SIM = ('vizzy_sim_bridge', 'sim')

# name -> (default, description); '' = unset (the graph's or the node's files' value)
GRAPH_ARGUMENTS: dict[str, tuple[str, str]] = {
    'use_sim_time': ('', 'Follow /clock in every node that does not set use_sim_time itself '
                         '(default: the graph\'s use_sim_time).'),
    'namespace': ('/', 'Namespace of the whole graph, e.g. /head2 (every topic moves with it).'),
    'scene': ('', 'Simulator scene: ' + ' | '.join(SCENES) + ' (default: config/sim.yaml\'s).'),
    'seed': ('', 'Simulator seed, an integer >= 0 (default: config/sim.yaml\'s).'),
    'params_file': ('', 'An extra ROS 2 parameters YAML given to every node after its own files: '
                        'its /** or <node name> sections override the defaults.'),
    'rviz': ('false', 'Also start RViz (vizzy_sim_bridge rviz.launch.py).'),
}
# what a single node's launch file (src/<pkg>/launch/<node>.launch.py) declares
NODE_ARGUMENTS: dict[str, tuple[str, str]] = {
    'use_sim_time': ('false', 'Follow /clock (true with the sim, or a bag played with --clock).'),
    'namespace': ('', 'Namespace of the node, e.g. /head2.'),
    'params_file': ('', 'An extra ROS 2 parameters YAML after the node\'s own config: its /** or '
                        '<node name> section overrides the defaults.'),
}
# what `vizzy launch` takes after the graph file (rviz needs rviz2: ros2 launch only)
VIZZY_LAUNCH_KEYS: tuple[str, ...] = ('scene', 'seed', 'params_file', 'namespace', 'use_sim_time')


@dataclass(frozen=True)
class LaunchArgs:
    """Resolved launch arguments; None: not given (the graph's or the files' own value)."""

    namespace: str = ''
    use_sim_time: bool | None = None
    scene: str | None = None
    seed: int | None = None
    params_file: Path | None = None
    rviz: bool = False


def split_key_values(items: Sequence[str], known: Sequence[str]) -> dict[str, str]:
    """['scene:=pedestrians', ...] -> {'scene': 'pedestrians'}, as ros2 launch reads its
    `key:=value` arguments; LaunchError (one line, listing the known keys) for anything else."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition(':=')
        if not sep or not key:
            raise LaunchError(f'launch argument {item!r}: expected key:=value '
                              f'(known keys: {", ".join(known)})')
        if key not in known:
            raise LaunchError(f'unknown launch argument {key!r} (known: {", ".join(known)})')
        out[key] = value
    return out


def _bool(key: str, text: str) -> bool:
    value = text.strip().lower()
    if value not in ('true', 'false'):
        raise LaunchError(f'{key}:={text}: expected true or false')
    return value == 'true'


def launch_args(values: Mapping[str, str]) -> LaunchArgs:
    """Check launch argument strings (a missing or '' value: not given) -> LaunchArgs;
    LaunchError names the argument and what it expects."""
    def given(key: str) -> str:
        return str(values.get(key) or '').strip()

    scene = given('scene') or None
    if scene is not None and scene not in SCENES:
        raise LaunchError(f'scene:={scene}: expected one of {", ".join(SCENES)}')
    seed = None
    if given('seed'):
        try:
            seed = int(given('seed'))
        except ValueError:
            seed = -1
        if seed < 0:
            raise LaunchError(f'seed:={given("seed")}: expected an integer >= 0')
    params_file = None
    if given('params_file'):
        params_file = Path(given('params_file')).expanduser().resolve()
        check_params_file(params_file)
    namespace = given('namespace')
    return LaunchArgs(
        namespace='' if namespace == '/' else namespace,
        use_sim_time=_bool('use_sim_time', given('use_sim_time')) if given('use_sim_time')
        else None,
        scene=scene, seed=seed, params_file=params_file,
        rviz=_bool('rviz', given('rviz')) if given('rviz') else False)


def check_params_file(path: Path) -> None:
    """A ROS 2 parameters file: a mapping of node names (`/**`, `sim`, `/head2/sim`) to
    `ros__parameters`; LaunchError names the file and what is wrong."""
    if not path.is_file():
        raise LaunchError(f'params_file:={path}: no such file')
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise LaunchError(f'params_file:={path}: not valid YAML '
                          f'({" ".join(str(exc).split())})') from None
    if not isinstance(data, dict) or not all(
            isinstance(section, dict) and isinstance(section.get('ros__parameters'), dict)
            for section in data.values()):
        raise LaunchError(f'params_file:={path}: expected `<node name or /**>: ros__parameters: '
                          '{name: value}` sections')


def namespace_proof_params(path: Path, out_dir: Path) -> Path:
    """path, or a copy of it in out_dir whose bare node-name keys (`sim:`, which rcl matches to
    the node /sim only) read `/**/sim:`, matching that node name in any namespace."""
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise LaunchError(f'parameters file {path}: {exc}') from None
    if not isinstance(data, dict) or all(str(key).startswith('/') for key in data):
        return path
    out_dir.mkdir(parents=True, exist_ok=True)
    out = Path(tempfile.mkstemp(prefix=f'{path.stem}_', suffix='.yaml', dir=out_dir)[1])
    out.write_text(yaml.safe_dump(
        {(key if str(key).startswith('/') else f'/**/{key}'): value for key, value in data.items()},
        sort_keys=False))
    return out


def node_parameters(package: str, executable: str, files: Sequence[Path], use_sim_time: bool,
                    args: LaunchArgs, proof_dir: Path | None = None) -> list[Path | dict[str, Any]]:
    """One node's parameters, in the order they apply (later wins): its own files, use_sim_time,
    args.params_file, then scene and seed if it is the sim. proof_dir: where namespace-proof
    copies of the files go (a namespaced node; None: the files as they are). A path stands for
    `--params-file`, a dict for `-p name:=value` each (launch_ros's Node takes both)."""
    def proof(path: Path) -> Path:
        return namespace_proof_params(path, proof_dir) if proof_dir is not None else path

    out: list[Path | dict[str, Any]] = [proof(path) for path in files]
    out.append({'use_sim_time': use_sim_time})
    if args.params_file is not None:
        out.append(proof(args.params_file))
    if (package, executable) == SIM:
        sim = {k: v for k, v in (('scene', args.scene), ('seed', args.seed)) if v is not None}
        if sim:
            out.append(sim)
    return out


def param_assignment(name: str, value: Any) -> str:
    """`-p`'s name:=value, the value in YAML that reads back as the same value."""
    text = yaml.safe_dump(value, default_flow_style=True, width=1 << 20).strip()
    return f'{name}:={text.removesuffix("...").strip()}'
