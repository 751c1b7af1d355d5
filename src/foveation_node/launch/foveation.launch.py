"""Launch the foveation node (foveation) with config/foveation.yaml.

    ros2 launch foveation_node foveation.launch.py
        [use_sim_time:=true] [namespace:=/head2] [params_file:=my.yaml]

params_file comes after config/foveation.yaml (its `/**:` or `foveation:` section overrides it); in
a namespace the node gets copies of both keyed `/**/foveation` (rcl would match a bare `foveation:`
to /foveation only). Read by vizzy_runtime.launch_args, as graph.launch.py's arguments are.
"""

import os
import tempfile
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from vizzy_runtime.launch_args import NODE_ARGUMENTS, launch_args, node_parameters


def _node(context, config: str) -> list:
    """The node, with the launch arguments as given (resolved here, at launch time)."""
    args = launch_args({key: LaunchConfiguration(key).perform(context) for key in NODE_ARGUMENTS})
    proof_dir = Path(tempfile.mkdtemp(prefix='vizzy_launch_')) if args.namespace else None
    parameters = node_parameters('foveation_node', 'foveation', [Path(config)],
                                 bool(args.use_sim_time), args, proof_dir)
    return [Node(
        package='foveation_node',
        executable='foveation',
        name='foveation',
        namespace=args.namespace or None,
        output='screen',
        parameters=[str(p) if isinstance(p, Path) else p for p in parameters],
    )]


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(
        get_package_share_directory('foveation_node'), 'config', 'foveation.yaml')
    return LaunchDescription([
        *(DeclareLaunchArgument(key, default_value=default, description=description)
          for key, (default, description) in NODE_ARGUMENTS.items()),
        OpaqueFunction(function=_node, args=[config]),
    ])
