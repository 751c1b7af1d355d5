"""Launch the foveation node (foveation) with config/foveation.yaml."""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(
        get_package_share_directory('foveation_node'), 'config', 'foveation.yaml')
    return LaunchDescription([
        DeclareLaunchArgument(
            'use_sim_time', default_value='false',
            description='Follow /clock (true with the sim, or a bag played with --clock).'),
        Node(
            package='foveation_node',
            executable='foveation',
            name='foveation',
            output='screen',
            parameters=[
                config,
                {'use_sim_time': ParameterValue(
                    LaunchConfiguration('use_sim_time'), value_type=bool)},
            ],
        ),
    ])
