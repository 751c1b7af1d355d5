"""The cylinder_detector node: its parameters, config/cylinder_detector.yaml, its input checks."""

from pathlib import Path

import numpy as np

from cylinder_detector_node import node
from vizzy_runtime.convert import array_to_pointcloud2
from vizzy_runtime.testing import check_node_parameters, check_parameter_table, node_under_test

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'cylinder_detector.yaml'


def test_parameter_table_and_config() -> None:
    check_parameter_table(node.PARAMETERS, node.check_parameter, CONFIG, 'cylinder_detector')


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


def test_node_declares_its_parameters_and_refuses_bad_values() -> None:
    with node_under_test(node.CylinderDetectorNode) as ros_node:
        check_node_parameters(ros_node, node.PARAMETERS, 'heartbeat_period_s', 0.0)
