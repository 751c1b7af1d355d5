"""Launch the whole Vizzy graph of config/graph.yaml (the file `vizzy launch` reads without ROS).

    ros2 launch vizzy_runtime graph.launch.py [use_sim_time:=true|false] [namespace:=/head2]

Nodes use relative topic names, so `namespace:=/head2` moves the whole graph (PushROSNamespace);
/clock, /tf and /tf_static are remapped to relative names for every node (SetRemap: a no-op at the
root namespace), so rclpy's time source and absolute tf users stay inside the namespace too. rcl
applies a params file's bare `sim:` section to /sim only, so each node gets a copy of its files
whose bare keys read `/**/sim` (the same at the root). The same as `vizzy launch --namespace
/head2` (vizzy_runtime/launcher.py: GRAPH_REMAPS, namespace_proof_params).
"""

import os
import tempfile

import yaml
from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, GroupAction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node, PushROSNamespace, SetRemap
from launch_ros.parameter_descriptions import ParameterValue


def _load_graph(path: str) -> dict:
    """The graph description, checked enough to name the entry at fault."""
    with open(path) as f:
        graph = yaml.safe_load(f)
    if not isinstance(graph, dict) or not isinstance(graph.get('nodes'), list):
        raise RuntimeError(f'{path}: expected a mapping with a list under "nodes"')
    for i, entry in enumerate(graph['nodes']):
        missing = [k for k in ('package', 'executable', 'name')
                   if not isinstance(entry, dict) or not entry.get(k)]
        if missing:
            raise RuntimeError(f'{path}: node #{i} lacks {", ".join(missing)}')
    return graph


def _namespace_proof(path: str, out_dir: str) -> str:
    """path, or a copy in out_dir whose bare node-name keys (`sim:`, which rcl matches to /sim
    only) read `/**/sim:`, so the file applies to that node inside any namespace."""
    with open(path) as f:
        data = yaml.safe_load(f)
    if not isinstance(data, dict) or all(str(key).startswith('/') for key in data):
        return path
    stem = os.path.splitext(os.path.basename(path))[0]
    fd, out = tempfile.mkstemp(prefix=stem + '_', suffix='.yaml', dir=out_dir)
    with os.fdopen(fd, 'w') as f:
        yaml.safe_dump({(key if str(key).startswith('/') else '/**/' + str(key)): value
                        for key, value in data.items()}, f, sort_keys=False)
    return out


def generate_launch_description() -> LaunchDescription:
    graph_file = os.path.join(
        get_package_share_directory('vizzy_runtime'), 'config', 'graph.yaml')
    graph = _load_graph(graph_file)
    actions = [DeclareLaunchArgument(
        'use_sim_time', default_value=str(bool(graph.get('use_sim_time', False))).lower(),
        description='Follow /clock in every node that does not set use_sim_time itself.'),
        DeclareLaunchArgument(
            'namespace', default_value='/',
            description='Namespace of the whole graph, e.g. /head2 (every topic moves with it).')]
    # the graph's scope: its namespace, and /clock, /tf, /tf_static relative for every node
    group = [PushROSNamespace(LaunchConfiguration('namespace')), SetRemap('/clock', 'clock'),
             SetRemap('/tf', 'tf'), SetRemap('/tf_static', 'tf_static')]
    params_dir = tempfile.mkdtemp(prefix='vizzy_launch_')
    # the graph's environment defaults; the caller's own environment wins
    env = {str(k): os.environ.get(str(k), str(v)) for k, v in (graph.get('env') or {}).items()}
    for entry in graph['nodes']:
        share = get_package_share_directory(entry['package'])
        parameters = [_namespace_proof(os.path.join(share, rel), params_dir)
                      for rel in entry.get('parameters') or []]
        if 'use_sim_time' in entry:  # per-node override (the sim is the /clock source)
            parameters.append({'use_sim_time': bool(entry['use_sim_time'])})
        else:
            parameters.append({'use_sim_time': ParameterValue(
                LaunchConfiguration('use_sim_time'), value_type=bool)})
        respawn = {'respawn': bool(entry.get('respawn', graph.get('respawn', False))),
                   'respawn_delay': float(entry.get('respawn_delay',
                                                    graph.get('respawn_delay', 0.0)))}
        if 'respawn_max_retries' in entry:
            respawn['respawn_max_retries'] = int(entry['respawn_max_retries'])
        group.append(Node(
            package=entry['package'],
            additional_env=env,
            executable=entry['executable'],
            name=entry['name'],
            namespace=entry.get('namespace') or None,
            parameters=parameters,
            remappings=[(str(k), str(v)) for k, v in (entry.get('remappings') or {}).items()],
            output='screen',
            **respawn,
        ))
    actions.append(GroupAction(group))
    return LaunchDescription(actions)
