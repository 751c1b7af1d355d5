"""The bundled `vizzy topic` / `vizzy node` / `vizzy param` verbs see nodes on the real rclpy
(rmw_fastrtps_cpp): the gaze controller and a tiny talker, each started by .venv-ros's python.
Each verb is run as a user runs it, a fresh process with its default discovery wait.

`vizzy param` is the bundled runtime's parameter client (AsyncParameterClient) calling the real
node's rcl_interfaces services. The reverse, a Fast DDS client calling a bundled node's services,
cannot work (rmw_fastrtps_cpp's client keeps only replies carrying its identity as RTPS inline QoS,
which Cyclone DDS cannot send): see vizzy_runtime.rclpy_compat.parameter_client."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from vizzy_runtime.testing import real_rclpy_python, scaled

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mixed_support import (  # noqa: E402
    Flow,
    RealProcess,
    graph_subset,
    real_launch,
    stop_all,
    wait_state,
)

pytestmark = pytest.mark.slow  # real-rclpy nodes in processes of their own

VIZZY = [sys.executable, '-m', 'vizzy_runtime.cli']   # the bundled runtime's CLI (.venv)

TALKER = r'''
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, DurabilityPolicy
from std_msgs.msg import String
rclpy.init()
node = Node('mixed_talker')
pub = node.create_publisher(String, '/mixed/chatter', 10)
latched = node.create_publisher(String, '/mixed/latched', QoSProfile(
    depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
latched.publish(String(data='published once'))
count = [0]
def tick():
    count[0] += 1
    pub.publish(String(data=f'hello {count[0]}'))
node.create_timer(0.1, tick)
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
node.destroy_node()
rclpy.try_shutdown()
'''


@pytest.fixture(scope='module')
def real_nodes(tmp_path_factory):
    """gaze_controller (by `vizzy launch` on the real rclpy) and mixed_talker, both publishing."""
    real_rclpy_python()  # skips without .venv-ros
    tmp = tmp_path_factory.mktemp('mixed_cli')
    # on wall time: no sim here to publish /clock
    gaze = real_launch(graph_subset(tmp / 'real.yaml', ['gaze_controller'], use_sim_time=False),
                       tmp / 'gaze.log')
    talker = RealProcess(['-c', TALKER], tmp / 'talker.log')
    try:
        flow = Flow(['/gaze/state', '/mixed/chatter'])
        up = wait_state(lambda: flow.all_heard() or not (gaze.alive() and talker.alive()),
                        scaled(120))
        assert up and gaze.alive() and talker.alive(), (
            f'real nodes not up: {flow.counts}\n{gaze.log()}\n{talker.log()}')
        flow.close()
        yield gaze, talker
    finally:  # (clean exits are test_mixed_graph's and test_mixed_bag's business)
        stop_all(gaze.stop, talker.stop)


def vizzy(*args: str, timeout: float = scaled(60), code: int = 0) -> str:
    proc = subprocess.run([*VIZZY, *args], capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == code, (f'vizzy {" ".join(args)}: exit {proc.returncode}\n'
                                     f'{proc.stderr[-2000:]}')
    return proc.stdout + proc.stderr if code else proc.stdout


def test_node_list_sees_real_rclpy_nodes(real_nodes):
    names = vizzy('node', 'list').split()
    assert {'/gaze_controller', '/mixed_talker'} <= set(names), names


def test_topic_list_sees_real_rclpy_topics_with_types(real_nodes):
    lines = set(vizzy('topic', 'list', '-t').splitlines())
    assert {'/mixed/chatter [std_msgs/msg/String]', '/mixed/latched [std_msgs/msg/String]',
            '/gaze/state [active_vision_msgs/msg/GazeState]',
            '/gaze/command [active_vision_msgs/msg/GazeCommand]',      # a subscription only
            '/vizzy/joint_commands [sensor_msgs/msg/JointState]'} <= lines, lines


def test_topic_echo_decodes_real_rclpy_messages(real_nodes):
    out = vizzy('topic', 'echo', '/mixed/chatter', '-n', '1')
    assert re.fullmatch(r"data: hello \d+\n---\n", out), out     # ros2's YAML: no quotes
    # latched: published once at start-up, long before; echo adapts to the writer's durability
    assert vizzy('topic', 'echo', '/mixed/latched', '--once') == 'data: published once\n---\n'
    out = vizzy('topic', 'echo', '/gaze/state', '-n', '1')
    assert out.endswith('---\n') and out.count('---') == 1, out
    assert 'frame_id: base_link' in out and 'status_message:' in out, out


def test_topic_hz_measures_a_real_rclpy_publisher(real_nodes):
    out = vizzy('topic', 'hz', '/mixed/chatter', '--duration', '4')
    rates = [float(r) for r in re.findall(r'average rate: ([0-9.]+)', out)]
    assert rates, out
    # a 10 Hz timer on a loaded machine: loose bounds, the point is that it is measured
    assert 1.0 < rates[-1] < 100.0, out
    assert re.search(r'min: [0-9.]+s max: [0-9.]+s std dev: [0-9.]+s window: \d+', out), out


def test_param_verbs_get_set_and_are_refused_on_a_real_rclpy_node(real_nodes):
    names = vizzy('param', 'list', '/gaze_controller').split()
    assert {'neck_share', 'pursuit_gain', 'use_sim_time',
            'start_type_description_service'} <= set(names)
    assert vizzy('param', 'get', '/gaze_controller', 'neck_share') == 'Double value is: 0.0\n'
    assert vizzy('param', 'set', '/gaze_controller', 'neck_share',
                 '0.25') == 'Set parameter successful\n'
    assert vizzy('param', 'get', '/gaze_controller', 'neck_share') == 'Double value is: 0.25\n'
    # refused by the real rclpy itself: the descriptor's range, then the declared type
    out = vizzy('param', 'set', '/gaze_controller', 'neck_share', '3.0', code=1)
    assert 'Setting parameter failed' in out and 'out of range' in out, out
    out = vizzy('param', 'set', '/gaze_controller', 'neck_share', 'abc', code=1)
    assert 'Setting parameter failed' in out and 'Wrong parameter type' in out, out
    assert vizzy('param', 'get', '/gaze_controller', 'neck_share') == 'Double value is: 0.25\n'
    out = vizzy('param', 'describe', '/gaze_controller', 'neck_share')
    assert 'Type: double' in out and 'Range: [0.0, 1.0]' in out and 'Neck/eye split' in out, out
    vizzy('param', 'set', '/gaze_controller', 'neck_share', '0.0')


def test_param_client_queues_concurrent_calls_to_a_fast_dds_service(real_nodes, context):
    """Fast DDS replies carry no identity Cyclone can read: one request in flight, in order."""
    from vizzy_runtime.ros import AsyncParameterClient, Node, Parameter, SingleThreadedExecutor
    node = Node('mixed_param_client', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    client = AsyncParameterClient(node, '/gaze_controller')
    assert client.wait_for_services(scaled(30))
    asked = [['pursuit_gain'], ['neck_share', 'pursuit_gain'], ['nope'],
             ['pursuit_gain', 'neck_share']] * 3
    futures = [client.get_parameters(names) for names in asked]  # all in flight at once
    for future in futures:
        executor.spin_until_future_complete(future, 20)
        assert future.done()
    # each reply is its own request's: rclpy answers [] when a name is not declared
    assert [[v.double_value for v in f.result().values] for f in futures] == \
        [[8.0], [0.0, 8.0], [], [8.0, 0.0]] * 3
    future = client.set_parameters([Parameter('pursuit_gain', value=4.0)])
    executor.spin_until_future_complete(future, 20)
    assert future.result().results[0].successful
    future = client.get_parameters(['pursuit_gain'])
    executor.spin_until_future_complete(future, 20)
    assert future.result().values[0].double_value == 4.0
    client.destroy()
    node.destroy_node()
