"""The foveation node's recognition live on the bundled runtime: detections per pass and saccades.

The classifier is conftest's stub colour detector (no training); a test node publishes
images, camera_info and gaze states and listens to /foveation/detections,
/foveation/detections_2d and /gaze/command.
Nothing asserts on wall-clock time: the tests wait for conditions.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from foveation_node import node as fov_node
from foveation_node.core.overlay import FIXATION_COLOUR, PASS_COLOURS
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
GazeCommand = message('active_vision_msgs/msg/GazeCommand')
FoveatedDetectionArray = message('active_vision_msgs/msg/FoveatedDetectionArray')
Detection2DArray = message('vision_msgs/msg/Detection2DArray')
Image = message('sensor_msgs/msg/Image')
CameraInfo = message('sensor_msgs/msg/CameraInfo')

TIMEOUT = scaled(30.0)
WIDTH, HEIGHT = 320, 240
FX = 180.0
PATCH = (260, 60)                 # a red patch up and to the right of the centre
FRAME = 'left_camera_optical_frame'


class Camera(Node):
    """Publishes images, camera_info and gaze states (as a driver: the default reliable QoS);
    keeps detections and gaze commands. On the foveation node's resolved topic names."""

    def __init__(self, context: Context, foveation: Any) -> None:
        super().__init__('fake_camera', context=context, start_parameter_services=False)
        self.detections: list[Any] = []
        self.commands: list[Any] = []
        self.image_pub = self.create_publisher(Image, foveation._image_sub.topic_name,
                                               qos_profile_system_default)
        self.info_pub = self.create_publisher(CameraInfo, foveation._info_sub.topic_name,
                                              qos_profile_system_default)
        self.gaze_pub = self.create_publisher(GazeState, foveation._gaze_state_sub.topic_name, 10)
        self.create_subscription(FoveatedDetectionArray, foveation._det_pub.topic_name,
                                 self.detections.append, 10)
        self.detections_2d: list[Any] = []
        self.create_subscription(Detection2DArray, foveation._det2d_pub.topic_name,
                                 self.detections_2d.append, 10)
        self.create_subscription(GazeCommand, foveation._gaze_pub.topic_name,
                                 self.commands.append, 10)
        self.overlays: list[Any] = []
        self.create_subscription(Image, foveation._overlay_pub.topic_name, self.overlays.append,
                                 qos_profile_sensor_data)


def _camera_info() -> Any:
    info = CameraInfo(width=WIDTH, height=HEIGHT)
    info.header.frame_id = FRAME
    info.k = [FX, 0.0, (WIDTH - 1) / 2, 0.0, FX, (HEIGHT - 1) / 2, 0.0, 0.0, 1.0]
    return info


def _image_msg() -> Any:
    img = np.full((HEIGHT, WIDTH, 3), 40, np.uint8)
    u, v = PATCH
    img[v - 12:v + 12, u - 12:u + 12] = (230, 30, 30)
    msg = numpy_to_image(img, 'rgb8')
    msg.header.frame_id = FRAME
    msg.header.stamp.sec = 7
    return msg


@pytest.fixture
def graph(context, stub_model):
    model, labels = stub_model
    foveation = fov_node.FoveationNode(context=context, parameter_overrides=[
        Parameter('model_path', value=str(model)), Parameter('labels_path', value=str(labels)),
        Parameter('f0', value=30.0), Parameter('recognition_rate_hz', value=50.0),
        Parameter('top_k', value=3), Parameter('saccade_min_interval_s', value=0.0)])
    camera = Camera(context, foveation)
    with spinning(context, [camera, foveation],
                  lambda: camera.image_pub.get_subscription_count() > 0
                  and camera.info_pub.get_subscription_count() > 0
                  and foveation._det_pub.get_subscription_count() > 0
                  and foveation._det2d_pub.get_subscription_count() > 0
                  and foveation._gaze_pub.get_subscription_count() > 0, TIMEOUT) as executor:
        yield camera, foveation, executor


def _send_until(camera: Camera, executor: Any, msg: Any, done: Any) -> bool:
    """Publish camera_info and msg every 0.2 s until done()."""
    def publish() -> None:
        camera.info_pub.publish(_camera_info())
        camera.image_pub.publish(msg)

    return publish_until(publish, done, executor, TIMEOUT)


def test_detections_per_pass_and_a_saccade_to_the_object(graph) -> None:
    camera, foveation, executor = graph
    assert foveation._classifier is not None
    assert _send_until(camera, executor, _image_msg(),
                       lambda: len(camera.detections) >= 2 and camera.commands)
    first, second = camera.detections[0], camera.detections[1]
    assert [d.pass_index for d in first.detections] == [0, 0, 0]
    assert {d.pass_index for d in second.detections} == {1}
    assert first.header.frame_id == FRAME and first.header.stamp.sec == 7
    assert (first.fixation_u, first.fixation_v) == ((WIDTH - 1) / 2, (HEIGHT - 1) / 2)
    assert first.fovea_size == 30.0
    best = second.detections[0]
    assert best.label == 'red' and best.class_id == 0 and best.score > 0.9
    box = best.box
    cu, cv = box.x_offset + box.width / 2, box.y_offset + box.height / 2
    assert abs(cu - PATCH[0]) < 20 and abs(cv - PATCH[1]) < 20
    # pass 2 of the red label looked with the fovea on the patch
    assert abs(best.fixation_u - PATCH[0]) < 20 and abs(best.fixation_v - PATCH[1]) < 20

    cmd = camera.commands[0]
    assert cmd.source == 'foveation' and cmd.priority == 30
    assert cmd.mode == GazeCommand.MODE_FIXATION_POINT
    assert cmd.motion == GazeCommand.MOTION_SACCADE
    assert cmd.header.frame_id == FRAME and cmd.hold_time == 1.0
    p = np.array([cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z])
    assert np.linalg.norm(p) == pytest.approx(1.0)             # saccade_distance_m
    # the ray through the patch: right (x > 0) and up (y < 0) of the optical axis
    u = FX * p[0] / p[2] + (WIDTH - 1) / 2
    v = FX * p[1] / p[2] + (HEIGHT - 1) / 2
    assert math.hypot(u - PATCH[0], v - PATCH[1]) < 20


