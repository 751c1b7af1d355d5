"""The sim node: declared parameters and its config YAML."""

from pathlib import Path

import yaml

from vizzy_runtime.ros import Parameter
from vizzy_runtime.testing import (
    check_node_parameters,
    check_parameter_table,
    node_under_test,
    parameter_refusals,
    startup_problem,
)
from vizzy_sim_bridge import sim_node

CONFIG = Path(__file__).resolve().parents[1] / 'config'


def test_parameter_table_and_config() -> None:
    check_parameter_table(sim_node.PARAMETERS, sim_node.check_parameter, CONFIG / 'sim.yaml',
                          'sim', sim_node.check_parameters)


def test_sim_config_runs_the_sim_on_wall_time() -> None:
    doc = yaml.safe_load((CONFIG / 'sim.yaml').read_text())
    assert doc['sim']['ros__parameters']['use_sim_time'] is False


def test_out_of_range_values_are_refused() -> None:
    sim = (sim_node.PARAMETERS, sim_node.check_parameter, sim_node.check_parameters)
    with parameter_refusals(*sim) as refused:
        assert refused('rate_hz', 0.0) and refused('rgbd_max_range_m', 0.4)   # below min range
        assert refused('rgbd_min_range_m', 10.0)                               # [0, 10)
    # read-only: refused at start-up only
    assert 'initial_joint_positions' in startup_problem(
        *sim, initial_joint_positions=[0.0] * 4)
    assert 'must be finite' in startup_problem(
        *sim, initial_joint_positions=[float('nan')] + [0.0] * 4)
    assert "parameter 'scene' = 'kitchen'" in startup_problem(*sim, scene='kitchen')
    assert "'render_backend' = 'vulkan'" in startup_problem(*sim, render_backend='vulkan')
    assert "parameter 'width' = 8: out of range [16, 4096]" in startup_problem(*sim, width=8)
    assert sim_node.check_parameters({'rgbd_min_range_m': 2.0, 'rgbd_max_range_m': 1.0})


def test_node_declares_its_parameters_and_refuses_bad_values() -> None:
    with node_under_test(sim_node.SimNode) as ros_node:
        check_node_parameters(ros_node, sim_node.PARAMETERS, 'rate_hz', -1.0)


def test_sim_refuses_to_follow_its_own_clock() -> None:
    with node_under_test(sim_node.SimNode) as ros_node:
        assert ros_node.get_parameter('use_sim_time').value is False
        result = ros_node.set_parameters([Parameter('use_sim_time', value=True)])[0]
        assert not result.successful


def test_sim_refuses_read_only_parameters() -> None:
    with node_under_test(sim_node.SimNode) as ros_node:
        result = ros_node.set_parameters([Parameter('width', value=320)])[0]
        assert not result.successful
        assert ros_node.get_parameter('width').value == 640
