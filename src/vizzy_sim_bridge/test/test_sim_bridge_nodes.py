"""The sim and gaze_controller nodes: declared parameters and their config YAML."""

from pathlib import Path

import pytest
import yaml

from vizzy_runtime.ros import Parameter
from vizzy_runtime.testing import (
    check_node_parameters,
    check_parameter_table,
    node_under_test,
    parameter_refusals,
    startup_problem,
)
from vizzy_sim_bridge import gaze_controller_node, sim_node

CONFIG = Path(__file__).resolve().parents[1] / 'config'
# (node name, module, check, check_all): the gaze controller's rules are all ranges
NODES = [('sim', sim_node, sim_node.check_parameter, sim_node.check_parameters),
         ('gaze_controller', gaze_controller_node, None, gaze_controller_node.check_parameters)]


@pytest.mark.parametrize('node_name, module, check, check_all', NODES)
def test_parameter_table_and_config(node_name, module, check, check_all) -> None:
    check_parameter_table(module.PARAMETERS, check, CONFIG / f'{node_name}.yaml', node_name,
                          check_all)


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
    gaze = (gaze_controller_node.PARAMETERS, None, gaze_controller_node.check_parameters)
    with parameter_refusals(*gaze) as refused:
        assert refused('saccade_min_duration_s', -0.1)
        assert refused('max_fixation_distance_m', 0.0)
        assert refused('max_velocity_rad_s', gaze_controller_node._VMAX * 1.01)
        assert refused('max_velocity_rad_s', gaze_controller_node._VMAX) is None


@pytest.mark.parametrize('make, module, bad', [
    (sim_node.SimNode, sim_node, ('rate_hz', -1.0)),
    (gaze_controller_node.GazeControllerNode, gaze_controller_node,
     ('saccade_min_duration_s', -1.0)),
])
def test_node_declares_its_parameters_and_refuses_bad_values(make, module, bad) -> None:
    with node_under_test(make) as ros_node:
        check_node_parameters(ros_node, module.PARAMETERS, *bad)


def test_sim_refuses_to_follow_its_own_clock() -> None:
    with node_under_test(sim_node.SimNode) as ros_node:
        assert ros_node.get_parameter('use_sim_time').value is False
        result = ros_node.set_parameters([Parameter('use_sim_time', value=True)])[0]
        assert not result.successful


def test_gaze_controller_refuses_min_fixation_beyond_max() -> None:
    with node_under_test(gaze_controller_node.GazeControllerNode) as ros_node:
        result = ros_node.set_parameters([Parameter('min_fixation_distance_m', value=20.0)])[0]
        assert not result.successful and 'max_fixation_distance_m' in result.reason
        assert ros_node.get_parameter('min_fixation_distance_m').value == 0.15


def test_sim_refuses_read_only_parameters() -> None:
    with node_under_test(sim_node.SimNode) as ros_node:
        result = ros_node.set_parameters([Parameter('width', value=320)])[0]
        assert not result.successful
        assert ros_node.get_parameter('width').value == 640
