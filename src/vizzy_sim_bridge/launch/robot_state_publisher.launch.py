"""robot_state_publisher with the Vizzy head's URDF, and optionally RViz with vizzy.rviz.

For a head without the simulator (the real robot, a bag without /tf): robot_state_publisher
publishes /robot_description and, from /joint_states (our joint names and signs:
core/kinematics.py), /tf and /tf_static for every frame of the head. The URDF is generated here,
at launch time, by vizzy_sim_bridge.core.urdf.head_urdf() from the kinematics and the MuJoCo
model the simulator uses, so no copy of it is installed. The simulator publishes
/robot_description, /tf and /tf_static itself: with it, start only RViz (rviz.launch.py).

    ros2 launch vizzy_sim_bridge robot_state_publisher.launch.py [rviz:=true] [use_sim_time:=true]

Needs robot_state_publisher (in ros-jazzy-ros-base) and, for rviz:=true, rviz2.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

from vizzy_sim_bridge.core.urdf import head_urdf


def generate_launch_description() -> LaunchDescription:
    rviz_config = os.path.join(get_package_share_directory('vizzy_runtime'), 'config',
                               'vizzy.rviz')
    return LaunchDescription([
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='Follow /clock (true when playing a bag or with a sim).'),
        DeclareLaunchArgument('rviz', default_value='false',
                              description='Also start RViz with vizzy_runtime/config/vizzy.rviz.'),
        Node(
            package='robot_state_publisher',
            executable='robot_state_publisher',
            name='robot_state_publisher',
            output='screen',
            parameters=[{
                # value_type=str: the XML goes through as it is, not parsed as YAML
                'robot_description': ParameterValue(head_urdf(), value_type=str),
                'use_sim_time': LaunchConfiguration('use_sim_time'),
            }],
        ),
        Node(
            package='rviz2',
            executable='rviz2',
            name='rviz2',
            arguments=['-d', rviz_config],
            parameters=[{'use_sim_time': LaunchConfiguration('use_sim_time')}],
            condition=IfCondition(LaunchConfiguration('rviz')),
        ),
    ])
