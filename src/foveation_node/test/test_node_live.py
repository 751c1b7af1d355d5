"""The foveation node live on the bundled runtime: images in, foveated images and JPEGs out.

A test node publishes camera images and gaze states and listens to the node's outputs, all in
one process and one executor. Nothing asserts on wall-clock time: the tests wait for conditions.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest

from foveation_node import node as fov_node
from foveation_node.core.synthetic import white_noise
from vizzy_runtime.convert import image_to_numpy, numpy_to_image
from vizzy_runtime.ros import (
    Context,
    Node,
    Parameter,
    message,
    qos_profile_sensor_data,
    qos_profile_system_default,
)
from vizzy_runtime.testing import publish_until, scaled, spinning, wait_until

pytestmark = pytest.mark.live  # also run on the real rclpy (scripts/test_ros.sh)

GazeState = message('active_vision_msgs/msg/GazeState')
DiagnosticStatus = message('diagnostic_msgs/msg/DiagnosticStatus')
Image = message('sensor_msgs/msg/Image')
CompressedImage = message('sensor_msgs/msg/CompressedImage')

TIMEOUT = scaled(20.0)
WIDTH, HEIGHT = 161, 121          # odd: the centre (80, 60) is a whole pixel
F0 = 8.0


class Camera(Node):
    """Publishes images and gaze states (as a driver: the default reliable QoS); keeps what the
    foveation node publishes. On the node's resolved topic names."""

    def __init__(self, context: Context, foveation: Any) -> None:
        super().__init__('fake_camera', context=context, start_parameter_services=False)
        self.images: list[Any] = []
        self.jpegs: list[Any] = []
        self.image_pub = self.create_publisher(Image, foveation._image_sub.topic_name,
                                               qos_profile_system_default)
        self.gaze_pub = self.create_publisher(GazeState, foveation._gaze_state_sub.topic_name, 10)
        self.create_subscription(Image, foveation._pub.topic_name, self.images.append,
                                 qos_profile_sensor_data)
        self.create_subscription(CompressedImage, foveation._jpeg_pub.topic_name,
                                 self.jpegs.append, qos_profile_sensor_data)


@pytest.fixture
def graph(context):
    foveation = fov_node.FoveationNode(
        context=context, parameter_overrides=[Parameter('f0', value=F0)])
    camera = Camera(context, foveation)
    with spinning(context, [camera, foveation],
                  lambda: camera.image_pub.get_subscription_count() > 0
                  and camera.gaze_pub.get_subscription_count() > 0
                  and foveation._pub.get_subscription_count() > 0
                  and foveation._jpeg_pub.get_subscription_count() > 0, TIMEOUT) as executor:
        yield camera, foveation, executor


def _scene(seed: int = 1) -> np.ndarray:
    """A textured rgb8 image: white noise, so every region has the same fine detail."""
    return np.clip(white_noise(WIDTH, HEIGHT, 3, std=50.0, seed=seed), 0, 255).astype(np.uint8)


def _send_until(camera: Camera, executor: Any, msg: Any, done: Any) -> bool:
    """Publish msg again every 0.2 s until done()."""
    return publish_until(lambda: camera.image_pub.publish(msg), done, executor, TIMEOUT)


def _high_pass(image: np.ndarray) -> np.ndarray:
    grey = image.astype(np.float32).mean(axis=2)
    return np.abs(cv2.Laplacian(grey, cv2.CV_32F))


def test_foveates_and_compresses(graph) -> None:
    camera, foveation, executor = graph
    scene = _scene()
    msg = numpy_to_image(scene, 'rgb8')
    msg.header.frame_id = 'left_camera_optical_frame'
    msg.header.stamp.sec = 42
    assert _send_until(camera, executor, msg, lambda: camera.images and camera.jpegs)

    published = camera.images[-1]
    assert (published.encoding, published.width, published.height) == ('rgb8', WIDTH, HEIGHT)
    assert published.header.frame_id == 'left_camera_optical_frame'
    assert published.header.stamp.sec == 42
    out = image_to_numpy(published)
    # the fovea keeps the original pixels (within the pyramid's rounding)...
    centre = np.s_[60 - 1:60 + 2, 80 - 1:80 + 2]
    assert np.abs(out[centre].astype(int) - scene[centre].astype(int)).max() <= 2
    # ...and the periphery loses its fine detail: far less high-pass energy than the input
    corner = np.s_[5:30, 5:40]
    assert _high_pass(out)[corner].mean() < 0.3 * _high_pass(scene)[corner].mean()

    jpeg = camera.jpegs[-1]
    assert jpeg.format == 'rgb8; jpeg compressed bgr8' and jpeg.header.stamp.sec == 42
    data = np.asarray(jpeg.data, dtype=np.uint8)
    decoded = cv2.imdecode(data, cv2.IMREAD_COLOR)
    assert decoded is not None and decoded.shape == (HEIGHT, WIDTH, 3)
    decoded_rgb = cv2.cvtColor(decoded, cv2.COLOR_BGR2RGB).astype(float)
    assert np.abs(decoded_rgb - out).mean() < 10.0       # the JPEG is of the foveated image
    quality = foveation.get_parameter('jpeg_quality').value
    raw = fov_node.encode_jpeg(scene, 'rgb8', quality)
    assert data.size < 0.7 * len(raw), (data.size, len(raw))
    assert foveation.last_bandwidth is not None          # the first frame is reported
    assert foveation.last_bandwidth[1] == len(raw)


