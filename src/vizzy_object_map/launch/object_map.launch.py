"""Launch the object map (object_map) with config/object_map.yaml.

    ros2 launch vizzy_object_map object_map.launch.py
        [use_sim_time:=true] [namespace:=/head2] [params_file:=my.yaml]

params_file comes after config/object_map.yaml (its `/**:` or `object_map:` section overrides it);
in a namespace the node gets copies of both keyed `/**/object_map` (rcl would match a bare
`object_map:` to /object_map only).
The description: vizzy_runtime.node_launch (the same for every node).
"""

from vizzy_runtime.node_launch import node_launch_description


def generate_launch_description():
    return node_launch_description('vizzy_object_map', 'object_map')
