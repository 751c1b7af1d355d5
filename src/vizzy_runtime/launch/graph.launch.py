"""Launch the whole Vizzy graph of config/graph.yaml (the file `vizzy launch` reads without ROS).

    ros2 launch vizzy_runtime graph.launch.py [use_sim_time:=true|false]
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
import yaml


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


def generate_launch_description() -> LaunchDescription:
    graph_file = os.path.join(
        get_package_share_directory('vizzy_runtime'), 'config', 'graph.yaml')
    graph = _load_graph(graph_file)
    actions = [DeclareLaunchArgument(
        'use_sim_time', default_value=str(bool(graph.get('use_sim_time', False))).lower(),
        description='Follow /clock in every node that does not set use_sim_time itself.')]
    for entry in graph['nodes']:
        share = get_package_share_directory(entry['package'])
        parameters = [os.path.join(share, rel) for rel in entry.get('parameters') or []]
        if 'use_sim_time' in entry:  # per-node override (the sim is the /clock source)
            parameters.append({'use_sim_time': bool(entry['use_sim_time'])})
        else:
            parameters.append({'use_sim_time': ParameterValue(
                LaunchConfiguration('use_sim_time'), value_type=bool)})
        actions.append(Node(
            package=entry['package'],
            executable=entry['executable'],
            name=entry['name'],
            namespace=entry.get('namespace') or None,
            parameters=parameters,
            remappings=[(str(k), str(v)) for k, v in (entry.get('remappings') or {}).items()],
            output='screen',
        ))
    return LaunchDescription(actions)
