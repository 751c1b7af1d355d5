"""Launch the foveation node (foveation) with config/foveation.yaml.

    ros2 launch foveation_node foveation.launch.py
        [use_sim_time:=true] [namespace:=/head2] [params_file:=my.yaml]

params_file comes after config/foveation.yaml (its `/**:` or `foveation:` section overrides it); in
a namespace the node gets copies of both keyed `/**/foveation` (rcl would match a bare `foveation:`
to /foveation only).
The description: vizzy_runtime.node_launch (the same for every node).
"""

from vizzy_runtime.node_launch import node_launch_description


def generate_launch_description():
    return node_launch_description('foveation_node', 'foveation')
