"""Launch the cylinder detector (cylinder_detector) with config/cylinder_detector.yaml.

    ros2 launch cylinder_detector_node cylinder_detector.launch.py
        [use_sim_time:=true] [namespace:=/head2] [params_file:=my.yaml]

params_file comes after config/cylinder_detector.yaml (its `/**:` or `cylinder_detector:` section
overrides it); in a namespace the node gets copies of both keyed `/**/cylinder_detector` (rcl would
match a bare `cylinder_detector:` to /cylinder_detector only).
The description: vizzy_runtime.node_launch (the same for every node).
"""

from vizzy_runtime.node_launch import node_launch_description


def generate_launch_description():
    return node_launch_description('cylinder_detector_node', 'cylinder_detector')
