"""The cylinder_detector node: its parameters, config/cylinder_detector.yaml, its input checks."""

from pathlib import Path

import numpy as np
import pytest

from cylinder_detector_node import node
from vizzy_runtime.convert import array_to_pointcloud2
from vizzy_runtime.testing import (
    check_node_parameters,
    check_parameter_table,
    node_under_test,
    parameter_refusals,
)
from vizzy_vision.frames import quaternion_z_to

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'cylinder_detector.yaml'


def test_parameter_table_and_config() -> None:
    check_parameter_table(node.PARAMETERS, node.check_parameter, CONFIG, 'cylinder_detector',
                          node.check_all)


def test_clouds_are_checked() -> None:
    xyz = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4')])
    good = np.zeros(100, dtype=xyz)
    assert node.cloud_problem(array_to_pointcloud2(good), 50) is None
    nan = np.full(100, np.nan, dtype=xyz)
    assert '0 finite points' in node.cloud_problem(array_to_pointcloud2(nan), 50)
    flat = np.zeros(100, dtype=[('x', '<f4'), ('y', '<f4')])
    assert 'no field(s) z' in node.cloud_problem(array_to_pointcloud2(flat), 50)
    short = array_to_pointcloud2(good)
    short.width = 1000  # more points than the data holds
    assert 'bytes' in node.cloud_problem(short, 50)
    # each refusal carries a short stable reason (an InputHealth counter key)
    empty = array_to_pointcloud2(np.zeros(0, dtype=xyz))
    odd = array_to_pointcloud2(good)
    odd.fields[2].datatype = 99
    for msg, reason in ((array_to_pointcloud2(nan), node.TOO_FEW_POINTS),
                        (array_to_pointcloud2(flat), node.NO_XYZ), (short, node.SHORT_DATA),
                        (empty, node.EMPTY_CLOUD), (odd, node.BAD_FIELDS)):
        with pytest.raises(node.CloudRefused) as refused:
            node.cloud_xyz(msg, 50)
        assert refused.value.reason == reason, str(refused.value)
    assert all(not any(c.isdigit() for c in r) for r in node.CLOUD_REASONS + node.IMAGE_REASONS)


def test_node_declares_its_parameters_and_refuses_bad_values() -> None:
    with node_under_test(node.CylinderDetectorNode) as ros_node:
        check_node_parameters(ros_node, node.PARAMETERS, 'heartbeat_period_s', 0.0)


def test_parameters_taken_together_and_mapped_to_the_core() -> None:
    values = {p.name: p.default for p in node.PARAMETERS}
    assert node.check_all(values) is None
    assert 'radius_min_m' in node.check_all({**values, 'radius_min_m': 0.2})
    with parameter_refusals(node.PARAMETERS, node.check_parameter, node.check_all) as refused:
        assert refused('method', 'hough') and refused('bias', 'up')
        assert 'radius_max_m' in refused('radius_min_m', 0.2)
        assert refused('frame_id', '') and refused('min_points', -1)
        assert refused('radius_max_m', 2.5) and refused('voxel_size_m', 0.0)
        assert refused('min_points', 0) is None and refused('max_range_m', 0.0) is None
    seg, fit = node.pipeline_params({**values, 'method': 'rabbani', 'max_range_m': 0.0})
    assert fit.method == 'rabbani' and seg.max_range is None
    assert fit.n_directions == values['n_directions'] and seg.voxel_size == values['voxel_size_m']


def test_markers_turn_z_onto_the_axis() -> None:
    from cylinder_detector_node.core.fitting import Cylinder
    for axis in ([0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, -0.6, 0.8], [0.0, 0.0, -1.0]):
        x, y, z, w = quaternion_z_to(np.array(axis))
        image = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
        assert np.allclose(image, axis, atol=1e-9)
    header = node.CylinderArray().header
    header.frame_id = 'cam'
    cyl = Cylinder((0.1, 0.2, 0.9), (0.0, -0.6, 0.8), 0.03, 0.12, 0.8, 80, 100)
    markers = node.marker_array(header, [cyl]).markers
    assert [m.action for m in markers][0] == node.Marker.DELETEALL
    body = markers[1]
    assert body.type == node.Marker.CYLINDER and body.header.frame_id == 'cam'
    assert (body.scale.x, body.scale.y, body.scale.z) == (0.06, 0.06, 0.12)
    assert body.color.g > body.color.r          # confident: green
    arr = node.cylinder_array(header, [cyl])
    assert arr.cylinders[0].radius == 0.03 and arr.cylinders[0].fit_quality == 0.8


