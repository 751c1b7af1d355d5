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
from vizzy_runtime.ros import (
    Context,
    Node,
    Parameter,
    message,
    qos_profile_sensor_data,
    qos_profile_system_default,
)
from vizzy_runtime.testing import scaled, spinning, wait_until
from vizzy_runtime.tf import TF_TOPIC

pytestmark = pytest.mark.live  # also run on the real rclpy (scripts/test_ros.sh)

Image = message('sensor_msgs/msg/Image')
CameraInfo = message('sensor_msgs/msg/CameraInfo')
TrackArray = message('active_vision_msgs/msg/TrackArray')
AttentionRegions = message('active_vision_msgs/msg/AttentionRegions')
GazeCommand = message('active_vision_msgs/msg/GazeCommand')
GazeState = message('active_vision_msgs/msg/GazeState')

TIMEOUT = scaled(20.0)
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
    """Publishes images, camera_info (as a driver: the default reliable QoS) and gaze states;
    keeps what the mot_planner publishes. On the node's resolved topic names."""

    def __init__(self, context: Context, mot: Any) -> None:
        super().__init__('fake_camera', context=context, start_parameter_services=False)
        self.tracks: list[Any] = []
        self.attention: list[Any] = []
        self.overlays: list[Any] = []
        self.gaze: list[Any] = []
        self.tf_topic = mot.resolve_topic_name(TF_TOPIC)
        self.image_pub = self.create_publisher(Image, mot._image_sub.topic_name,
                                               qos_profile_system_default)
        self.info_pub = self.create_publisher(CameraInfo, mot._info_sub.topic_name,
                                              qos_profile_system_default)
        self.gaze_pub = self.create_publisher(GazeState, mot._gaze_state_sub.topic_name, 10)
        self.create_subscription(TrackArray, mot._tracks_pub.topic_name, self.tracks.append, 10)
        self.create_subscription(AttentionRegions, mot._attention_pub.topic_name,
                                 self.attention.append, 10)
        self.create_subscription(Image, mot._overlay_pub.topic_name, self.overlays.append,
                                 qos_profile_sensor_data)
        self.create_subscription(GazeCommand, mot._gaze_pub.topic_name, self.gaze.append, 10)


@pytest.fixture
def graph(context, monkeypatch):
    monkeypatch.setattr(mot_node, 'DETECTOR_FACTORY', lambda params: BlobDetector())
    mot = mot_node.MotPlannerNode(context=context, parameter_overrides=[
        Parameter('k_max', value=K_MAX), Parameter('s_max', value=0.3),
        Parameter('full_frame_period', value=5), Parameter('gaze_rate_hz', value=30.0)])
    camera = Camera(context, mot)
    with spinning(context, [camera, mot],
                  lambda: camera.image_pub.get_subscription_count() > 0
                  and camera.info_pub.get_subscription_count() > 0
                  and camera.gaze_pub.get_subscription_count() > 0
                  and mot._tracks_pub.get_subscription_count() > 0
                  and mot._attention_pub.get_subscription_count() > 0
                  and mot._gaze_pub.get_subscription_count() > 0, TIMEOUT) as executor:
        yield camera, mot, executor


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
    # a full frame (births, paid from the budget when the savings allow) attends everyone
    if list(camera.attention[-1].track_ids) == [0]:
        assert sum(t.attended for t in last.tracks) == len(PEOPLE)
    else:
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


