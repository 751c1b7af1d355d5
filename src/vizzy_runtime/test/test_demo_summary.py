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
from vizzy_runtime.demo_summary import (
    DPI,
    FIGSIZE,
    _TfHistory,
    cylinder_footprint,
    object_class,
    summarize_bag,
)

S = 1_000_000_000
PANELS = {'left', 'object_map', 'recall', 'foveated', 'points', 'cylinders', 'tracks', 'gaze'}
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
    assert result['empty'] == ['object_map', 'recall', 'cylinders']
    note = result['panels']['cylinders'].note
    assert 'no /cylinders in the bag' in note
    assert 'no scene ground truth in the bag' in note
    assert result['panels']['recall'].note == 'no /objects/map in the bag'
    assert result['panels']['object_map'].note == (
        'no /objects/map in the bag; no scene ground truth in the bag (/sim/ground_truth/objects)')
    assert result['errors'] == []
    # Every fixation is in front of the camera and inside the 64x48 view, and the detections'
    # frame is in the bag: nothing to report. Without ground truth the detections cannot be
    # checked: the frame is the last detections'.
    assert result['panels']['left'].note == ''
    assert result['panels']['left'].facts == {'rule': 'last detections', 'stamp_ns': 2 * S,
                                              'correct': 0, 'wrong': 0, 'score_sum': 0.0,
                                              'messages': 1}


