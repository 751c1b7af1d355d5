"""The foveation node: declared parameters, config/foveation.yaml and the checks of its input."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from foveation_node import node
from vizzy_runtime.convert import numpy_to_image
from vizzy_runtime.testing import (
    check_node_parameters,
    check_parameter_table,
    node_under_test,
    parameter_refusals,
    startup_problem,
)

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'foveation.yaml'


def test_parameter_table_and_config() -> None:
    check_parameter_table(node.PARAMETERS, node.check_parameter, CONFIG, 'foveation')


def test_images_are_checked() -> None:
    """Each problem has its reason (a stable counter key) and a detail with the values."""
    msg = numpy_to_image(np.zeros((48, 64, 3), np.uint8), 'rgb8')
    assert node.image_problem(msg, 4096, 4096) is None
    msg.encoding = 'bgr8'
    assert node.image_problem(msg, 4096, 4096) is None
    mono = numpy_to_image(np.zeros((48, 64), np.uint8), 'mono8')
    assert node.image_problem(mono, 4096, 4096) == (
        'unsupported encoding', "'mono8' is not one of rgb8, bgr8")
    msg.height = 100  # more rows than the data holds
    reason, detail = node.image_problem(msg, 4096, 4096)
    assert reason == 'size inconsistent with data' and '9216 data bytes' in detail
    empty = numpy_to_image(np.zeros((48, 64, 3), np.uint8), 'rgb8')
    empty.width = 0
    assert node.image_problem(empty, 4096, 4096) == ('empty image', '0x48')
    big = numpy_to_image(np.zeros((48, 64, 3), np.uint8), 'rgb8')
    reason, detail = node.image_problem(big, 32, 4096)
    assert reason == 'too large' and 'max_width' in detail
    narrow = numpy_to_image(np.zeros((48, 64, 3), np.uint8), 'rgb8')
    narrow.step = 100
    assert node.image_problem(narrow, 4096, 4096)[0] == 'step shorter than a row'
    for bad in (mono, msg, empty, big, narrow):
        assert node.image_problem(bad, 32, 4096)[0] in node.IMAGE_REASONS


def test_node_declares_its_parameters_and_refuses_bad_values() -> None:
    with node_under_test(node.FoveationNode) as ros_node:
        check_node_parameters(ros_node, node.PARAMETERS, 'max_width', 0)


def test_parameter_checks() -> None:
    with parameter_refusals(node.PARAMETERS, node.check_parameter) as refused:
        assert refused('levels', 0) and refused('levels', 11) and refused('levels', 5) is None
        assert 'sigma_1' in refused('sigma_1', 1.0)          # below the pyramid's floor
        assert refused('sigma_1', node.PYRAMID_SIGMA_1 * (1 - 5e-7))   # exact, unlike a range
        assert refused('sigma_1', node.PYRAMID_SIGMA_1) is None
        assert refused('f0', 0.0) and refused('f0', float('nan')) and refused('f0', 25.0) is None
        assert refused('jpeg_quality', 0) and refused('jpeg_quality', 101)
        assert refused('jpeg_quality', 1) is None
        assert refused('fixation_u', float('inf')) and refused('fixation_u', -1.0) is None
        assert refused('follow_gaze', 1) and refused('follow_gaze', True) is None
        # recognition and saccades
        assert refused('saliency_threshold', 0.0) and refused('saliency_threshold', 1.01)
        assert refused('saliency_threshold', 1.0) is None
        assert refused('top_k', 0) and refused('top_k', 2.0) and refused('top_k', 5) is None
        assert refused('recognition_rate_hz', 0.0) and refused('recognition_rate_hz', 0.5) is None
        assert refused('model_path', 3) and refused('model_path', '') is None
        assert 'no such file' in refused('model_path', '/no/such/model.pt')
        assert 'no such file' in refused('labels_path', '/no/such/labels.txt')
        assert refused('model_path', node.DEFAULT_MODEL) is None
        assert refused('saccade_distance_m', 0.05) and refused('saccade_min_score', float('nan'))
        assert refused('saccades_enabled', 'yes') and refused('saccade_hold_time_s', 0.0) is None


def test_bad_start_up_values_are_one_line_naming_node_parameter_and_rule() -> None:
    assert startup_problem(node.PARAMETERS, node.check_parameter, levels=-3) == (
        "parameter_table: parameter 'levels' = -3: out of range [1, 10]")
    assert startup_problem(node.PARAMETERS, node.check_parameter, levels='abc') == (
        "parameter_table: parameter 'levels' = 'abc': expected integer, got string")
    assert startup_problem(node.PARAMETERS, node.check_parameter, f0=0.0) == (
        "parameter_table: parameter 'f0' = 0.0: f0 must be in (0, 100000], got 0.0")


def test_package_paths_resolve_to_the_packaged_model() -> None:
    model = node.resolve_path(node.DEFAULT_MODEL)
    assert model.name == 'fovea_cnn.pt' and model.parent.name == 'models'
    assert model.parent.parent == Path(node.__file__).parent
    assert node.resolve_path('/tmp/x.pt') == Path('/tmp/x.pt')
    with pytest.raises(ValueError, match='no installed package'):
        node.resolve_path('package://no_such_package_here/x.pt')


def test_fixation_defaults_to_the_centre_and_must_be_on_the_image() -> None:
    assert node.fixation_for(640, 480, -1.0, -1.0) == (319.5, 239.5)
    assert node.fixation_for(640, 480, 10.0, -1.0) == (10.0, 239.5)
    with pytest.raises(ValueError, match='outside'):
        node.fixation_for(640, 480, 700.0, 10.0)


def test_jpeg_keeps_the_colours() -> None:
    rgb = np.zeros((32, 32, 3), np.uint8)
    rgb[..., 0] = 200                                    # red in rgb8
    decoded = cv2.imdecode(np.frombuffer(node.encode_jpeg(rgb, 'rgb8', 95), np.uint8),
                           cv2.IMREAD_COLOR)             # BGR
    assert decoded[16, 16, 2] > 150 and decoded[16, 16, 0] < 50
