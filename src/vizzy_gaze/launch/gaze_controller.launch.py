"""Launch the gaze controller (vizzy_gaze gaze_controller), config/gaze_controller.yaml."""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(
        get_package_share_directory('vizzy_gaze'), 'config', 'gaze_controller.yaml')
    return LaunchDescription([
        DeclareLaunchArgument(
            'use_sim_time', default_value='false',
            description='Follow /clock (true with the sim, or a bag played with --clock).'),
        Node(
            package='vizzy_gaze',
            executable='gaze_controller',
            name='gaze_controller',
            output='screen',
            parameters=[
                config,
                {'use_sim_time': ParameterValue(
                    LaunchConfiguration('use_sim_time'), value_type=bool)},
            ],
        ),
    ])
