"""The foveation node counts every input it refuses, per topic and reason (InputHealth), keeps
running, and processes the next good message; the counts go out on /diagnostics.

A test node publishes bad images and a bad camera_info on the node's inputs, all in one process
and one executor (an exception escaping a callback would end the test's spin_once). Nothing
asserts on wall-clock time: the tests wait for conditions.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from foveation_node import node as fov_node
from vizzy_runtime.convert import numpy_to_image
from vizzy_runtime.input_health import DIAGNOSTICS_TOPIC
from vizzy_runtime.ros import (
    Context,
    Node,
    Parameter,
    message,
    qos_profile_sensor_data,
    qos_profile_system_default,
)
from vizzy_runtime.testing import (
    publish_until,
    refused_once,
    reported_status,
    scaled,
    spinning,
    wait_until,
)

pytestmark = pytest.mark.live  # also run on the real rclpy (scripts/test_ros.sh)

Image = message('sensor_msgs/msg/Image')
CameraInfo = message('sensor_msgs/msg/CameraInfo')
DiagnosticArray = message('diagnostic_msgs/msg/DiagnosticArray')
DiagnosticStatus = message('diagnostic_msgs/msg/DiagnosticStatus')

TIMEOUT = scaled(20.0)
WIDTH, HEIGHT = 161, 121


class Camera(Node):
    """Publishes images and camera_info on the node's resolved inputs; keeps its foveated
    images and the /diagnostics reports."""

    def __init__(self, context: Context, foveation: Any) -> None:
        super().__init__('fake_camera', context=context, start_parameter_services=False)
        self.images: list[Any] = []
        self.reports: list[Any] = []
        self.image_pub = self.create_publisher(Image, foveation._image_sub.topic_name,
                                               qos_profile_system_default)
        self.info_pub = self.create_publisher(CameraInfo, foveation._info_sub.topic_name,
                                              qos_profile_system_default)
        self.create_subscription(Image, foveation._pub.topic_name, self.images.append,
                                 qos_profile_sensor_data)
        self.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self.reports.append,
                                 qos_profile_system_default)


@pytest.fixture
def graph(context):
    foveation = fov_node.FoveationNode(context=context, parameter_overrides=[
        Parameter('f0', value=8.0), Parameter('model_path', value='')])   # no recognition
    camera = Camera(context, foveation)
    with spinning(context, [camera, foveation],
                  lambda: camera.image_pub.get_subscription_count() > 0
                  and camera.info_pub.get_subscription_count() > 0
                  and foveation._pub.get_subscription_count() > 0, TIMEOUT) as executor:
        yield camera, foveation, executor


def _good_image() -> Any:
    rng = np.random.default_rng(1)
    msg = numpy_to_image(rng.integers(0, 256, (HEIGHT, WIDTH, 3), np.uint8), 'rgb8')
    msg.header.frame_id = 'left_camera_optical_frame'
    return msg


def _small(**fields: Any) -> Any:
    """An 8x4 rgb8 image (96 bytes, step 24) with fields changed."""
    msg = numpy_to_image(np.zeros((4, 8, 3), np.uint8), 'rgb8')
    for name, value in fields.items():
        setattr(msg, name, value)
    return msg


def _camera_info(k: list[float]) -> Any:
    info = CameraInfo(width=WIDTH, height=HEIGHT)
    info.k = k
    return info


def test_refused_inputs_are_counted_per_topic_and_reason(graph, capfd) -> None:
    camera, foveation, executor = graph
    health = foveation.input_health
    image_topic, info_topic = foveation._image_topic, foveation._info_topic

    def accepted(topic: str) -> int:
        return health.accepted().get(topic, 0)

    # a good image and camera_info first: both ways matched, nothing refused yet
    good = _good_image()
    assert publish_until(lambda: camera.image_pub.publish(good),
                         lambda: accepted(image_topic) > 0 and camera.images, executor, TIMEOUT)
    k = [200.0, 0.0, 80.0, 0.0, 200.0, 60.0, 0.0, 0.0, 1.0]
    assert publish_until(lambda: camera.info_pub.publish(_camera_info(k)),
                         lambda: accepted(info_topic) > 0, executor, TIMEOUT)
    assert health.refused() == {}

    bad_images = [
        ('unsupported encoding', _small(encoding='yuv9')),
        ('unsupported encoding', _small(encoding='mono8')),
        ('size inconsistent with data', _small(height=8)),    # 96 bytes, 192 needed
        ('empty image', _small(height=0)),
        ('step shorter than a row', _small(step=10)),        # a row of 8 rgb8 px is 24 bytes
        ('too small for levels', _small()),                  # 5 levels need 32 px a side
    ]
    for reason, msg in bad_images:
        assert refused_once(foveation, executor, lambda msg=msg: camera.image_pub.publish(msg),
                             (image_topic, reason)), reason
    # a fixation outside the image
    assert foveation.set_parameters([Parameter('fixation_u', value=1000.0)])[0].successful
    assert refused_once(foveation, executor, lambda: camera.image_pub.publish(good),
                         (image_topic, 'fixation outside image'))
    assert foveation.set_parameters([Parameter('fixation_u', value=-1.0)])[0].successful
    # an exception inside the callback is counted too (node_tools.guarded), and swallowed
    def broken(width: int, height: int) -> Any:
        raise RuntimeError('foveator on fire')

    foveation._get_foveator = broken
    assert refused_once(foveation, executor, lambda: camera.image_pub.publish(good),
                         (image_topic, 'failed on an image: RuntimeError'))
    del foveation._get_foveator                          # the class's again
    # a camera_info without a usable K: refused, the last good one stays
    assert refused_once(foveation, executor,
                         lambda: camera.info_pub.publish(_camera_info([0.0] * 9)),
                         (info_topic, 'unusable K'))
    assert foveation._camera_k == tuple(k)

    assert health.refused() == {
        (image_topic, 'unsupported encoding'): 2,
        (image_topic, 'size inconsistent with data'): 1,
        (image_topic, 'empty image'): 1,
        (image_topic, 'step shorter than a row'): 1,
        (image_topic, 'too small for levels'): 1,
        (image_topic, 'fixation outside image'): 1,
        (image_topic, 'failed on an image: RuntimeError'): 1,
        (info_topic, 'unusable K'): 1,
    }

    # the next good image is processed: accepted and foveated
    images, done = len(camera.images), accepted(image_topic)
    assert publish_until(lambda: camera.image_pub.publish(good),
                         lambda: accepted(image_topic) > done and len(camera.images) > images,
                         executor, TIMEOUT)

    # /diagnostics: the node's status carries the counts
    name = foveation.get_fully_qualified_name()
    assert wait_until(lambda: reported_status(camera.reports, name).get(f'{info_topic}: unusable K')
                      == '1', TIMEOUT, spin=executor)
    values = reported_status(camera.reports, name)
    assert values[f'{image_topic}: unsupported encoding'] == '2'
    assert int(values[f'{image_topic}: accepted']) >= 1

    # logged: the first of each (topic, reason) in one line with the values
    err = capfd.readouterr().err
    assert f"{image_topic}: refused: unsupported encoding: 'yuv9' is not one of" in err, err
    assert f'{image_topic}: refused: failed on an image: RuntimeError: foveator on fire' in err
    assert f'{info_topic}: refused: unusable K: K [0, 0, 0, 0, 0, 0, 0, 0, 0]' in err, err
    assert 'Traceback' not in err, err
