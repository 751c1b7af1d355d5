"""The stereo_ses node: declared parameters, config/stereo_ses.yaml and the checks of its input."""

from pathlib import Path

import numpy as np

from stereo_ses_node import node
from vizzy_runtime.convert import array_to_pointcloud2, numpy_to_image
from vizzy_runtime.testing import check_node_parameters, check_parameter_table, node_under_test

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'stereo_ses.yaml'


def test_parameter_table_and_config() -> None:
    check_parameter_table(node.PARAMETERS, node.check_parameter, CONFIG, 'stereo_ses')


def test_images_are_checked() -> None:
    msg = numpy_to_image(np.zeros((48, 64, 3), np.uint8), 'rgb8')
    assert node.image_problem(msg) is None
    msg.encoding = 'bgr8'
    assert node.image_problem(msg) is None
    mono = numpy_to_image(np.zeros((48, 64), np.uint8), 'mono8')
    assert 'encoding' in node.image_problem(mono)
    msg.height = 100  # more rows than the data holds
    assert 'bytes' in node.image_problem(msg)


def test_empty_cells_cloud_has_the_documented_fields() -> None:
    cloud = array_to_pointcloud2(np.zeros(0, dtype=node.CELL_DTYPE))
    assert [f.name for f in cloud.fields] == ['x', 'y', 'z', 'information']
    assert cloud.width == 0 and cloud.point_step == 16


def test_node_declares_its_parameters_and_refuses_bad_values() -> None:
    with node_under_test(node.StereoSesNode) as ros_node:
        check_node_parameters(ros_node, node.PARAMETERS, 'publish_rate_hz', 0.0)