def test_images_are_read_as_rgb() -> None:
    from vizzy_runtime.convert import numpy_to_image
    rgb = np.zeros((4, 5, 3), np.uint8)
    rgb[..., 0] = 200                                    # red
    assert (node.rgb_image(numpy_to_image(rgb, 'rgb8')) == rgb).all()
    bgr = numpy_to_image(np.ascontiguousarray(rgb[..., ::-1]), 'bgr8')
    assert (node.rgb_image(bgr) == rgb).all()
    with pytest.raises(ValueError, match='not a colour one'):
        node.rgb_image(numpy_to_image(np.zeros((4, 5), np.uint8), 'mono8'))
    # the checks on arrival: (reason, detail) or None
    assert node.colour_image_refusal(numpy_to_image(rgb, 'rgb8')) is None
    assert node.colour_image_refusal(numpy_to_image(np.zeros((4, 5, 4), np.uint8), 'bgra8')) is None
    reason, detail = node.colour_image_refusal(numpy_to_image(np.zeros((4, 5), np.uint8), 'mono8'))
    assert reason == node.UNSUPPORTED_ENCODING and "'mono8'" in detail
    tall = numpy_to_image(rgb, 'rgb8')
    tall.height = 8                                      # more rows than the data holds
    assert node.colour_image_refusal(tall)[0] == node.SHORT_DATA
    tall.height, tall.step = 4, 10                       # a row is 15 bytes
    assert node.colour_image_refusal(tall)[0] == node.SHORT_STEP
    tall.width = 0
    assert node.colour_image_refusal(tall)[0] == node.EMPTY_IMAGE
    stamp = node.CylinderArray().header.stamp
    stamp.sec, stamp.nanosec = 3, 500_000_000
    assert node.stamp_seconds(stamp) == 3.5


def test_up_comes_from_tf_else_the_clouds_minus_y() -> None:
    from cylinder_detector_node.core.segmentation import CAMERA_UP
    values = {p.name: p.default for p in node.PARAMETERS}
    seg, _ = node.pipeline_params({**values, 'up_tolerance_deg': 20.0})
    assert seg.up_tolerance_deg == 20.0
    # an optical frame (x right, y down, z forward) pitched 30 degrees down, 1.2 m above base_link
    # columns: x, y, z of cam
    level = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    t = np.radians(30.0)
    pitch = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(t), -np.sin(t)], [0.0, np.sin(t), np.cos(t)]])
    pose = np.eye(4)
    pose[:3, :3] = level @ pitch.T      # forward tilted towards the floor
    pose[:3, 3] = (0.0, 0.0, 1.2)
    with node_under_test(node.CylinderDetectorNode) as ros_node:
        assert ros_node.cloud_up('cam') == CAMERA_UP          # no tf yet: the optical frame's -y
        ros_node.tf_buffer.set_transform('base_link', 'cam', pose)
        up = np.array(ros_node.cloud_up('cam'))
        # camera-down plus forward
        assert np.allclose(up, [0.0, -np.cos(t), -np.sin(t)], atol=1e-9)
        assert np.allclose(ros_node.cloud_up('/cam'), up)
        assert ros_node.cloud_up('elsewhere') == CAMERA_UP    # not in the tree
        ros_node._p['up_frame'] = ''                            # no up frame: -y
        assert ros_node.cloud_up('cam') == CAMERA_UP


def test_clusters_go_out_as_table_aligned_boxes() -> None:
    """Each segmented object becomes a Detection3D whose box, turned by its orientation, holds
    the object's points and whose z axis is the table normal."""
    from cylinder_detector_node.core.pipeline import Detection
    from cylinder_detector_node.core.segmentation import Cluster
    from vizzy_vision.frames import rotation_matrix
    rng = np.random.default_rng(3)
    normal = np.array([0.0, -0.8, -0.6])                 # a camera looking down at a table
    # a 10 x 6 x 12 cm box standing on the table, in the table frame, then in the camera's
    local = rng.uniform([-0.05, -0.03, 0.0], [0.05, 0.03, 0.12], (500, 3))
    from cylinder_detector_node.core.fitting import rotation_to_z
    to_table = rotation_to_z(normal)
    centre = np.array([0.1, 0.2, 1.0])
    points = local @ to_table + centre
    det = Detection(plane=np.array([*normal, 0.5]),
                    all_clusters=[Cluster(points, points.min(0), points.max(0))],
                    cluster_probabilities=[0.25])
    header = node.CylinderArray().header
    header.frame_id = 'rgbd'
    arr = node.cluster_array(header, det)
    assert arr.header.frame_id == 'rgbd' and len(arr.detections) == 1
    d = arr.detections[0]
    size = np.array([d.bbox.size.x, d.bbox.size.y, d.bbox.size.z])
    np.testing.assert_allclose(size, [0.1, 0.06, 0.12], atol=0.005)
    o = d.bbox.center.orientation
    r = rotation_matrix((o.x, o.y, o.z, o.w))
    np.testing.assert_allclose(r[:, 2], normal, atol=1e-9)     # the box's z: the table normal
    c = d.bbox.center.position
    inside = (points - [c.x, c.y, c.z]) @ r                     # box coordinates
    assert np.all(np.abs(inside) <= size / 2 + 1e-9)
    assert [(h.hypothesis.class_id, h.hypothesis.score) for h in d.results] == [('cylinder', 0.25)]
    assert node.cluster_array(header, None).detections == []   # a refused cloud: none


def test_markers_are_built_only_while_something_subscribes(monkeypatch) -> None:
    """The MarkerArray is for viewers: without a subscriber it is not built (issue 27); the
    CylinderArray always goes out."""
    from vizzy_runtime.ros import message
    built: list[int] = []
    real = node.marker_array
    monkeypatch.setattr(node, 'marker_array', lambda *args: built.append(1) or real(*args))
    with node_under_test(node.CylinderDetectorNode) as detector:
        detector._publish(message('std_msgs/msg/Header')(frame_id='rgbd'), [])
        assert built == []
        monkeypatch.setattr(node, 'has_subscribers', lambda pub: pub is detector._marker_pub)
        detector._publish(message('std_msgs/msg/Header')(frame_id='rgbd'), [])
        assert built == [1]
