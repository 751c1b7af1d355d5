"""The cylinder_detector node: its parameters, config/cylinder_detector.yaml, its input checks."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from cylinder_detector_node import node
from vizzy_runtime.convert import array_to_pointcloud2
from vizzy_runtime.ros import Parameter, rclpy

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'cylinder_detector.yaml'
DECLARED = {name: default for name, default, _ in node.PARAMETERS}


def _config() -> dict:
    doc = yaml.safe_load(CONFIG.read_text())
    assert list(doc) == ['cylinder_detector'], 'the config is for node cylinder_detector only'
    return doc['cylinder_detector']['ros__parameters']


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


def test_clouds_are_checked() -> None:
    xyz = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4')])
    good = np.zeros(100, dtype=xyz)
    assert node.cloud_problem(array_to_pointcloud2(good), 50) is None
    nan = np.full(100, np.nan, dtype=xyz)
    assert '0 finite points' in node.cloud_problem(array_to_pointcloud2(nan), 50)
    flat = np.zeros(100, dtype=[('x', '<f4'), ('y', '<f4')])
    assert 'no field(s) z' in node.cloud_problem(array_to_pointcloud2(flat), 50)
    short = array_to_pointcloud2(good)
    short.width = 1000  # more points than the data holds
    assert 'bytes' in node.cloud_problem(short, 50)


@pytest.fixture
def ros_context():
    rclpy.init()
    yield
    rclpy.try_shutdown()


def test_node_declares_its_parameters_and_refuses_bad_values(ros_context) -> None:
    ros_node = node.CylinderDetectorNode()
    try:
        for name, default, _ in node.PARAMETERS:
            assert ros_node.get_parameter(name).value == default, name
        result = ros_node.set_parameters([Parameter('heartbeat_period_s', value=0.0)])[0]
        assert not result.successful and 'heartbeat_period_s' in result.reason
    finally:
        ros_node.destroy_node()
