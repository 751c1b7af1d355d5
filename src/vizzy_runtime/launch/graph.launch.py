"""Launch the whole Vizzy graph of config/graph.yaml (the file `vizzy launch` reads without ROS).

    ros2 launch vizzy_runtime graph.launch.py [use_sim_time:=true|false] [namespace:=/head2]
        [scene:=tabletop|visual_search|pedestrians] [seed:=N] [params_file:=my.yaml] [rviz:=true]

scene and seed go to the sim; params_file is given to every node after its own files (its `/**:`
or `<node name>:` sections override the defaults); rviz:=true also includes vizzy_sim_bridge's
rviz.launch.py. The arguments are read by vizzy_runtime.launch_args, the same code as `vizzy
launch [graph.yaml] scene:=... params_file:=...` (launch_args.GRAPH_ARGUMENTS, node_parameters).

Nodes use relative topic names, so `namespace:=/head2` moves the whole graph (PushROSNamespace);
/clock, /tf and /tf_static are remapped to relative names for every node (SetRemap: a no-op at the
root namespace), so rclpy's time source and absolute tf users stay inside the namespace too. rcl
applies a params file's bare `sim:` section to /sim only, so each node gets a copy of its files
whose bare keys read `/**/sim` (the same at the root). The same as `vizzy launch --namespace
/head2` (vizzy_runtime/launcher.py: GRAPH_REMAPS, namespace_proof_params).
"""

import os
import tempfile
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import (
    DeclareLaunchArgument,
    GroupAction,
    IncludeLaunchDescription,
    OpaqueFunction,
)
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node, PushROSNamespace, SetRemap

from vizzy_runtime.launch_args import GRAPH_ARGUMENTS, launch_args, node_parameters
from vizzy_runtime.launcher import load_graph


def _nodes(context, graph_file: str) -> list:
    """The graph's Nodes, with the launch arguments as given (resolved here, at launch time)."""
    graph = load_graph(graph_file)
    args = launch_args({key: LaunchConfiguration(key).perform(context)
                        for key in GRAPH_ARGUMENTS})
    use_sim_time = graph.use_sim_time if args.use_sim_time is None else args.use_sim_time
    params_dir = Path(tempfile.mkdtemp(prefix='vizzy_launch_'))
    # the graph's environment defaults; the caller's own environment wins
    env = {k: os.environ.get(k, v) for k, v in graph.env.items()}
    nodes = []
    for spec in graph.nodes:
        share = Path(get_package_share_directory(spec.package))
        parameters = node_parameters(
            spec.package, spec.executable, [share / rel for rel in spec.parameters],
            use_sim_time if spec.use_sim_time is None else spec.use_sim_time,  # the sim: false
            args, params_dir)
        respawn, respawn_delay = graph.respawns(spec)
        retries = {} if spec.respawn_max_retries < 0 else {
            'respawn_max_retries': spec.respawn_max_retries}
        nodes.append(Node(
            package=spec.package,
            additional_env=env,
            executable=spec.executable,
            name=spec.name,
            namespace=spec.namespace or None,
            parameters=[str(p) if isinstance(p, Path) else p for p in parameters],
            remappings=[(str(k), str(v)) for k, v in spec.remappings.items()],
            output='screen',
            respawn=respawn,
            respawn_delay=respawn_delay,
            **retries,
        ))
    return nodes


def _rviz(context) -> list:
    """rviz:=true: vizzy_sim_bridge's rviz.launch.py (vizzy.rviz reads the root namespace's
    topics), outside the graph's namespace; its share directory looked up only then."""
    if not launch_args({'rviz': LaunchConfiguration('rviz').perform(context)}).rviz:
        return []
    return [IncludeLaunchDescription(
        PythonLaunchDescriptionSource(os.path.join(
            get_package_share_directory('vizzy_sim_bridge'), 'launch', 'rviz.launch.py')),
        launch_arguments={'use_sim_time': LaunchConfiguration('use_sim_time')}.items())]


def generate_launch_description() -> LaunchDescription:
    graph_file = os.path.join(
        get_package_share_directory('vizzy_runtime'), 'config', 'graph.yaml')
    default_sim_time = str(load_graph(graph_file).use_sim_time).lower()
    actions = [DeclareLaunchArgument(key, default_value=default_sim_time
                                     if key == 'use_sim_time' else default,
                                     description=description)
               for key, (default, description) in GRAPH_ARGUMENTS.items()]
    # the graph's scope: its namespace, and /clock, /tf, /tf_static relative for every node
    group = [PushROSNamespace(LaunchConfiguration('namespace')), SetRemap('/clock', 'clock'),
             SetRemap('/tf', 'tf'), SetRemap('/tf_static', 'tf_static'),
             OpaqueFunction(function=_nodes, args=[graph_file])]
    actions.append(GroupAction(group))
    actions.append(OpaqueFunction(function=_rviz))
    return LaunchDescription(actions)
