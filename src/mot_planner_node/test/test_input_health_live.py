"""The mot_planner node counts every input it refuses, per topic and reason (InputHealth), keeps
running with its tracks untouched, and processes the next good message; the counts go out on
/diagnostics.

A test node publishes bad images and a bad camera_info on the node's inputs, all in one process
and one executor (an exception escaping a callback would end the test's spin_once). The detector
is a stub that finds nothing (the subject is the input checks). Nothing asserts on wall-clock
time: the tests wait for conditions.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from mot_planner_node import node as mot_node
from mot_planner_node.core.detector import BoxShrink, Detections
from mot_planner_node.core.observation import DetectorGeometry
from vizzy_runtime.convert import numpy_to_image
from vizzy_runtime.input_health import DIAGNOSTICS_TOPIC
from vizzy_runtime.ros import Context, Node, message, qos_profile_system_default
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
TrackArray = message('active_vision_msgs/msg/TrackArray')
DiagnosticArray = message('diagnostic_msgs/msg/DiagnosticArray')

TIMEOUT = scaled(20.0)
WIDTH, HEIGHT = 160, 120


class NoDetector:
    """A detector that finds nobody."""

    geometry = DetectorGeometry(window_w=32.0, window_h=64.0, stride=4.0, scale_step=1.05)
    box_shrink = BoxShrink()

    def detect(self, image: np.ndarray, regions: np.ndarray | None = None) -> Detections:
        return Detections(np.zeros((0, 4)), np.zeros(0))


class Camera(Node):
    """Publishes images and camera_info on the node's resolved inputs; keeps its track arrays
    and the /diagnostics reports."""

    def __init__(self, context: Context, mot: Any) -> None:
        super().__init__('fake_camera', context=context, start_parameter_services=False)
        self.tracks: list[Any] = []
        self.reports: list[Any] = []
        self.image_pub = self.create_publisher(Image, mot._image_sub.topic_name,
                                               qos_profile_system_default)
        self.info_pub = self.create_publisher(CameraInfo, mot._info_sub.topic_name,
                                              qos_profile_system_default)
        self.create_subscription(TrackArray, mot._tracks_pub.topic_name, self.tracks.append, 10)
        self.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self.reports.append,
                                 qos_profile_system_default)


@pytest.fixture
def graph(context, monkeypatch):
    monkeypatch.setattr(mot_node, 'DETECTOR_FACTORY', lambda params: NoDetector())
    mot = mot_node.MotPlannerNode(context=context)
    camera = Camera(context, mot)
    with spinning(context, [camera, mot],
                  lambda: camera.image_pub.get_subscription_count() > 0
                  and camera.info_pub.get_subscription_count() > 0
                  and mot._tracks_pub.get_subscription_count() > 0, TIMEOUT) as executor:
        yield camera, mot, executor


def _good_image() -> Any:
    msg = numpy_to_image(np.full((HEIGHT, WIDTH, 3), 30, np.uint8), 'rgb8')
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
    camera, mot, executor = graph
    health = mot.input_health
    image_topic, info_topic = mot._image_topic, mot._info_topic

    def accepted(topic: str) -> int:
        return health.accepted().get(topic, 0)

    # a good image and camera_info first: both ways matched, nothing refused yet
    good = _good_image()
    assert publish_until(lambda: camera.image_pub.publish(good),
                         lambda: accepted(image_topic) > 0 and camera.tracks, executor, TIMEOUT)
    k = [200.0, 0.0, 80.0, 0.0, 200.0, 60.0, 0.0, 0.0, 1.0]
    assert publish_until(lambda: camera.info_pub.publish(_camera_info(k)),
                         lambda: accepted(info_topic) > 0, executor, TIMEOUT)
    assert health.refused() == {}
    processed, size = mot.frames_processed, mot._tracker.image_size

    bad_images = [
        ('unsupported encoding', _small(encoding='yuv9')),
        ('unsupported encoding', _small(encoding='mono8')),
        ('size inconsistent with data', _small(height=8)),    # 96 bytes, 192 needed
        ('empty image', _small(height=0)),
        ('step shorter than a row', _small(step=10)),        # a row of 8 rgb8 px is 24 bytes
        # issue 28 item 8: a 1x100000 frame reset the tracker (a new size); no person fits it
        ('smaller than the detector window',
         numpy_to_image(np.zeros((100000, 1, 3), np.uint8), 'rgb8')),
        ('smaller than the detector window',
         numpy_to_image(np.zeros((1, 100000, 3), np.uint8), 'rgb8')),
    ]
    for reason, msg in bad_images:
        assert refused_once(mot, executor, lambda msg=msg: camera.image_pub.publish(msg),
                             (image_topic, reason)), reason
    # an exception inside the callback is counted too (node_tools.guarded), and swallowed
    def broken(*args: Any, **kwargs: Any) -> Any:
        raise RuntimeError('tracker on fire')

    mot._tracker.step = broken
    assert refused_once(mot, executor, lambda: camera.image_pub.publish(good),
                         (image_topic, 'failed on an image: RuntimeError'))
    del mot._tracker.step                                # the class's again
    # a camera_info without a usable K: refused, the last good one stays
    assert refused_once(mot, executor, lambda: camera.info_pub.publish(_camera_info([0.0] * 9)),
                         (info_topic, 'unusable K'))
    assert mot._k == k

    assert health.refused() == {
        (image_topic, 'unsupported encoding'): 2,
        (image_topic, 'size inconsistent with data'): 1,
        (image_topic, 'empty image'): 1,
        (image_topic, 'step shorter than a row'): 1,
        (image_topic, 'smaller than the detector window'): 2,
        (image_topic, 'failed on an image: RuntimeError'): 1,
        (info_topic, 'unusable K'): 1,
    }
    # the refused images touched nothing: no frame processed, no size change, no reset
    assert mot.frames_processed == processed and mot._tracker.image_size == size
    assert mot.frames_dropped == 7 and mot.resets == 0

    # the next good image is processed: accepted and tracked
    tracks, done = len(camera.tracks), accepted(image_topic)
    assert publish_until(lambda: camera.image_pub.publish(good),
                         lambda: accepted(image_topic) > done and len(camera.tracks) > tracks,
                         executor, TIMEOUT)
    assert mot.frames_processed > processed

    # /diagnostics: the node's status carries the counts
    name = mot.get_fully_qualified_name()
    assert wait_until(lambda: reported_status(camera.reports, name).get(f'{info_topic}: unusable K')
                      == '1', TIMEOUT, spin=executor)
    values = reported_status(camera.reports, name)
    assert values[f'{image_topic}: unsupported encoding'] == '2'
    assert int(values[f'{image_topic}: accepted']) >= 1

    # logged: the first of each (topic, reason) in one line with the values
    err = capfd.readouterr().err
    assert f"{image_topic}: refused: unsupported encoding: 'yuv9' is not one of" in err, err
    assert f'{image_topic}: refused: failed on an image: RuntimeError: tracker on fire' in err
    assert f'{info_topic}: refused: unusable K: K [0, 0, 0, 0, 0, 0, 0, 0, 0]' in err, err
    assert 'Traceback' not in err, err
