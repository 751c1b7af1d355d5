"""The mot_planner node: its parameters, config/mot_planner.yaml and its input checks."""

from pathlib import Path

import numpy as np

from mot_planner_node import node
from vizzy_runtime.convert import numpy_to_image
from vizzy_runtime.testing import (
    check_node_parameters,
    check_parameter_table,
    node_under_test,
    parameter_refusals,
)

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'mot_planner.yaml'


def test_parameter_table_and_config() -> None:
    check_parameter_table(node.PARAMETERS, node.check_parameter, CONFIG, 'mot_planner')


def test_parameter_checks() -> None:
    with parameter_refusals(node.PARAMETERS, node.check_parameter) as refused:
        assert refused('win_stride', 12) and refused('win_stride', 72) and refused('win_stride', 0)
        assert refused('win_stride', 16) is None and refused('win_stride', 64) is None
        assert refused('scale', 1.0) and refused('scale', 1.01) is None
        assert refused('full_frame_scale', 1.0) and refused('full_frame_scale', 0.5)
        assert refused('full_frame_scale', 0.0) is None and refused('full_frame_scale', 1.1) is None
        assert refused('s_max', 0.0) and refused('s_max', 1.0) is None
        assert refused('person_height_m', [2.0, 1.0]) and refused('person_height_m', [0.0, 2.0])
        assert refused('person_height_m', [1.0, 2.0, 3.0]) and refused('world_frame', '')
        assert refused('k_max', 3.0) and refused('publish_gaze', 1)      # the declared types
        # issue 28 item 4: a positive cap so low it switches tracking off, without a warning
        assert refused('max_rate_hz', 1e-9) and refused('max_rate_hz', 0.009)
        assert refused('max_rate_hz', 0.0) is None and refused('max_rate_hz', 0.01) is None


def test_images_are_checked() -> None:
    msg = numpy_to_image(np.zeros((48, 64, 3), np.uint8), 'rgb8')
    assert node.image_problem(msg) is None
    msg.encoding = 'bgr8'
    assert node.image_problem(msg) is None
    mono = numpy_to_image(np.zeros((48, 64), np.uint8), 'mono8')
    assert node.image_problem(mono) == ('unsupported encoding', "'mono8' is not one of rgb8, bgr8")
    msg.height = 100  # more rows than the data holds
    reason, detail = node.image_problem(msg)
    assert reason == 'size inconsistent with data' and '9216 data bytes' in detail
    empty = numpy_to_image(np.zeros((48, 64, 3), np.uint8), 'rgb8')
    empty.height = 0
    assert node.image_problem(empty) == ('empty image', '64x0')
    narrow = numpy_to_image(np.zeros((48, 64, 3), np.uint8), 'rgb8')
    narrow.step = 100
    assert node.image_problem(narrow)[0] == 'step shorter than a row'


def test_node_declares_its_parameters_and_refuses_bad_values() -> None:
    with node_under_test(node.MotPlannerNode) as ros_node:
        check_node_parameters(ros_node, node.PARAMETERS, 's_max', 2.0)


def test_floor_default_is_the_kinematics_constant() -> None:
    """floor_z_m's default is the floor in base_link (the node copies it, not to depend on
    the simulator's package at run time)."""
    from vizzy_vision.kinematics import WAIST_HEIGHT
    assert node.FLOOR_Z_M == -WAIST_HEIGHT
    assert {p.name: p.default for p in node.PARAMETERS}['floor_z_m'] == -WAIST_HEIGHT
