"""The gaze_controller node: declared parameters and their config YAML."""

from pathlib import Path

from vizzy_gaze import gaze_controller_node
from vizzy_runtime.ros import Parameter
from vizzy_runtime.testing import (
    check_node_parameters,
    check_parameter_table,
    node_under_test,
    parameter_refusals,
)

CONFIG = Path(__file__).resolve().parents[1] / 'config'


def test_parameter_table_and_config() -> None:
    # the gaze controller's rules are all ranges, then one rule across parameters
    check_parameter_table(gaze_controller_node.PARAMETERS, None, CONFIG / 'gaze_controller.yaml',
                          'gaze_controller', gaze_controller_node.check_parameters)


def test_out_of_range_values_are_refused() -> None:
    gaze = (gaze_controller_node.PARAMETERS, None, gaze_controller_node.check_parameters)
    with parameter_refusals(*gaze) as refused:
        assert refused('saccade_min_duration_s', -0.1)
        assert refused('max_fixation_distance_m', 0.0)
        assert refused('max_velocity_rad_s', gaze_controller_node._VMAX * 1.01)
        assert refused('max_velocity_rad_s', gaze_controller_node._VMAX) is None


def test_node_declares_its_parameters_and_refuses_bad_values() -> None:
    with node_under_test(gaze_controller_node.GazeControllerNode) as ros_node:
        check_node_parameters(ros_node, gaze_controller_node.PARAMETERS,
                              'saccade_min_duration_s', -1.0)


def test_gaze_controller_refuses_min_fixation_beyond_max() -> None:
    with node_under_test(gaze_controller_node.GazeControllerNode) as ros_node:
        result = ros_node.set_parameters([Parameter('min_fixation_distance_m', value=20.0)])[0]
        assert not result.successful and 'max_fixation_distance_m' in result.reason
        assert ros_node.get_parameter('min_fixation_distance_m').value == 0.15
