"""The launch description of one node with its package's config (each node's
`<name>.launch.py` is this call): the node arguments of launch_args (`use_sim_time`,
`namespace`, `params_file`), resolved at launch time. Needs ROS 2's launch / launch_ros, imported
here only when a launch file asks."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

from .launch_args import NODE_ARGUMENTS, launch_args, node_parameters


def node_launch_description(package: str, executable: str) -> Any:
    """`ros2 launch <package> <executable>.launch.py`: the node `executable` of `package`, named
    as its executable, with config/<executable>.yaml, then params_file."""
    from ament_index_python.packages import get_package_share_directory
    from launch import LaunchDescription  # type: ignore[attr-defined, unused-ignore]
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    def node(context: Any, config: str) -> list[Any]:
        args = launch_args({key: LaunchConfiguration(key).perform(context)
                            for key in NODE_ARGUMENTS})
        proof_dir = Path(tempfile.mkdtemp(prefix='vizzy_launch_')) if args.namespace else None
        parameters = node_parameters(package, executable, [Path(config)],
                                     bool(args.use_sim_time), args, proof_dir)
        return [Node(package=package, executable=executable, name=executable,
                     namespace=args.namespace or None, output='screen',
                     parameters=[str(p) if isinstance(p, Path) else p for p in parameters])]

    config = os.path.join(get_package_share_directory(package), 'config', f'{executable}.yaml')
    return LaunchDescription([
        *(DeclareLaunchArgument(key, default_value=default, description=description)
          for key, (default, description) in NODE_ARGUMENTS.items()),
        OpaqueFunction(function=node, args=[config]),
    ])
