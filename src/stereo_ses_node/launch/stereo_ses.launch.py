"""Launch the stereo / Sensory Ego-Sphere node (stereo_ses) with config/stereo_ses.yaml.

    ros2 launch stereo_ses_node stereo_ses.launch.py
        [use_sim_time:=true] [namespace:=/head2] [params_file:=my.yaml]

params_file comes after config/stereo_ses.yaml (its `/**:` or `stereo_ses:` section overrides it);
in a namespace the node gets copies of both keyed `/**/stereo_ses` (rcl would match a bare
`stereo_ses:` to /stereo_ses only).
The description: vizzy_runtime.node_launch (the same for every node).
"""

from vizzy_runtime.node_launch import node_launch_description


def generate_launch_description():
    return node_launch_description('stereo_ses_node', 'stereo_ses')
