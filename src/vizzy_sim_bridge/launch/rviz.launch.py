"""RViz with vizzy_runtime/config/vizzy.rviz: both cameras, the foveated and tracking overlays, the
head (RobotModel from /robot_description), /stereo/points and /ses/cells coloured by information,
the detected cylinders and tf, in base_link.

With the simulated graph (`ros2 launch vizzy_runtime graph.launch.py`), which publishes
/robot_description, /tf and /tf_static itself:

    ros2 launch vizzy_sim_bridge rviz.launch.py

Without the simulator, robot_state_publisher.launch.py rviz:=true publishes the description and
the head's tf from /joint_states as well. Needs rviz2.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    rviz_config = os.path.join(get_package_share_directory('vizzy_runtime'), 'config',
                               'vizzy.rviz')
    return LaunchDescription([
        DeclareLaunchArgument('use_sim_time', default_value='true',
                              description='Follow /clock (the simulator publishes it).'),
        Node(
            package='rviz2',
            executable='rviz2',
            name='rviz2',
            arguments=['-d', rviz_config],
            parameters=[{'use_sim_time': LaunchConfiguration('use_sim_time')}],
        ),
    ])
