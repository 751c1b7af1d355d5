"""Launch the simulated Vizzy head (vizzy_sim_bridge sim: MuJoCo, see docs/vizzy_sim_bridge.md)
with config/sim.yaml.

The sim publishes /clock itself, so it always runs on wall time (use_sim_time false, set in
config/sim.yaml); the nodes that follow it run with use_sim_time true.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(get_package_share_directory('vizzy_sim_bridge'), 'config', 'sim.yaml')
    return LaunchDescription([
        Node(
            package='vizzy_sim_bridge',
            executable='sim',
            name='sim',
            output='screen',
            parameters=[config],
        ),
    ])