def test_pass_two_detections_as_vision_msgs(graph) -> None:
    camera, foveation, executor = graph
    assert foveation._det2d_pub.topic_name == '/foveation/detections_2d'
    assert _send_until(camera, executor, _image_msg(),
                       lambda: len(camera.detections) >= 2 and camera.detections_2d)
    # the same frame's pass 2 (the image never changes, so every recognition gives the same)
    second, out = camera.detections[1], camera.detections_2d[0]
    assert {d.pass_index for d in second.detections} == {1}
    assert out.header.frame_id == FRAME and out.header.stamp.sec == 7
    assert len(out.detections) == len(second.detections) == 3
    for det, ours in zip(out.detections, second.detections, strict=True):
        assert det.header.frame_id == FRAME and det.header.stamp.sec == 7 and det.id == ''
        # the same box: inclusive pixel bounds x_offset .. x_offset + width - 1
        assert det.bbox.size_x == ours.box.width and det.bbox.size_y == ours.box.height
        assert det.bbox.center.position.x == ours.box.x_offset + (ours.box.width - 1) / 2
        assert det.bbox.center.position.y == ours.box.y_offset + (ours.box.height - 1) / 2
        assert det.bbox.center.theta == 0.0
        # its own label and score first, then the 2 other stub classes (top_k 3), likeliest first
        hyps = [(r.hypothesis.class_id, r.hypothesis.score) for r in det.results]
        assert hyps[0] == (ours.label, ours.score)
        assert sorted(label for label, _ in hyps) == ['blue', 'green', 'red']
        assert hyps[2][1] <= hyps[1][1]
    best = out.detections[0]
    assert best.results[0].hypothesis.class_id == 'red' and best.results[0].hypothesis.score > 0.9
    c = best.bbox.center.position
    assert abs(c.x - PATCH[0]) < 20 and abs(c.y - PATCH[1]) < 20


def test_the_overlay_shows_both_passes_fixation_and_fovea(graph) -> None:
    camera, foveation, executor = graph
    assert _send_until(camera, executor, _image_msg(), lambda: bool(camera.overlays))
    overlay = camera.overlays[0]
    assert (overlay.encoding, overlay.width, overlay.height) == ('rgb8', WIDTH, HEIGHT)
    assert overlay.header.frame_id == FRAME and overlay.header.stamp.sec == 7
    pixels = image_to_numpy(overlay)
    for colour in (*PASS_COLOURS.values(), FIXATION_COLOUR):
        assert (pixels == np.array(colour, np.uint8)).all(axis=-1).any(), colour
    # the fovea's circle (radius f0 = 30) around the fixation, the image centre
    u, v = round((WIDTH - 1) / 2 + 30), round((HEIGHT - 1) / 2)
    ring = pixels[v - 2:v + 3, u - 2:u + 3]
    assert (ring == np.array(FIXATION_COLOUR, np.uint8)).all(axis=-1).any()


def test_no_saccade_from_a_stale_frame_or_when_disabled(graph) -> None:
    camera, foveation, executor = graph
    camera.info_pub.publish(_camera_info())
    assert wait_until(lambda: foveation._camera_k is not None, TIMEOUT, spin=executor)
    msg = _image_msg()
    image = np.asarray(msg.data, np.uint8).reshape(HEIGHT, WIDTH, 3)
    centre = ((WIDTH - 1) / 2, (HEIGHT - 1) / 2)
    stale = foveation._saccade_epoch - 1              # a saccade began after the frame
    assert foveation.recognise(image, msg, centre, stale) is not None
    assert foveation.saccades_sent == 0
    foveation.set_parameters([Parameter('saccades_enabled', value=False)])
    foveation.recognise(image, msg, centre, foveation._saccade_epoch)
    assert foveation.saccades_sent == 0
    foveation.set_parameters([Parameter('saccades_enabled', value=True)])
    foveation.recognise(image, msg, centre, foveation._saccade_epoch)
    assert foveation.saccades_sent == 1
    # while the eyes move: none
    camera.gaze_pub.publish(GazeState(in_saccade=True))
    assert wait_until(lambda: foveation._in_saccade, TIMEOUT, spin=executor)
    foveation.recognise(image, msg, centre, foveation._saccade_epoch)
    assert foveation.saccades_sent == 1


def test_a_bad_model_is_logged_and_the_node_keeps_foveating(graph, tmp_path, capfd) -> None:
    camera, foveation, executor = graph
    bad = tmp_path / 'bad.pt'
    bad.write_bytes(b'\x00garbage')
    assert foveation.set_parameters([Parameter('model_path', value=str(bad))])[0].successful
    assert foveation._classifier is None
    assert 'cannot load TorchScript model' in capfd.readouterr().err
    frames = foveation.frames_published
    assert _send_until(camera, executor, _image_msg(),
                       lambda: foveation.frames_published > frames + 2)
    assert foveation.recognitions == 0
    # an empty path switches recognition off without complaint; bad values are refused
    assert foveation.set_parameters([Parameter('model_path', value='')])[0].successful
    assert 'recognition off' in capfd.readouterr().err
    assert not foveation.set_parameters([Parameter('saliency_threshold', value=1.5)])[0].successful
    assert not foveation.set_parameters([Parameter('top_k', value=0)])[0].successful