def test_bad_frames_size_change_and_parameters(graph, capfd) -> None:
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
    assert mot.frames_dropped > 0 and "'mono8'" in capfd.readouterr().err
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
    assert mot.resets == 1 and 'frame size changed' in capfd.readouterr().err
    assert mot._tracker.image_size == (400, 300)
    assert wait_until(lambda: len(camera.tracks) >= n_tracks + 3, TIMEOUT, spin=executor)
    assert len(camera.tracks[-1].tracks) == len(PEOPLE)
    assert all(len(m.regions) <= K_MAX for m in camera.attention)

    # parameters at run time: the planner's keep the tracks, bad values are refused
    ids = set(mot._tracker.tracks.ids.tolist())
    assert mot._tracker.planner.cfg.depth == 1                    # the deployed horizon
    assert mot.set_parameters([Parameter('k_max', value=1), Parameter('horizon', value=3)])[0]\
        .successful
    assert (mot._tracker.planner.cfg.k_max, mot._tracker.planner.cfg.depth) == (1, 3)
    def after_change() -> list[Any]:  # by stamp: a message of frame 6 may still be in flight
        first = _image(render(7, 400, 300), 7).header.stamp
        return [m for m in camera.attention
                if (m.header.stamp.sec, m.header.stamp.nanosec) >= (first.sec, first.nanosec)]

    for frame in range(7, 10):
        assert _feed(camera, mot, executor, _image(render(frame, 400, 300), frame))
    assert wait_until(lambda: len(after_change()) >= 3, TIMEOUT, spin=executor)
    assert all(len(m.regions) <= 1 and m.k_max == 1 for m in after_change())
    assert set(mot._tracker.tracks.ids.tolist()) == ids
    assert not mot.set_parameters([Parameter('s_max', value=1.5)])[0].successful
    assert not mot.set_parameters([Parameter('horizon', value=9)])[0].successful
    # the track births and reporting keep the tracks as well (-1: report a track while it lives)
    assert all(r.successful for r in mot.set_parameters([
        Parameter('birth_share', value=0.4), Parameter('report_misses', value=-1),
        Parameter('keep_lost', value=3), Parameter('birth_score', value=0.5),
        Parameter('occluded_share', value=0.0)]))
    cfg = mot._tracker.cfg
    assert set(mot._tracker.tracks.ids.tolist()) == ids
    assert (cfg.birth_share, cfg.report_misses, cfg.keep_lost, cfg.birth_score,
            cfg.occluded_share) == (0.4, None, 3, 0.5, None)     # 0: no occlusion reasoning
    assert not mot.set_parameters([Parameter('birth_share', value=0.99)])[0].successful
    assert not mot.set_parameters([Parameter('win_stride', value=12)])[0].successful


TFMessage = message('tf2_msgs/msg/TFMessage')
TransformStamped = message('geometry_msgs/msg/TransformStamped')
# The optical frame's orientation in base_link at rest (z forward = base x, x right = -y).
OPTICAL_IN_BASE = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def _tf(stamp: Any, rotation: np.ndarray) -> Any:
    from scipy.spatial.transform import Rotation
    t = TransformStamped(child_frame_id=FRAME)
    t.header.frame_id, t.header.stamp = 'base_link', stamp
    q = Rotation.from_matrix(rotation).as_quat()          # x, y, z, w
    r = t.transform.rotation
    r.x, r.y, r.z, r.w = (float(v) for v in q)
    t.transform.translation.z = 0.5
    return TFMessage(transforms=[t])


