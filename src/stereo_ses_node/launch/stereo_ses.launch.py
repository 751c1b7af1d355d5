"""Launch the stereo / Sensory Ego-Sphere node (stereo_ses) with config/stereo_ses.yaml.

    ros2 launch stereo_ses_node stereo_ses.launch.py
        [use_sim_time:=true] [namespace:=/head2] [params_file:=my.yaml]

params_file comes after config/stereo_ses.yaml (its `/**:` or `stereo_ses:` section overrides it);
in a namespace the node gets copies of both keyed `/**/stereo_ses` (rcl would match a bare
`stereo_ses:` to /stereo_ses only). Read by vizzy_runtime.launch_args, as graph.launch.py's
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
    parameters = node_parameters('stereo_ses_node', 'stereo_ses', [Path(config)],
                                 bool(args.use_sim_time), args, proof_dir)
    return [Node(
        package='stereo_ses_node',
        executable='stereo_ses',
        name='stereo_ses',
        namespace=args.namespace or None,
        output='screen',
        parameters=[str(p) if isinstance(p, Path) else p for p in parameters],
    )]


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(
        get_package_share_directory('stereo_ses_node'), 'config', 'stereo_ses.yaml')
    return LaunchDescription([
        *(DeclareLaunchArgument(key, default_value=default, description=description)
          for key, (default, description) in NODE_ARGUMENTS.items()),
        OpaqueFunction(function=_node, args=[config]),
    ])
