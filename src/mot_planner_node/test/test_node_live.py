"""The mot_planner node live on the bundled runtime: images in; tracks, regions, overlay, gaze out.

A test node publishes camera images, camera_info and gaze states and listens to the node's
outputs, all in one process and one executor. HOG does not fire on simple renders, so the node's
module-level DETECTOR_FACTORY is replaced by BlobDetector: bright rectangles on a dark background
are the "people", found only inside the regions the tracker asks for. Nothing asserts on
wall-clock time: the tests wait for conditions.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest

from mot_planner_node import node as mot_node
from mot_planner_node.core.detector import BoxShrink, Detections
from mot_planner_node.core.observation import DetectorGeometry
from vizzy_runtime.convert import image_to_numpy, numpy_to_image
from vizzy_runtime.ros import message, qos_profile_sensor_data
from vizzy_runtime.rclpy_compat.context import Context
from vizzy_runtime.rclpy_compat.executors import SingleThreadedExecutor
from vizzy_runtime.rclpy_compat.node import Node
from vizzy_runtime.rclpy_compat.parameter import Parameter
from vizzy_runtime.testing import wait_until

Image = message('sensor_msgs/msg/Image')
CameraInfo = message('sensor_msgs/msg/CameraInfo')
TrackArray = message('active_vision_msgs/msg/TrackArray')
AttentionRegions = message('active_vision_msgs/msg/AttentionRegions')
GazeCommand = message('active_vision_msgs/msg/GazeCommand')
GazeState = message('active_vision_msgs/msg/GazeState')

TIMEOUT = 20.0
WIDTH, HEIGHT = 320, 240
K_MAX = 2
FRAME = 'left_camera_optical_frame'
# (x, y, w, h) of four "people" at frame 0 (scales 1 and 1.25 of a 32x64 window) and their
# velocity [px/frame]: more people than K_MAX, so the planner must choose.
PEOPLE = np.array([[20, 40, 32, 64], [100, 120, 40, 80], [180, 30, 32, 64], [250, 110, 40, 80]],
                  float)
VELOCITY = np.array([1.0, 0.5])


class BlobDetector:
    """Finds bright rectangles; a blob counts in a region when its centre lies inside it."""

    geometry = DetectorGeometry(window_w=32.0, window_h=64.0, stride=4.0, scale_step=1.05)
    box_shrink = BoxShrink()

    def detect(self, image: np.ndarray, regions: np.ndarray | None = None) -> Detections:
        grey = image if image.ndim == 2 else image.max(axis=2)
        n, _, stats, _ = cv2.connectedComponentsWithStats((grey > 128).astype(np.uint8))
        boxes = stats[1:, :4].astype(float)
        if regions is not None:
            cx, cy = boxes[:, 0] + boxes[:, 2] / 2, boxes[:, 1] + boxes[:, 3] / 2
            r = np.asarray(regions, float).reshape(-1, 6)
            inside = ((cx[:, None] >= r[:, 0]) & (cx[:, None] < r[:, 2])
                      & (cy[:, None] >= r[:, 1]) & (cy[:, None] < r[:, 3])).any(axis=1)
            boxes = boxes[inside]
        return Detections(boxes, np.ones(len(boxes)))


def render(frame: int, width: int = WIDTH, height: int = HEIGHT) -> np.ndarray:
    image = np.full((height, width, 3), 30, np.uint8)
    for x, y, w, h in PEOPLE.astype(int).tolist():
        x, y = int(x + VELOCITY[0] * frame), int(y + VELOCITY[1] * frame)
        if x + w <= width and y + h <= height:
            image[y:y + h, x:x + w] = 220
    return image


class Camera(Node):
    """Publishes images, camera_info and gaze states; keeps what the mot_planner publishes."""

    def __init__(self, context: Context) -> None:
        super().__init__('fake_camera', context=context, start_parameter_services=False)
        self.tracks: list[Any] = []
        self.attention: list[Any] = []
        self.overlays: list[Any] = []
        self.gaze: list[Any] = []
        self.image_pub = self.create_publisher(Image, mot_node.IMAGE_TOPIC, qos_profile_sensor_data)
        self.info_pub = self.create_publisher(CameraInfo, mot_node.CAMERA_INFO_TOPIC,
                                              qos_profile_sensor_data)
        self.gaze_pub = self.create_publisher(GazeState, mot_node.GAZE_STATE_TOPIC, 10)
        self.create_subscription(TrackArray, mot_node.TRACKS_TOPIC, self.tracks.append, 10)
        self.create_subscription(AttentionRegions, mot_node.ATTENTION_TOPIC,
                                 self.attention.append, 10)
        self.create_subscription(Image, mot_node.OVERLAY_TOPIC, self.overlays.append,
                                 qos_profile_sensor_data)
        self.create_subscription(GazeCommand, mot_node.GAZE_COMMAND_TOPIC, self.gaze.append, 10)


@pytest.fixture
def graph(context, monkeypatch):
    monkeypatch.setattr(mot_node, 'DETECTOR_FACTORY', lambda params: BlobDetector())
    camera = Camera(context)
    mot = mot_node.MotPlannerNode(context=context, parameter_overrides=[
        Parameter('k_max', value=K_MAX), Parameter('s_max', value=0.3),
        Parameter('full_frame_period', value=5), Parameter('gaze_rate_hz', value=30.0)])
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(camera)
    executor.add_node(mot)
    assert wait_until(lambda: camera.image_pub.get_subscription_count() > 0
                      and camera.info_pub.get_subscription_count() > 0
                      and camera.gaze_pub.get_subscription_count() > 0
                      and mot._tracks_pub.get_subscription_count() > 0
                      and mot._attention_pub.get_subscription_count() > 0
                      and mot._gaze_pub.get_subscription_count() > 0, TIMEOUT, spin=executor)
    try:
        yield camera, mot, executor
    finally:
        executor.remove_node(camera)
        executor.remove_node(mot)
        mot.destroy_node()
        camera.destroy_node()


def _image(array: np.ndarray, stamp_frame: int, encoding: str = 'rgb8') -> Any:
    msg = numpy_to_image(array, encoding)
    msg.header.frame_id = FRAME
    msg.header.stamp.sec = 100 + stamp_frame // 30
    msg.header.stamp.nanosec = int((stamp_frame % 30) * 1e9 / 30)
    return msg


def _feed(camera: Camera, mot: Any, executor: Any, msg: Any) -> bool:
    """Publish msg again every 0.2 s (sensor data QoS is best effort) until the node used it."""
    done = mot.frames_processed + 1
    for _ in range(int(TIMEOUT / 0.2)):
        camera.image_pub.publish(msg)
        if wait_until(lambda: mot.frames_processed >= done, 0.2, spin=executor):
            return True
    return False


def _camera_info() -> Any:
    info = CameraInfo(width=WIDTH, height=HEIGHT)
    info.header.frame_id = FRAME
    info.k = [200.0, 0.0, WIDTH / 2, 0.0, 200.0, HEIGHT / 2, 0.0, 0.0, 1.0]
    return info


def _check_attention(msg: Any, s_max: float) -> None:
    assert len(msg.regions) == len(msg.track_ids) <= msg.k_max == K_MAX
    assert msg.planning_time_ms >= 0.0
    if list(msg.track_ids) == [0]:                   # a full-frame detection
        assert (msg.regions[0].width, msg.regions[0].height) == (WIDTH, HEIGHT)
    else:
        assert 0.0 <= msg.budget_fraction <= s_max + 1e-9


def test_tracks_attention_overlay_and_gaze(graph) -> None:
    camera, mot, executor = graph
    camera.info_pub.publish(_camera_info())
    assert wait_until(lambda: mot._k is not None, TIMEOUT, spin=executor)
    for frame in range(12):
        assert _feed(camera, mot, executor, _image(render(frame), frame))
    assert wait_until(lambda: len(camera.tracks) >= 12 and len(camera.attention) >= 12,
                      TIMEOUT, spin=executor)

    for msg in camera.attention:
        _check_attention(msg, 0.3)
    planned = [m for m in camera.attention if list(m.track_ids) != [0]]
    assert planned and any(len(m.regions) == K_MAX for m in planned)   # the planner chose

    last = camera.tracks[-1]
    assert last.header.frame_id == FRAME
    assert len(last.tracks) == len(PEOPLE)
    assert len({t.id for t in last.tracks}) == len(PEOPLE)
    assert {t.id for t in camera.tracks[0].tracks} == {t.id for t in last.tracks}  # identities kept
    truth = PEOPLE[:, :2] + PEOPLE[:, 2:] / 2 + 11 * VELOCITY
    for t in last.tracks:
        assert t.label == 'person' and len(t.covariance) == 36 and t.age == 11
        assert np.min(np.hypot(truth[:, 0] - t.center_u, truth[:, 1] - t.center_v)) < 8.0
        assert t.scale == pytest.approx(t.height / 64.0, rel=0.05)
        assert np.all(np.isfinite(t.covariance))
    assert sum(t.attended for t in last.tracks) <= K_MAX
    # velocities in px/s (30 frames/s stamps): the people move 1 px/frame to the right
    assert np.mean([t.velocity_u for t in last.tracks]) == pytest.approx(30.0, abs=12.0)

    assert wait_until(lambda: camera.overlays, TIMEOUT, spin=executor)
    overlay = image_to_numpy(camera.overlays[-1])
    assert camera.overlays[-1].encoding == 'rgb8' and overlay.shape == (HEIGHT, WIDTH, 3)
    assert ((overlay == (0, 255, 0)).all(axis=2)).any()                 # a green track box

    assert wait_until(lambda: camera.gaze, TIMEOUT, spin=executor)
    cmd = camera.gaze[-1]
    assert cmd.source == 'mot_planner' and cmd.priority == 10
    assert cmd.motion == GazeCommand.MOTION_PURSUIT
    assert cmd.mode == GazeCommand.MODE_FIXATION_POINT and cmd.header.frame_id == FRAME
    p = np.array([cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z])
    assert np.linalg.norm(p) == pytest.approx(3.0) and p[2] > 0

    # during a saccade no gaze commands
    camera.gaze_pub.publish(GazeState(in_saccade=True))
    assert wait_until(lambda: mot._in_saccade, TIMEOUT, spin=executor)
    sent = mot.gaze_commands
    for frame in range(12, 15):
        assert _feed(camera, mot, executor, _image(render(frame), frame))
    assert mot.gaze_commands == sent


def test_bad_frames_size_change_and_parameters(graph, capsys) -> None:
    camera, mot, executor = graph
    for frame in range(3):
        assert _feed(camera, mot, executor, _image(render(frame), frame))
    assert wait_until(lambda: camera.tracks and len(camera.tracks[-1].tracks) == len(PEOPLE),
                      TIMEOUT, spin=executor)

    # a mono8 frame is dropped with a log line; the tracks are untouched
    ids = set(mot._tracker.tracks.ids.tolist())
    mono = _image(np.full((HEIGHT, WIDTH), 100, np.uint8), 3, 'mono8')
    for _ in range(int(TIMEOUT / 0.2)):
        camera.image_pub.publish(mono)
        if wait_until(lambda: mot.frames_dropped > 0, 0.2, spin=executor):
            break
    assert mot.frames_dropped > 0 and "'mono8'" in capsys.readouterr().err
    assert set(mot._tracker.tracks.ids.tolist()) == ids

    # a truncated frame too
    bad = _image(render(3), 3)
    bad.height = HEIGHT + 10
    dropped = mot.frames_dropped
    camera.image_pub.publish(bad)
    assert wait_until(lambda: mot.frames_dropped > dropped, TIMEOUT, spin=executor)

    # a frame size change: warning, tracker reset, bootstrap on the new size, node keeps going
    n_tracks = len(camera.tracks)
    for frame in range(4, 7):
        assert _feed(camera, mot, executor, _image(render(frame, 400, 300), frame))
    assert mot.resets == 1 and 'frame size changed' in capsys.readouterr().err
    assert mot._tracker.image_size == (400, 300)
    assert wait_until(lambda: len(camera.tracks) >= n_tracks + 3, TIMEOUT, spin=executor)
    assert len(camera.tracks[-1].tracks) == len(PEOPLE)
    assert all(len(m.regions) <= K_MAX for m in camera.attention)

    # parameters at run time: the planner's keep the tracks, bad values are refused
    ids = set(mot._tracker.tracks.ids.tolist())
    assert mot.set_parameters([Parameter('k_max', value=1)])[0].successful
    assert mot._tracker.planner.cfg.k_max == 1
    before = len(camera.attention)
    for frame in range(7, 10):
        assert _feed(camera, mot, executor, _image(render(frame, 400, 300), frame))
    assert wait_until(lambda: len(camera.attention) >= before + 3, TIMEOUT, spin=executor)
    assert all(len(m.regions) <= 1 and m.k_max == 1 for m in camera.attention[before:])
    assert set(mot._tracker.tracks.ids.tolist()) == ids
    assert not mot.set_parameters([Parameter('s_max', value=1.5)])[0].successful
    assert not mot.set_parameters([Parameter('win_stride', value=12)])[0].successful
