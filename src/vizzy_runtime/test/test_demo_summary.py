"""The demo's one-page summary (vizzy_runtime.demo_summary), drawn from tiny hand-made bags."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.image import imread

from vizzy_runtime import msgs
from vizzy_runtime.bag import BagWriter
from vizzy_runtime.convert import array_to_pointcloud2, numpy_to_image
from vizzy_runtime.demo_summary import DPI, FIGSIZE, _TfHistory, cylinder_footprint, summarize_bag

S = 1_000_000_000
PANELS = {'left', 'foveated', 'points', 'cylinders', 'tracks', 'gaze'}
W, H = 64, 48
K = [50.0, 0.0, 31.5, 0.0, 50.0, 23.5, 0.0, 0.0, 1.0]


def M(typename: str, **kwargs: Any) -> Any:
    return msgs.get_message(typename)(**kwargs)


def header(t_ns: int, frame: str) -> Any:
    return M('std_msgs/msg/Header', frame_id=frame,
             stamp=M('builtin_interfaces/msg/Time', sec=t_ns // S, nanosec=t_ns % S))


def transform(parent: str, child: str, t_ns: int, xyz: tuple, quat: tuple) -> Any:
    return M('geometry_msgs/msg/TransformStamped', header=header(t_ns, parent),
             child_frame_id=child,
             transform=M('geometry_msgs/msg/Transform',
                         translation=M('geometry_msgs/msg/Vector3', x=xyz[0], y=xyz[1], z=xyz[2]),
                         rotation=M('geometry_msgs/msg/Quaternion', x=quat[0], y=quat[1],
                                    z=quat[2], w=quat[3])))


# base_link -> optical frame of a camera looking along base_link's +x (z forward, x right, y down).
OPTICAL = (-0.5, 0.5, -0.5, 0.5)
IDENTITY = (0.0, 0.0, 0.0, 1.0)


def image(t_ns: int, value: int) -> Any:
    img = np.full((H, W, 3), value, np.uint8)
    img[H // 2:, :, 0] = 200
    return numpy_to_image(img, 'rgb8', header(t_ns, 'left_camera_optical_frame'))


def cloud(t_ns: int, frame: str, xyz: np.ndarray, information: bool) -> Any:
    names = ['x', 'y', 'z'] + (['information'] if information else [])
    arr = np.zeros(len(xyz), dtype=[(n, np.float32) for n in names])
    arr['x'], arr['y'], arr['z'] = xyz.T
    if information:
        arr['information'] = np.linspace(0, 10, len(xyz))
    return array_to_pointcloud2(arr, header(t_ns, frame))


def write_bag(path: Path, samples: list[tuple[str, str, int, Any]]) -> None:
    with BagWriter(path) as writer:
        for topic, typename, _, _ in samples:
            writer.add_topic(topic, typename)
        for topic, typename, t_ns, msg in sorted(samples, key=lambda s: s[2]):
            writer.write(topic, msgs.serialize(msg, typename), t_ns)


def perception_samples() -> list[tuple[str, str, int, Any]]:
    """A short run: two frames, gaze, foveation, stereo, SES, tracks; no cylinders."""
    out: list[tuple[str, str, int, Any]] = [
        ('/tf_static', 'tf2_msgs/msg/TFMessage', 1, M('tf2_msgs/msg/TFMessage', transforms=[
            transform('base_link', 'left_camera_optical_frame', 0, (0, 0, 1), OPTICAL),
            transform('base_link', 'ego', 0, (0, 0, 1), IDENTITY)]))]
    for i, t in enumerate((1 * S, 2 * S)):
        out += [('/vizzy/left/image_raw', 'sensor_msgs/msg/Image', t, image(t, 60 + 60 * i)),
                ('/vizzy/left/camera_info', 'sensor_msgs/msg/CameraInfo', t,
                 M('sensor_msgs/msg/CameraInfo', header=header(t, 'left_camera_optical_frame'),
                   width=W, height=H, k=np.array(K))),
                ('/foveation/image', 'sensor_msgs/msg/Image', t + 1000, image(t, 30))]
    for i in range(6):  # the head looks straight ahead, then a little left, then saccades back
        t = S + i * S // 5
        out.append(('/gaze/state', 'active_vision_msgs/msg/GazeState', t + 5,
                    M('active_vision_msgs/msg/GazeState', header=header(t, 'base_link'),
                      fixation_point=M('geometry_msgs/msg/Point', x=2.0, y=0.1 * (i // 2), z=1.0),
                      in_saccade=i == 3, active_source='foveation' if i else '',
                      version=0.05 * i, vergence=0.1, tilt=0.2)))
    box = M('sensor_msgs/msg/RegionOfInterest', x_offset=10, y_offset=12, width=20, height=15)
    out.append(('/foveation/detections', 'active_vision_msgs/msg/FoveatedDetectionArray',
                2 * S + 50,
                M('active_vision_msgs/msg/FoveatedDetectionArray',
                  header=header(2 * S, 'left_camera_optical_frame'), fixation_u=31.5,
                  fixation_v=23.5,
                  detections=[M('active_vision_msgs/msg/FoveatedDetection', label='can', score=0.8,
                                box=box, pass_index=1)])))
    pts = np.array([[0.0, 0.0, 2.0], [0.2, 0.1, 2.5], [-0.3, 0.0, 1.5]])
    out.append(('/stereo/points', 'sensor_msgs/msg/PointCloud2', 2 * S + 60,
                cloud(2 * S, 'left_camera_optical_frame', pts, information=True)))
    out.append(('/ses/cells', 'sensor_msgs/msg/PointCloud2', 2 * S + 70,
                cloud(2 * S, 'ego', np.array([[1.0, 0.0, 0.0], [1.5, 0.5, 0.2]]),
                      information=True)))
    for i in range(4):
        t = S + i * S // 4
        out.append(('/mot/tracks', 'active_vision_msgs/msg/TrackArray', t + 80,
                    M('active_vision_msgs/msg/TrackArray',
                      header=header(t, 'left_camera_optical_frame'),
                      tracks=[M('active_vision_msgs/msg/Track', id=tid, label='person',
                                center_u=10.0 + 5 * i + 20 * tid, center_v=20.0, width=8.0,
                                height=16.0)
                              for tid in (1, 2)])))
    return out


def check_png(path: Path) -> None:
    assert path.is_file() and path.stat().st_size > 10_000
    pixels = imread(str(path))
    assert pixels.shape[:2] == (round(FIGSIZE[1] * DPI), round(FIGSIZE[0] * DPI))


def test_panels_with_data_and_an_empty_one_said_in_words(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_bag(bag, perception_samples())
    result = summarize_bag(bag, tmp_path / 'out' / 'summary.png')
    check_png(tmp_path / 'out' / 'summary.png')
    assert result['path'] == str(tmp_path / 'out' / 'summary.png')
    assert set(result['panels']) == PANELS
    assert set(result['with_data']) == {'left', 'foveated', 'points', 'tracks', 'gaze'}
    assert result['empty'] == ['cylinders']
    note = result['panels']['cylinders'].note
    assert 'no /cylinders in the bag' in note
    assert 'no scene ground truth in the bag' in note
    assert result['errors'] == []
    # Every fixation is in front of the camera and inside the 64x48 view, and the detections'
    # frame is in the bag: nothing to report.
    assert result['panels']['left'].note == ''


def test_without_tf_the_3d_panels_say_so(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_bag(bag, [s for s in perception_samples() if s[0] != '/tf_static'])
    result = summarize_bag(bag, tmp_path / 'summary.png')
    check_png(tmp_path / 'summary.png')
    assert set(result['with_data']) == {'left', 'foveated', 'tracks', 'gaze'}
    assert 'fixation track not drawn' in result['panels']['left'].note
    note = result['panels']['points'].note
    assert '/stereo/points not placed' in note and '/ses/cells not placed' in note


def test_a_bag_without_any_of_the_topics_gives_six_empty_panels(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_bag(bag, [('/clock', 'rosgraph_msgs/msg/Clock', S, M('rosgraph_msgs/msg/Clock'))])
    result = summarize_bag(bag, tmp_path / 'summary.png')
    check_png(tmp_path / 'summary.png')
    assert result['with_data'] == []
    assert set(result['empty']) == PANELS
    notes = {k: p.note for k, p in result['panels'].items()}
    assert notes['left'] == 'no /vizzy/left/image_raw in the bag'
    assert notes['foveated'] == 'no /foveation/image in the bag'
    assert notes['tracks'] == 'no /mot/tracks in the bag'
    assert notes['gaze'] == 'no /gaze/state in the bag'
    assert 'no /stereo/points in the bag' in notes['points']
    assert 'no /ses/cells in the bag' in notes['points']
    assert 'no /cylinders in the bag' in notes['cylinders']


def test_cylinders_against_ground_truth(tmp_path: Path) -> None:
    """One true upright can at (1, 0.2) in base_link; the detector reports it, in the camera's
    optical frame, plus a cylinder where there is none; empty messages do not count."""
    def cylinder(center_base: tuple, radius: float) -> Any:
        x, y, z = center_base   # base_link -> optical: (x, y, z) -> (-y, -(z - 1), x)
        return M('active_vision_msgs/msg/Cylinder', label='cylinder', radius=radius, height=0.12,
                 center=M('geometry_msgs/msg/Point', x=-y, y=-(z - 1.0), z=x),
                 axis=M('geometry_msgs/msg/Vector3', x=0.0, y=-1.0, z=0.0), confidence=0.9)

    can = M('visualization_msgs/msg/Marker', header=header(0, 'base_link'), ns='objects', id=1,
            type=3, action=0, text='can_0',
            pose=M('geometry_msgs/msg/Pose',
                   position=M('geometry_msgs/msg/Point', x=1.0, y=0.2, z=0.3),
                   orientation=M('geometry_msgs/msg/Quaternion', w=1.0)),
            scale=M('geometry_msgs/msg/Vector3', x=0.066, y=0.066, z=0.12))
    samples = perception_samples() + [
        ('/sim/ground_truth/objects', 'visualization_msgs/msg/MarkerArray', S,
         M('visualization_msgs/msg/MarkerArray', markers=[can])),
        ('/cylinders', 'active_vision_msgs/msg/CylinderArray', S + 10,
         M('active_vision_msgs/msg/CylinderArray', header=header(S, 'left_camera_optical_frame'),
           cylinders=[cylinder((1.01, 0.19, 0.3), 0.03), cylinder((1.5, -0.4, 0.3), 0.02)])),
        ('/cylinders', 'active_vision_msgs/msg/CylinderArray', S + 20,
         M('active_vision_msgs/msg/CylinderArray', header=header(S, 'left_camera_optical_frame')))]
    bag = tmp_path / 'bag'
    write_bag(bag, samples)
    result = summarize_bag(bag, tmp_path / 'summary.png')
    check_png(tmp_path / 'summary.png')
    assert set(result['with_data']) == PANELS
    note = result['panels']['cylinders'].note
    assert 'true cylinders found at least once: 1/1' in note
    assert 'last message: 1 of 2 not at a true cylinder' in note


def test_cylinder_footprint_is_a_circle_when_upright_and_a_strip_when_lying() -> None:
    upright = cylinder_footprint(np.array([1.0, 2.0, 0.5]), np.array([0.0, 0.0, 1.0]), 0.05, 0.2)
    assert np.allclose(np.hypot(upright[:, 0] - 1.0, upright[:, 1] - 2.0), 0.05)
    lying = cylinder_footprint(np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), 0.05, 0.2)
    assert lying[:, 0].min() == pytest.approx(-0.1) and lying[:, 0].max() == pytest.approx(0.1)
    assert lying[:, 1].min() == pytest.approx(-0.05) and lying[:, 1].max() == pytest.approx(0.05)


def test_tf_history_uses_the_transform_at_or_before_the_stamp() -> None:
    tf = _TfHistory()
    tf.add([transform('base_link', 'head', 0, (0, 0, 1), IDENTITY)], static=True)
    for k in range(3):
        tf.add([transform('head', 'eye', k * S, (k, 0, 0), IDENTITY)], static=False)
    at = lambda t: tf.transform(np.zeros((1, 3)), 'base_link', 'eye', t)[0]  # noqa: E731
    assert np.allclose(at(S + S // 2), (1, 0, 1))
    assert np.allclose(at(2 * S), (2, 0, 1))
    assert np.allclose(at(-5), (0, 0, 1))   # before the first: the first
