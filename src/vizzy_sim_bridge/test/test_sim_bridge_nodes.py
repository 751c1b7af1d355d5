"""The sim and gaze_controller nodes: declared parameters and their config YAML."""

from pathlib import Path

import pytest
import yaml

from vizzy_runtime.ros import Parameter, rclpy
from vizzy_sim_bridge import gaze_controller_node, sim_node

CONFIG = Path(__file__).resolve().parents[1] / 'config'
NODES = [('sim', sim_node), ('gaze_controller', gaze_controller_node)]


@pytest.mark.parametrize('node_name, module', NODES)
def test_parameters_are_described_unique_and_valid(node_name, module) -> None:
    names = [name for name, _, _ in module.PARAMETERS]
    assert len(names) == len(set(names))
    for name, default, description in module.PARAMETERS:
        assert description.strip(), name
        assert module.check_parameter(name, default) is None, name


@pytest.mark.parametrize('node_name, module', NODES)
def test_config_names_declared_parameters_with_valid_values(node_name, module) -> None:
    doc = yaml.safe_load((CONFIG / f'{node_name}.yaml').read_text())
    assert list(doc) == [node_name]
    params = doc[node_name]['ros__parameters']
    declared = {name: default for name, default, _ in module.PARAMETERS}
    assert set(params) - {'use_sim_time'} <= set(declared)
    for name, value in params.items():
        if name == 'use_sim_time':
            continue
        # ROS 2 parameters are typed: 15 (integer) does not override 15.0 (double).
        assert type(value) is type(declared[name]), name
        assert module.check_parameter(name, value) is None, name


def test_sim_config_runs_the_sim_on_wall_time() -> None:
    doc = yaml.safe_load((CONFIG / 'sim.yaml').read_text())
    assert doc['sim']['ros__parameters']['use_sim_time'] is False


def test_out_of_range_values_are_refused() -> None:
    assert sim_node.check_parameter('rate_hz', 0.0)
    assert sim_node.check_parameter('joint_positions', [0.0] * 4)
    assert sim_node.check_parameter('joint_positions', [5.0, 0.0, 0.0, 0.0, 0.0])
    assert gaze_controller_node.check_parameter('saccade_duration_s', -0.1)
    assert gaze_controller_node.check_parameter('max_fixation_distance_m', 0.0)


@pytest.fixture
def ros_context():
    rclpy.init()
    yield
    rclpy.try_shutdown()


@pytest.mark.parametrize('make, bad', [
    (sim_node.SimNode, ('rate_hz', -1.0)),
    (gaze_controller_node.GazeControllerNode, ('saccade_duration_s', -1.0)),
])
def test_node_declares_its_parameters_and_refuses_bad_values(ros_context, make, bad) -> None:
    ros_node = make()
    module = sim_node if make is sim_node.SimNode else gaze_controller_node
    try:
        for name, default, _ in module.PARAMETERS:
            value = ros_node.get_parameter(name).value
            assert (list(value) if isinstance(default, list) else value) == default, name
        result = ros_node.set_parameters([Parameter(bad[0], value=bad[1])])[0]
        assert not result.successful and bad[0] in result.reason
    finally:
        ros_node.destroy_node()


def test_sim_refuses_to_follow_its_own_clock(ros_context) -> None:
    ros_node = sim_node.SimNode()
    try:
        assert ros_node.get_parameter('use_sim_time').value is False
        result = ros_node.set_parameters([Parameter('use_sim_time', value=True)])[0]
        assert not result.successful
    finally:
        ros_node.destroy_node()
