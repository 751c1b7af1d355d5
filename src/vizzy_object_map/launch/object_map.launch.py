"""Launch the object map (object_map) with config/object_map.yaml."""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(
        get_package_share_directory('vizzy_object_map'), 'config', 'object_map.yaml')
    return LaunchDescription([
        DeclareLaunchArgument(
            'use_sim_time', default_value='false',
            description='Follow /clock (true with the sim, or a bag played with --clock).'),
        Node(
            package='vizzy_object_map',
            executable='object_map',
            name='object_map',
            output='screen',
            parameters=[
                config,
                {'use_sim_time': ParameterValue(
                    LaunchConfiguration('use_sim_time'), value_type=bool)},
            ],
            # the recognitions come from the left camera (as in the graph)
            remappings=[('camera_info', 'vizzy/left/camera_info')],
        ),
    ])