def test_saccades_suppress_output(graph) -> None:
    camera, foveation, executor = graph
    msg = numpy_to_image(_scene(), 'rgb8')
    camera.gaze_pub.publish(GazeState(in_saccade=True))
    assert wait_until(lambda: foveation._in_saccade, TIMEOUT, spin=executor)
    before = len(camera.images)
    assert _send_until(camera, executor, msg, lambda: foveation.frames_suppressed >= 3)
    wait_until(lambda: False, 0.3, spin=executor)       # let anything in flight arrive
    assert len(camera.images) == before and foveation.frames_published == 0

    camera.gaze_pub.publish(GazeState(in_saccade=False))
    assert wait_until(lambda: not foveation._in_saccade, TIMEOUT, spin=executor)
    assert _send_until(camera, executor, msg, lambda: len(camera.images) > before)


def test_a_saccade_that_never_ends_is_a_warning_naming_the_held_frames(graph) -> None:
    """Issue 28 item 4: a gaze state stuck in_saccade stopped /foveation/image while
    /diagnostics said 'inputs OK'. Held frames are counted, and the stall is a WARN."""
    camera, foveation, executor = graph
    health = foveation.input_health
    msg = numpy_to_image(_scene(), 'rgb8')
    assert _send_until(camera, executor, msg, lambda: foveation.frames_published > 0)
    assert health.status().level == DiagnosticStatus.OK
    camera.gaze_pub.publish(GazeState(in_saccade=True))
    assert wait_until(lambda: foveation._in_saccade, TIMEOUT, spin=executor)
    # frames keep arriving; after OUTPUT_STALL_S of the node's clock without output: a stall
    assert _send_until(camera, executor, msg, lambda: bool(health.stalls()))
    status = health.status()
    assert status.level == DiagnosticStatus.WARN, status.message
    jpeg_topic = foveation._jpeg_pub.topic_name
    assert status.message.startswith(f'no {jpeg_topic} for '), status.message
    assert f'while {foveation._image_topic} arrives' in status.message
    held = health.held()[(foveation._image_topic, fov_node.IN_SACCADE)]
    assert held == foveation.frames_suppressed >= 2
    assert 'held (in saccade)' in status.message, status.message
    values = {kv.key: kv.value for kv in status.values}
    assert values[f'{foveation._image_topic}: held (in saccade)'] == str(held)
    # the saccade ends: the output resumes and the warning with it
    camera.gaze_pub.publish(GazeState(in_saccade=False))
    assert _send_until(camera, executor, msg, lambda: not health.stalls())
    assert health.status().level == DiagnosticStatus.OK


def test_bad_images_are_dropped_and_the_node_keeps_working(graph, capfd) -> None:
    camera, foveation, executor = graph
    mono = numpy_to_image(np.full((HEIGHT, WIDTH), 100, np.uint8), 'mono8')
    assert _send_until(camera, executor, mono,
                       lambda: "'mono8'" in capfd.readouterr().err)
    assert not camera.images

    # a fixation outside the image: logged and skipped, nothing published
    result = foveation.set_parameters([Parameter('fixation_u', value=1000.0)])[0]
    assert result.successful
    msg = numpy_to_image(_scene(), 'rgb8')
    assert _send_until(camera, executor, msg, lambda: 'outside' in capfd.readouterr().err)
    assert not camera.images

    # back on the image, and a new fovea size (the Foveator is rebuilt): the node works
    assert all(r.successful for r in foveation.set_parameters(
        [Parameter('fixation_u', value=-1.0), Parameter('f0', value=30.0)]))
    assert _send_until(camera, executor, msg, lambda: camera.images)
    assert foveation._foveator is not None and foveation._foveator.f0 == 30.0
    # bad values are refused at run time
    assert not foveation.set_parameters([Parameter('jpeg_quality', value=0)])[0].successful
    assert not foveation.set_parameters([Parameter('sigma_1', value=1.0)])[0].successful
