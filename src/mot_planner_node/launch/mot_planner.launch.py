"""Launch the multiple object tracking planner (mot_planner) with config/mot_planner.yaml.

    ros2 launch mot_planner_node mot_planner.launch.py
        [use_sim_time:=true] [namespace:=/head2] [params_file:=my.yaml]

params_file comes after config/mot_planner.yaml (its `/**:` or `mot_planner:` section overrides
it); in a namespace the node gets copies of both keyed `/**/mot_planner` (rcl would match a bare
`mot_planner:` to /mot_planner only).
The description: vizzy_runtime.node_launch (the same for every node).
"""

from vizzy_runtime.node_launch import node_launch_description


def generate_launch_description():
    return node_launch_description('mot_planner_node', 'mot_planner')