def _blobs(centres: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    image = np.full((HEIGHT, WIDTH, 3), 30, np.uint8)
    for (u, v), (w, h) in zip(centres, sizes, strict=True):
        x0, y0 = int(round(u - w / 2)), int(round(v - h / 2))
        image[max(y0, 0):y0 + int(h), max(x0, 0):x0 + int(w)] = 220
    return image


@pytest.mark.parametrize('ego_motion', [True, False])
def test_ego_motion_from_tf_keeps_tracks_through_a_head_turn(graph, ego_motion) -> None:
    """The head pans 13 deg left between two images (the people jump ~46 px right): with
    the rotation from /tf the tracks follow; without it they are lost."""
    from mot_planner_node.core.egomotion import rotation_homography, warp_points
    camera, mot, executor = graph
    tf_pub = camera.create_publisher(TFMessage, camera.tf_topic, 10)
    # the blobs are not people standing on a floor (test_gaze_only_on_people_on_the_floor)
    assert all(r.successful for r in mot.set_parameters([
        Parameter('ego_motion', value=ego_motion), Parameter('full_frame_period', value=1000),
        Parameter('person_check', value=False)]))
    assert wait_until(lambda: tf_pub.get_subscription_count() > 0, TIMEOUT, spin=executor)
    camera.info_pub.publish(_camera_info())
    assert wait_until(lambda: mot._k is not None, TIMEOUT, spin=executor)
    centres = np.array([[76.0, 92.0], [160.0, 140.0], [236.0, 82.0]])
    sizes = np.array([[32.0, 64.0], [40.0, 80.0], [32.0, 64.0]])
    pan = np.radians(13.0)
    turned = np.array([[np.cos(pan), -np.sin(pan), 0], [np.sin(pan), np.cos(pan), 0],
                       [0, 0, 1]]) @ OPTICAL_IN_BASE
    h = rotation_homography(np.reshape(_camera_info().k, (3, 3)),
                            turned.T @ OPTICAL_IN_BASE)
    moved, _ = warp_points(h, centres)
    assert np.all(moved[:, 0] - centres[:, 0] > 40)
    for frame in range(14):
        rotation, seen = (turned, moved) if frame >= 7 else (OPTICAL_IN_BASE, centres)
        msg = _image(_blobs(seen, sizes), frame)
        tf_pub.publish(_tf(msg.header.stamp, rotation))
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        assert wait_until(lambda stamp=stamp: mot._poses.newest(FRAME) is None
                          or mot._poses.newest(FRAME) >= stamp - 1e-6, TIMEOUT, spin=executor)
        assert _feed(camera, mot, executor, msg)
    assert wait_until(lambda: len(camera.tracks) >= 14, TIMEOUT, spin=executor)
    first, last = camera.tracks[0], camera.tracks[-1]
    assert len(first.tracks) == 3
    # original tracks that sit on a person after the turn
    kept = [t for t in last.tracks if t.id in {f.id for f in first.tracks}
            and np.min(np.hypot(*(moved - [t.center_u, t.center_v]).T)) < 6.0]
    if ego_motion:
        assert mot.frames_compensated >= 12
        assert mot.last_ego_rotation_deg == pytest.approx(0.0, abs=1e-6)   # since frame 7
        assert len(kept) == len(last.tracks) == 3
        # gaze goes out in base_link, through the camera pose of the image it came from
        assert wait_until(lambda: camera.gaze, TIMEOUT, spin=executor)
        cmd = camera.gaze[-1]
        assert cmd.header.frame_id == 'base_link'
        p = np.array([cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z])
        cam = turned.T @ (p - [0.0, 0.0, 0.5])
        uv = np.reshape(_camera_info().k, (3, 3)) @ cam
        assert uv[0] / uv[2] == pytest.approx(moved[:, 0].mean(), abs=6.0)
    else:
        assert mot.frames_compensated == 0
        assert len(kept) < 3


def test_gaze_only_on_established_tracks(graph) -> None:
    """A one-frame false positive becomes a track at the bootstrap but never steers the head;
    a steady person does once it has gaze_min_hits detections and gaze_min_age frames."""
    camera, mot, executor = graph
    camera.info_pub.publish(_camera_info())
    assert wait_until(lambda: mot._k is not None, TIMEOUT, spin=executor)
    person = np.array([[60.0, 120.0]])
    ghost = np.array([[270.0, 120.0]])
    size = np.array([[32.0, 64.0]])
    for frame in range(5):                       # gaze_min_age = 5: nobody may steer yet
        seen = np.concatenate([person, ghost]) if frame == 0 else person
        assert _feed(camera, mot, executor,
                     _image(_blobs(seen, np.repeat(size, len(seen), 0)), frame))
        assert mot.gaze_commands == 0
    assert camera.tracks and len(camera.tracks[0].tracks) == 2   # the ghost was a track
    for frame in range(5, 9):
        assert _feed(camera, mot, executor, _image(_blobs(person, size), frame))
    assert wait_until(lambda: camera.gaze, TIMEOUT, spin=executor)
    for cmd in camera.gaze:                      # towards the person (left), never the mean
        assert cmd.fixation_point.x < 0
    p = camera.gaze[-1].fixation_point
    assert p.x / p.z == pytest.approx((60.0 - WIDTH / 2) / 200.0, abs=0.03)
    assert not mot.set_parameters([Parameter('gaze_min_hits', value=0)])[0].successful
    assert not mot.set_parameters([Parameter('world_frame', value='')])[0].successful


def test_gaze_only_on_people_on_the_floor(graph) -> None:
    """With the camera 1.036 m above the floor (0.5 m above base_link, floor_z_m = -0.536),
    level: a blob whose bottom meets the floor 4 m away at a 1.7 m person's size steers the
    head; a larger one just below the horizon (a 'person' 8 m tall, 21 m away) is tracked,
    labelled implausible and drawn grey, and never steers."""
    camera, mot, executor = graph
    tf_pub = camera.create_publisher(TFMessage, camera.tf_topic, 10)
    assert wait_until(lambda: tf_pub.get_subscription_count() > 0, TIMEOUT, spin=executor)
    camera.info_pub.publish(_camera_info())
    assert wait_until(lambda: mot._k is not None, TIMEOUT, spin=executor)
    # person: feet at v = 120 + 200 * 1.0358 / 4 = 171.8, head at 120 - 200 * 0.6642 / 4 = 86.8
    person_c, person_s = np.array([[60.0, 129.3]]), np.array([[34.0, 85.0]])
    ghost_c, ghost_s = np.array([[250.0, 90.0]]), np.array([[40.0, 80.0]])
    image = _blobs(np.concatenate([person_c, ghost_c]), np.concatenate([person_s, ghost_s]))
    for frame in range(10):
        msg = _image(image, frame)
        tf_pub.publish(_tf(msg.header.stamp, OPTICAL_IN_BASE))
        assert wait_until(lambda: mot._tf.can_transform('base_link', FRAME), TIMEOUT,
                          spin=executor)
        assert _feed(camera, mot, executor, msg)
    assert wait_until(lambda: camera.gaze and len(camera.tracks) >= 10, TIMEOUT, spin=executor)
    heights = sorted(mot.last_implied_heights.values())
    assert heights[0] == pytest.approx(1.7, abs=0.1) and heights[1] > 5.0
    tracks = sorted(camera.tracks[-1].tracks, key=lambda t: t.center_u)
    assert [t.label for t in tracks] == ['person', 'person_implausible']
    assert tracks[0].center_u == pytest.approx(60.0, abs=3.0)
    for cmd in camera.gaze:     # towards the person: 100 px left of centre at fx = 200
        p = cmd.fixation_point
        assert cmd.header.frame_id == 'base_link' and p.y / p.x == pytest.approx(0.5, abs=0.05)
    overlay = image_to_numpy(camera.overlays[-1])
    assert ((overlay == (150, 150, 150)).all(axis=2)).any()             # a grey track box
    assert not mot.set_parameters([Parameter('person_height_m', value=[2.0, 1.0])])[0].successful
    assert not mot.set_parameters([Parameter('person_check_frames', value=0)])[0].successful


def test_max_rate_tracks_every_other_frame_of_their_stamps(graph) -> None:
    camera, mot, executor = graph
    assert mot.set_parameters([Parameter('max_rate_hz', value=15.0)])[0].successful
    processed, skipped = mot.frames_processed, mot.frames_skipped
    for frame in range(8):                                 # stamps 30 frames a second
        seen = mot.frames_processed + mot.frames_skipped
        msg = _image(render(frame), frame)
        for _ in range(int(TIMEOUT / 0.2)):
            camera.image_pub.publish(msg)
            if wait_until(lambda seen=seen: mot.frames_processed + mot.frames_skipped > seen, 0.2,
                          spin=executor):
                break
    assert mot.frames_processed - processed == 4           # frames 0, 2, 4, 6
    assert mot.frames_skipped - skipped >= 4                # (a copy sent again is skipped too)
    assert wait_until(lambda: len(camera.tracks) >= 4, TIMEOUT, spin=executor)
    frames = [round(m.header.stamp.nanosec * 30 / 1e9) for m in camera.tracks[-4:]]
    assert frames == [0, 2, 4, 6]
