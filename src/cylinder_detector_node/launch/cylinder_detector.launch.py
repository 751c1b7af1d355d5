"""Launch the cylinder detector (cylinder_detector) with config/cylinder_detector.yaml.

    ros2 launch cylinder_detector_node cylinder_detector.launch.py
        [use_sim_time:=true] [namespace:=/head2] [params_file:=my.yaml]

params_file comes after config/cylinder_detector.yaml (its `/**:` or `cylinder_detector:` section
overrides it); in a namespace the node gets copies of both keyed `/**/cylinder_detector` (rcl would
match a bare `cylinder_detector:` to /cylinder_detector only). Read by vizzy_runtime.launch_args,
as graph.launch.py's arguments are.
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
    parameters = node_parameters('cylinder_detector_node', 'cylinder_detector', [Path(config)],
                                 bool(args.use_sim_time), args, proof_dir)
    return [Node(
        package='cylinder_detector_node',
        executable='cylinder_detector',
        name='cylinder_detector',
        namespace=args.namespace or None,
        output='screen',
        parameters=[str(p) if isinstance(p, Path) else p for p in parameters],
    )]


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(
        get_package_share_directory('cylinder_detector_node'), 'config', 'cylinder_detector.yaml')
    return LaunchDescription([
        *(DeclareLaunchArgument(key, default_value=default, description=description)
          for key, (default, description) in NODE_ARGUMENTS.items()),
        OpaqueFunction(function=_node, args=[config]),
    ])
