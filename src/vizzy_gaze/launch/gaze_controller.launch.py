"""Launch the gaze controller (vizzy_gaze gaze_controller), config/gaze_controller.yaml.

    ros2 launch vizzy_gaze gaze_controller.launch.py
        [use_sim_time:=true] [namespace:=/head2] [params_file:=my.yaml]

params_file comes after config/gaze_controller.yaml (its `/**:` or `gaze_controller:` section
overrides it); in a namespace the node gets copies of both keyed `/**/gaze_controller` (rcl would
match a bare `gaze_controller:` to /gaze_controller only). Read by vizzy_runtime.launch_args, as
graph.launch.py's arguments are.
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
    parameters = node_parameters('vizzy_gaze', 'gaze_controller', [Path(config)],
                                 bool(args.use_sim_time), args, proof_dir)
    return [Node(
        package='vizzy_gaze',
        executable='gaze_controller',
        name='gaze_controller',
        namespace=args.namespace or None,
        output='screen',
        parameters=[str(p) if isinstance(p, Path) else p for p in parameters],
    )]


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(
        get_package_share_directory('vizzy_gaze'), 'config', 'gaze_controller.yaml')
    return LaunchDescription([
        *(DeclareLaunchArgument(key, default_value=default, description=description)
          for key, (default, description) in NODE_ARGUMENTS.items()),
        OpaqueFunction(function=_node, args=[config]),
    ])
