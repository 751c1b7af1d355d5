"""Launch the multiple object tracking planner (mot_planner) with config/mot_planner.yaml.

    ros2 launch mot_planner_node mot_planner.launch.py
        [use_sim_time:=true] [namespace:=/head2] [params_file:=my.yaml]

params_file comes after config/mot_planner.yaml (its `/**:` or `mot_planner:` section overrides
it); in a namespace the node gets copies of both keyed `/**/mot_planner` (rcl would match a bare
`mot_planner:` to /mot_planner only). Read by vizzy_runtime.launch_args, as graph.launch.py's
arguments are.
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
    parameters = node_parameters('mot_planner_node', 'mot_planner', [Path(config)],
                                 bool(args.use_sim_time), args, proof_dir)
    return [Node(
        package='mot_planner_node',
        executable='mot_planner',
        name='mot_planner',
        namespace=args.namespace or None,
        output='screen',
        parameters=[str(p) if isinstance(p, Path) else p for p in parameters],
    )]


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(
        get_package_share_directory('mot_planner_node'), 'config', 'mot_planner.yaml')
    return LaunchDescription([
        *(DeclareLaunchArgument(key, default_value=default, description=description)
          for key, (default, description) in NODE_ARGUMENTS.items()),
        OpaqueFunction(function=_node, args=[config]),
    ])
