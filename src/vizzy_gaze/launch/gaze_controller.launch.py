"""Launch the gaze controller (vizzy_gaze gaze_controller), config/gaze_controller.yaml.

    ros2 launch vizzy_gaze gaze_controller.launch.py
        [use_sim_time:=true] [namespace:=/head2] [params_file:=my.yaml]

params_file comes after config/gaze_controller.yaml (its `/**:` or `gaze_controller:` section
overrides it); in a namespace the node gets copies of both keyed `/**/gaze_controller` (rcl would
match a bare `gaze_controller:` to /gaze_controller only).
The description: vizzy_runtime.node_launch (the same for every node).
"""

from vizzy_runtime.node_launch import node_launch_description


def generate_launch_description():
    return node_launch_description('vizzy_gaze', 'gaze_controller')
