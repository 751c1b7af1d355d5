"""The mot_planner node: its parameters, config/mot_planner.yaml and its input checks."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from mot_planner_node import node
from vizzy_runtime.convert import numpy_to_image
from vizzy_runtime.ros import Parameter, rclpy

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'mot_planner.yaml'
DECLARED = {name: default for name, default, _ in node.PARAMETERS}


def _config() -> dict:
    doc = yaml.safe_load(CONFIG.read_text())
    assert list(doc) == ['mot_planner'], 'the config is for node mot_planner only'
    return doc['mot_planner']['ros__parameters']


def test_parameters_are_described_and_unique() -> None:
    names = [name for name, _, _ in node.PARAMETERS]
    assert len(names) == len(set(names))
    assert all(description.strip() for _, _, description in node.PARAMETERS)


def test_defaults_are_valid() -> None:
    for name, default in DECLARED.items():
        assert node.check_parameter(name, default) is None, name


def test_config_names_declared_parameters_with_valid_values() -> None:
    params = _config()
    assert set(params) - {'use_sim_time'} <= set(DECLARED)
    for name, value in params.items():
        if name == 'use_sim_time':
            continue
        # ROS 2 parameters are typed: 15 (integer) does not override 15.0 (double).
        assert type(value) is type(DECLARED[name]), name
        assert node.check_parameter(name, value) is None, name


def test_out_of_range_values_are_refused() -> None:
    refused = [name for name, default in DECLARED.items()
               if isinstance(default, (int, float)) and not isinstance(default, bool)
               and node.check_parameter(name, -1e9) is not None]
    assert refused, 'at least one numeric parameter has a range'


def test_images_are_checked() -> None:
    msg = numpy_to_image(np.zeros((48, 64, 3), np.uint8), 'rgb8')
    assert node.image_problem(msg) is None
    msg.encoding = 'bgr8'
    assert node.image_problem(msg) is None
    mono = numpy_to_image(np.zeros((48, 64), np.uint8), 'mono8')
    assert 'encoding' in node.image_problem(mono)
    msg.height = 100  # more rows than the data holds
    assert 'bytes' in node.image_problem(msg)


@pytest.fixture
def ros_context():
    rclpy.init()
    yield
    rclpy.try_shutdown()


def test_node_declares_its_parameters_and_refuses_bad_values(ros_context) -> None:
    ros_node = node.MotPlannerNode()
    try:
        for name, default, _ in node.PARAMETERS:
            assert ros_node.get_parameter(name).value == default, name
        result = ros_node.set_parameters([Parameter('s_max', value=2.0)])[0]
        assert not result.successful and 's_max' in result.reason
    finally:
        ros_node.destroy_node()