def test_without_tf_the_3d_panels_say_so(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_bag(bag, [s for s in perception_samples() if s[0] != '/tf_static'])
    result = summarize_bag(bag, tmp_path / 'summary.png')
    check_png(tmp_path / 'summary.png')
    assert set(result['with_data']) == {'left', 'foveated', 'tracks', 'gaze'}
    assert 'fixation track not drawn' in result['panels']['left'].note
    note = result['panels']['points'].note
    assert '/stereo/points not placed' in note and '/ses/cells not placed' in note


def test_a_bag_without_any_of_the_topics_gives_empty_panels(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_bag(bag, [('/clock', 'rosgraph_msgs/msg/Clock', S, M('rosgraph_msgs/msg/Clock'))])
    result = summarize_bag(bag, tmp_path / 'summary.png')
    check_png(tmp_path / 'summary.png')
    assert result['with_data'] == []
    assert set(result['empty']) == PANELS
    notes = {k: p.note for k, p in result['panels'].items()}
    assert notes['left'] == 'no /vizzy/left/image_raw in the bag'
    assert notes['foveated'] == 'no /foveation/image in the bag'
    assert notes['tracks'] == 'no /mot/tracks in the bag'   # not drawn: said at the page's top
    assert notes['gaze'] == 'no /gaze/state in the bag'
    assert notes['recall'] == 'no /objects/map in the bag'
    assert notes['object_map'].startswith('no /objects/map in the bag')
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
    assert set(result['with_data']) == PANELS - {'object_map', 'recall'}
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


# --- the story: panel 1's frame, the recall curve, the object map against ground truth ---------
# The camera sits at (0, 0, 1) in base_link looking along +x (fx = 50, principal point (31.5,
# 23.5)): a point (x, y, 1) projects to u = 31.5 - 50 y / x, v = 23.5.

def marker(name: str, kind: int, xyz: tuple, scale: tuple, mid: int) -> Any:
    return M('visualization_msgs/msg/Marker', header=header(0, 'base_link'), ns='objects', id=mid,
             type=kind, action=0, text=name,
             pose=M('geometry_msgs/msg/Pose', position=M('geometry_msgs/msg/Point', x=xyz[0],
                                                         y=xyz[1], z=xyz[2]),
                    orientation=M('geometry_msgs/msg/Quaternion', w=1.0)),
             scale=M('geometry_msgs/msg/Vector3', x=scale[0], y=scale[1], z=scale[2]))


# can_0 straight ahead (u 25.9 to 37.1), box_0 to its left (u 9.3 to 22.4), jar_0 behind can_0
# (its box holds the image centre too, but can_0 is nearer), the table (a support: not an object).
TRUTH = M('visualization_msgs/msg/MarkerArray', markers=[
    marker('can_0', 3, (2.0, 0.0, 1.0), (0.4, 0.4, 0.6), 1),
    marker('box_0', 1, (2.0, 0.6, 1.0), (0.4, 0.4, 0.4), 2),
    marker('jar_0', 3, (4.0, 0.0, 1.0), (0.6, 0.6, 0.6), 3),
    marker('table', 1, (2.0, 0.0, 0.6), (1.0, 2.0, 0.05), 4)])
CENTRE, LEFT, NOWHERE = (31.5, 23.5), (16.5, 23.5), (60.0, 5.0)


def detections(t_ns: int, pass_index: int, dets: list[tuple[str, float, tuple]]) -> tuple:
    return ('/foveation/detections', 'active_vision_msgs/msg/FoveatedDetectionArray',
            t_ns + 50 + pass_index,
            M('active_vision_msgs/msg/FoveatedDetectionArray',
              header=header(t_ns, 'left_camera_optical_frame'), fixation_u=31.5, fixation_v=23.5,
              detections=[M('active_vision_msgs/msg/FoveatedDetection', label=label, score=score,
                            fixation_u=uv[0], fixation_v=uv[1], pass_index=pass_index,
                            box=M('sensor_msgs/msg/RegionOfInterest', x_offset=int(uv[0]) - 4,
                                  y_offset=int(uv[1]) - 4, width=8, height=8))
                          for label, score, uv in dets]))


def map_object(oid: str, label: str, xyz: tuple, confirmed: bool, established: bool = True) -> Any:
    return M('active_vision_msgs/msg/MapObject', id=oid, label=label,
             label_share=0.8 if label else 0.0, confirmed=confirmed, established=established,
             position=M('geometry_msgs/msg/Point', x=xyz[0], y=xyz[1], z=xyz[2]),
             size=M('geometry_msgs/msg/Vector3', x=0.2, y=0.2, z=0.3))


def object_map(t_ns: int, objects: list[Any]) -> tuple:
    return ('/objects/map', 'active_vision_msgs/msg/MapObjectArray', t_ns + 90,
            M('active_vision_msgs/msg/MapObjectArray', header=header(t_ns, 'base_link'),
              objects=objects))


# The earlier frame (1 s) has a correct detection (can on can_0, 0.6) and a wrong one (jar: the
# nearest object under its fixation is can_0, not jar_0); the later frame (2 s) has only wrong
# ones, more confident (can on box_0, 0.9; box on nothing).
EARLY = detections(S, 0, [('can', 0.6, CENTRE), ('jar', 0.3, CENTRE)])
LATE = [detections(2 * S, 0, [('can', 0.9, LEFT)]), detections(2 * S, 1, [('box', 0.2, NOWHERE)])]
# The map over time: an unnamed object; a can 7 cm off can_0 (found at 10 cm, not at 5 cm); then
# a can on can_0 (right), a can on box_0 (misnamed), a jar where nothing is (a false object),
# an established unnamed object and a tentative one.
MAPS = [object_map(S // 2, [map_object('u1', '', (2.0, 0.0, 1.0), False)]),
        object_map(S, [map_object('c0', 'can', (2.0, 0.0, 1.07), True)]),
        object_map(2 * S, [map_object('c1', 'can', (2.02, 0.0, 1.0), True),
                           map_object('c2', 'can', (2.0, 0.6, 1.0), True),
                           map_object('c3', 'jar', (3.0, -1.0, 1.0), True),
                           map_object('u1', '', (4.0, 0.0, 1.0), False),
                           map_object('t1', 'box', (1.0, 1.0, 1.0), False, established=False)])]


def story_samples(dets: list[tuple], truth: bool = True) -> list[tuple[str, str, int, Any]]:
    out = [s for s in perception_samples() if s[0] != '/foveation/detections'] + dets + MAPS
    if truth:
        out.append(('/sim/ground_truth/objects', 'visualization_msgs/msg/MarkerArray', S, TRUTH))
    return out


def summarize(tmp_path: Path, samples: list[tuple[str, str, int, Any]]) -> dict[str, Any]:
    bag = tmp_path / 'bag'
    write_bag(bag, samples)
    result = summarize_bag(bag, tmp_path / 'summary.png')
    check_png(tmp_path / 'summary.png')
    assert result['errors'] == []
    return result


def test_panel_1_shows_the_frame_with_the_most_confident_correct_detections(
        tmp_path: Path) -> None:
    result = summarize(tmp_path, story_samples([EARLY, *LATE]))
    left = result['panels']['left']
    assert left.has_data
    assert left.facts == {'rule': 'most confident correct', 'stamp_ns': S, 'correct': 1,
                          'wrong': 1, 'score_sum': pytest.approx(0.6), 'messages': 3}
    # panel 4: what the recogniser saw at that moment, not the last foveated image (2 s)
    assert result['panels']['foveated'].facts == {'frame': "panel 1's frame", 'stamp_ns': S}


def test_panel_4_takes_the_foveated_frame_nearest_panel_1_s_when_it_has_none(
        tmp_path: Path) -> None:
    """Panel 1's frame was suppressed in a saccade (or came before the recording caught
    foveation's output): the nearest foveated frame in time, not the last one (which may show
    the wall the head turned to at the end of the run)."""
    samples = [s for s in story_samples([EARLY, *LATE])
               if not (s[0] == '/foveation/image' and s[2] == S + 1000)]
    samples.append(('/foveation/image', 'sensor_msgs/msg/Image', S + S // 5 + 1000,
                    image(S + S // 5, 30)))
    samples.append(('/foveation/image', 'sensor_msgs/msg/Image', S - S // 2 + 1000,
                    image(S - S // 2, 30)))
    result = summarize(tmp_path, samples)
    assert result['panels']['left'].facts['stamp_ns'] == S
    assert result['panels']['foveated'].facts == {
        'frame': f"+{S // 5 * 1e-9:.2f} s from panel 1's frame", 'stamp_ns': S + S // 5}


def test_panel_1_ties_go_to_the_later_frame(tmp_path: Path) -> None:
    tie = detections(2 * S, 1, [('can', 0.6, CENTRE), ('jar', 0.3, LEFT)])   # 0.6 as EARLY
    result = summarize(tmp_path, story_samples([EARLY, LATE[0], tie]))
    assert result['panels']['left'].facts['rule'] == 'most confident correct'
    assert result['panels']['left'].facts['stamp_ns'] == 2 * S
    assert result['panels']['left'].facts['correct'] == 1


@pytest.mark.parametrize('truth', [True, False])
def test_panel_1_falls_back_to_the_last_detections(tmp_path: Path, truth: bool) -> None:
    """No detection ever correct, or no ground truth to check them: the last detections' frame
    (their final pass), as before."""
    result = summarize(tmp_path, story_samples(LATE if truth else [EARLY, *LATE], truth=truth))
    facts = result['panels']['left'].facts
    assert facts['rule'] == 'last detections'
    assert facts['stamp_ns'] == 2 * S
    # The final pass's one detection: wrong (on nothing) with ground truth, unchecked without.
    assert (facts['correct'], facts['wrong']) == ((0, 1) if truth else (0, 0))


def test_recall_and_precision_over_time(tmp_path: Path) -> None:
    result = summarize(tmp_path, story_samples([EARLY, *LATE]))
    recall = result['panels']['recall']
    assert recall.has_data and recall.note == ''
    f = recall.facts
    assert f['truths'] == 3   # can_0, box_0, jar_0: not the table
    # Times from the earliest stamp drawn (the first map's, 0.5 s).
    assert f['t_s'] == pytest.approx([0.0, 0.5, 1.5])
    assert f['confirmed'] == [0, 1, 3]
    assert f['unconfirmed'] == [1, 0, 1]
    assert f['recall_5cm'] == pytest.approx([0.0, 0.0, 1 / 3])
    assert f['recall_10cm'] == pytest.approx([0.0, 1 / 3, 1 / 3])
    assert np.isnan(f['precision_5cm'][0])   # nothing confirmed: no precision
    assert f['precision_5cm'][1:] == pytest.approx([0.0, 1 / 3])
    assert f['false_objects'] == [0, 0, 1]


def test_object_map_top_view_against_ground_truth(tmp_path: Path) -> None:
    result = summarize(tmp_path, story_samples([EARLY, *LATE]))
    panel = result['panels']['object_map']
    assert panel.has_data
    f = panel.facts
    assert (f['confirmed'], f['unconfirmed'], f['tentative']) == (3, 1, 1)
    assert f['pairs'] == {'c1': 'can_0'}   # drawn green with a line to can_0
    assert f['wrong'] == ['c2', 'c3']      # drawn red with a dotted line to the nearest
    s = f['score']
    assert (s['truths'], s['reported'], s['found']) == (3, 3, 1)
    assert (s['false_objects'], s['misnamed']) == (1, 1)
    assert s['recall'] == pytest.approx(1 / 3) and s['precision'] == pytest.approx(1 / 3)
    assert 'last map: 3 confirmed, 1 established unconfirmed, 1 tentative' in panel.note


def test_a_map_with_nothing_confirmed_still_makes_a_page(tmp_path: Path) -> None:
    samples = [s for s in story_samples([EARLY, *LATE]) if s[0] != '/objects/map'] + MAPS[:1]
    result = summarize(tmp_path, samples)
    assert {'object_map', 'recall'} <= set(result['with_data'])
    f = result['panels']['object_map'].facts
    assert (f['confirmed'], f['unconfirmed'], f['pairs']) == (0, 1, {})
    assert f['score']['recall'] == 0.0 and f['score']['reported'] == 0
    assert result['panels']['recall'].facts['confirmed'] == [0]


def test_object_class_is_the_name_before_the_underscore() -> None:
    assert [object_class(n) for n in ('can_0', 'can_lying', 'bottle_1', 'table', 'stand_2')] == \
        ['can', 'can', 'bottle', 'table', 'stand']


def test_panel_1_sums_the_correct_scores_of_a_message(tmp_path: Path) -> None:
    """A can on can_0 (0.6) and a box on box_0 (0.3) in the later frame: 0.9 beats 0.6."""
    both = detections(2 * S, 1, [('can', 0.6, CENTRE), ('box', 0.3, LEFT)])
    facts = summarize(tmp_path, story_samples([EARLY, LATE[0], both]))['panels']['left'].facts
    assert (facts['stamp_ns'], facts['correct'], facts['wrong']) == (2 * S, 2, 0)
    assert facts['score_sum'] == pytest.approx(0.9)


def test_the_drawn_pairs_are_as_many_as_object_scoring_finds() -> None:
    """The top view's lines pair the map's objects with true ones as object_scoring counts them
    (its own assignment, without scipy), crowded cases included."""
    from vizzy_runtime.demo_summary import _assignment, _pairs
    from vizzy_vision.object_scoring import Labelled, score
    rng = np.random.default_rng(3)
    for _ in range(200):
        labels = ['can', 'jar', 'box']
        truths = [Labelled(str(rng.choice(labels)), tuple(rng.uniform(0, 0.15, 3)))
                  for _ in range(int(rng.integers(0, 7)))]
        reported = [Labelled(str(rng.choice(labels)), tuple(rng.uniform(0, 0.15, 3)))
                    for _ in range(int(rng.integers(0, 7)))]
        pairs = _pairs(reported, truths, 0.05)
        assert len(pairs) == score(reported, truths, 0.05).found
        assert len(set(pairs.values())) == len(pairs)
        assert all(reported[i].label == truths[j].label for i, j in pairs.items())
    # The assignment is the cheapest: 2 + 2 beats 1 + 9.
    assert _assignment(np.array([[1.0, 2.0], [2.0, 9.0]])) == [(0, 1), (1, 0)]
    assert _assignment(np.array([[5.0], [1.0], [3.0]])) == [(1, 0)]
