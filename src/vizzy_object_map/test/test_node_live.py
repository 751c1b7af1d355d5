"""The object map live: segmented objects and recognitions in, labelled objects out.

A test node plays the other nodes: it publishes a static camera pose on /tf_static, the left
camera's camera_info, the cylinder detector's clusters and cylinders and foveation's detections,
and listens to /objects, /objects/markers and /objects/map, all in one process and executor.
Nothing asserts on wall-clock time: the tests wait for conditions.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from vizzy_object_map import node as map_node
from vizzy_runtime.convert import array_to_pointcloud2
from vizzy_runtime.ros import Context, Node, Parameter, message, qos_profile_latched
from vizzy_runtime.testing import (
    check_node_parameters,
    check_parameter_table,
    parameter_refusals,
    scaled,
    spinning,
    wait_until,
)
from vizzy_vision.camera import camera_matrix

pytestmark = pytest.mark.live  # also run on the real rclpy (scripts/test_ros.sh)

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'object_map.yaml'
TIMEOUT = scaled(60.0)
CAMERA = 'left_camera_optical_frame'
RGBD = 'rgbd_camera_optical_frame'
K = camera_matrix(640, 480, 85.4)
# both sensors 0.5 m above base_link looking along +x (optical z forward, x right, y down)
OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
ORIGIN = np.array([0.0, 0.0, 0.5])
CAN = np.array([0.8, 0.1, 0.3])          # base_link
BOX = np.array([0.9, -0.2, 0.32])

TFMessage = message('tf2_msgs/msg/TFMessage')
TransformStamped = message('geometry_msgs/msg/TransformStamped')
CameraInfo = message('sensor_msgs/msg/CameraInfo')
FoveatedDetection = message('active_vision_msgs/msg/FoveatedDetection')
FoveatedDetectionArray = message('active_vision_msgs/msg/FoveatedDetectionArray')
CylinderArray = message('active_vision_msgs/msg/CylinderArray')
CylinderMsg = message('active_vision_msgs/msg/Cylinder')
Detection3D = message('vision_msgs/msg/Detection3D')
Detection3DArray = message('vision_msgs/msg/Detection3DArray')
MarkerArray = message('visualization_msgs/msg/MarkerArray')
MapObjectArray = message('active_vision_msgs/msg/MapObjectArray')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')
GazeCommand = message('active_vision_msgs/msg/GazeCommand')
GazeState = message('active_vision_msgs/msg/GazeState')


def to_sensor(p: np.ndarray) -> np.ndarray:
    return OPTICAL.T @ (p - ORIGIN)


def pixel(p: np.ndarray) -> tuple[float, float]:
    uvw = K @ to_sensor(p)
    return float(uvw[0] / uvw[2]), float(uvw[1] / uvw[2])


class Peers(Node):
    """The other nodes of the graph, as far as the map sees them."""

    def __init__(self, context: Context, mapper: Any) -> None:
        super().__init__('map_peers', context=context, start_parameter_services=False)
        topics = mapper._topics
        self.tf_pub = self.create_publisher(TFMessage, '/tf_static', qos_profile_latched)
        self.info_pub = self.create_publisher(CameraInfo, topics[map_node.CAMERA_INFO_TOPIC], 10)
        self.det_pub = self.create_publisher(FoveatedDetectionArray,
                                             topics[map_node.DETECTIONS_TOPIC], 10)
        self.cluster_pub = self.create_publisher(Detection3DArray,
                                                 topics[map_node.CLUSTERS_TOPIC], 10)
        self.cyl_pub = self.create_publisher(CylinderArray, topics[map_node.CYLINDERS_TOPIC], 10)
        self.state_pub = self.create_publisher(GazeState, topics[map_node.GAZE_STATE_TOPIC], 10)
        self.objects: list[Any] = []
        self.markers: list[Any] = []
        self.maps: list[Any] = []
        self.create_subscription(Detection3DArray, mapper._objects_pub.topic_name,
                                 self.objects.append, 10)
        self.create_subscription(MarkerArray, mapper._markers_pub.topic_name,
                                 self.markers.append, 10)
        self.create_subscription(MapObjectArray, mapper._map_pub.topic_name, self.maps.append, 10)
        self.gaze: list[Any] = []
        self.create_subscription(GazeCommand, mapper._gaze_pub.topic_name, self.gaze.append, 10)

    def stamp(self) -> Any:
        return self.get_clock().now().to_msg()

    def publish_poses(self) -> None:
        from vizzy_vision.frames import matrix_to_quaternion
        q = matrix_to_quaternion(OPTICAL)
        transforms = []
        for child in (CAMERA, RGBD):
            t = TransformStamped(child_frame_id=child)
            t.header.frame_id, t.header.stamp = 'base_link', self.stamp()
            t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = (
                float(v) for v in ORIGIN)
            r = t.transform.rotation
            r.x, r.y, r.z, r.w = (float(v) for v in q)
            transforms.append(t)
        self.tf_pub.publish(TFMessage(transforms=transforms))
        info = CameraInfo(width=640, height=480)
        info.header.frame_id = CAMERA
        info.k = [float(v) for v in K.ravel()]
        self.info_pub.publish(info)

    def publish_clusters(self) -> None:
        msg = Detection3DArray()
        msg.header.frame_id, msg.header.stamp = RGBD, self.stamp()
        for i, (p, size) in enumerate(((CAN, (0.066, 0.122, 0.066)),
                                       (BOX, (0.1, 0.08, 0.12)))):
            d = Detection3D(id=str(i))
            c = d.bbox.center
            c.position.x, c.position.y, c.position.z = (float(v) for v in to_sensor(p))
            c.orientation.w = 1.0
            d.bbox.size.x, d.bbox.size.y, d.bbox.size.z = size
            msg.detections.append(d)
        self.cluster_pub.publish(msg)

    def publish_cylinder(self) -> None:
        msg = CylinderArray()
        msg.header.frame_id, msg.header.stamp = RGBD, self.stamp()
        c = CylinderMsg(id=0, label='cylinder', radius=0.033, height=0.122, confidence=0.9,
                        fit_quality=0.9)
        c.center.x, c.center.y, c.center.z = (float(v) for v in to_sensor(CAN))
        c.axis.x, c.axis.y, c.axis.z = (float(v) for v in OPTICAL.T @ [0.0, 0.0, 1.0])
        msg.cylinders.append(c)
        self.cyl_pub.publish(msg)

    def publish_gaze(self, fixation: np.ndarray, moving: bool = False) -> None:
        msg = GazeState(in_saccade=moving, active_source='object_map')
        msg.header.frame_id, msg.header.stamp = 'base_link', self.stamp()
        msg.fixation_point.x, msg.fixation_point.y, msg.fixation_point.z = (float(v)
                                                                           for v in fixation)
        self.state_pub.publish(msg)

    def publish_detection(self, label: str, score: float, at: np.ndarray | None,
                          pass_index: int = 1) -> None:
        msg = FoveatedDetectionArray()
        msg.header.frame_id, msg.header.stamp = CAMERA, self.stamp()
        u, v = pixel(at) if at is not None else (float(K[0, 2]), float(K[1, 2]))
        d = FoveatedDetection(label=label, class_id=0, score=score, fixation_u=u,
                              fixation_v=v, pass_index=pass_index)
        d.box.x_offset, d.box.y_offset, d.box.width, d.box.height = int(u) - 20, int(v) - 20, 40, 40
        msg.detections.append(d)
        self.det_pub.publish(msg)


@pytest.fixture
def graph(context):
    mapper = map_node.ObjectMapNode(context=context, parameter_overrides=[
        Parameter('publish_period_s', value=0.1), Parameter('use_stereo_depth', value=False),
        Parameter('min_pass', value=1), Parameter('max_pass', value=1)])
    peers = Peers(context, mapper)
    with spinning(context, [peers, mapper],
                  lambda: peers.cluster_pub.get_subscription_count() > 0
                  and peers.det_pub.get_subscription_count() > 0
                  and mapper._objects_pub.get_subscription_count() > 0, TIMEOUT) as executor:
        yield peers, mapper, executor


def test_parameter_table_and_config() -> None:
    check_parameter_table(map_node.PARAMETERS, map_node.check_parameter, CONFIG, 'object_map',
                          check_all=map_node.check_all)
    with parameter_refusals(map_node.PARAMETERS, map_node.check_parameter,
                            map_node.check_all) as refused:
        assert 'max_pass' in (refused('min_pass', 1) or '')
        assert 'map_frame' in (refused('map_frame', '/') or '')
        assert refused('min_recognitions', 0) and refused('association_radius_m', 0.0)
        assert refused('min_recognitions', 3) is None


def test_objects_are_placed_by_geometry_and_named_by_recognitions(graph) -> None:
    peers, mapper, executor = graph
    peers.publish_poses()
    assert wait_until(lambda: mapper._k is not None
                      and mapper.poses.pose_at(RGBD, 0.0) is not None, TIMEOUT, spin=executor)
    for _ in range(3):                                  # established after 3 segmentations
        n = sum(o.geometry for o in mapper.map.objects())
        peers.publish_clusters()
        assert wait_until(lambda n=n: sum(o.geometry for o in mapper.map.objects()) >= n + 2,
                          TIMEOUT, spin=executor)
    peers.publish_cylinder()
    assert wait_until(lambda: any(o.cylinders for o in mapper.map.objects()), TIMEOUT,
                      spin=executor)
    # both objects are established and unnamed: the map looks at one of them
    assert wait_until(lambda: peers.gaze, TIMEOUT, spin=executor)
    cmd = peers.gaze[0]
    assert cmd.source == 'object_map' and cmd.priority == 35 and cmd.header.frame_id == 'base_link'
    point = np.array([cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z])
    assert min(np.linalg.norm(point - CAN), np.linalg.norm(point - BOX)) < 0.01
    # pass 0 is not used by default; pass 1 names the object under its fixation
    peers.publish_detection('bottle', 0.9, CAN, pass_index=0)
    for score in (0.8, 0.6):
        peers.publish_detection('can', score, CAN)
    peers.publish_detection('box', 0.7, BOX)
    assert wait_until(lambda: mapper.recognitions_received >= 3, TIMEOUT, spin=executor)
    assert wait_until(lambda: peers.objects and len(peers.objects[-1].detections) == 1
                      and peers.maps and sum(o.recognitions for o in peers.maps[-1].objects)
                      == 3, TIMEOUT, spin=executor)
    [can] = peers.objects[-1].detections
    assert peers.objects[-1].header.frame_id == 'base_link'
    assert [(r.hypothesis.class_id, r.hypothesis.score) for r in can.results] == [('can', 1.0)]
    centre = can.bbox.center.position
    np.testing.assert_allclose([centre.x, centre.y, centre.z], CAN, atol=0.002)
    cov = np.reshape(can.results[0].pose.covariance, (6, 6))
    assert 0 < cov[0, 0] < 0.01 ** 2 and cov[3, 3] == -1.0
    assert can.bbox.size.z == pytest.approx(0.122, abs=0.02)
    # the box was named once: in the map, not confirmed; both boxes drawn, one named in green
    full = {o.label: o for o in peers.maps[-1].objects}
    assert set(full) == {'can', 'box'}
    assert full['can'].confirmed and not full['box'].confirmed and full['box'].established
    assert full['can'].geometry_observations == 4 and full['can'].recognitions == 2
    markers = peers.markers[-1].markers
    boxes = [m for m in markers if m.ns == 'objects']
    assert len(boxes) == 2 and sum(m.color.g > m.color.r for m in boxes) == 1
    assert any(m.text.startswith('can 1.00') for m in markers if m.ns == 'labels')


def test_the_gazes_own_pixel_names_the_object_at_the_fixation_point(graph) -> None:
    """A detection at the principal point names what lies where both optical axes meet (the
    fixation point of /gaze/state), whatever the pixel's own ray hits; during a saccade the
    fixation point says nothing."""
    peers, mapper, executor = graph
    assert all(r.successful for r in mapper.set_parameters([Parameter('min_pass', value=0)]))
    peers.publish_poses()
    assert wait_until(lambda: mapper._k is not None
                      and mapper.poses.pose_at(RGBD, 0.0) is not None, TIMEOUT, spin=executor)
    peers.publish_clusters()
    assert wait_until(lambda: len(mapper.map) == 2, TIMEOUT, spin=executor)
    peers.publish_gaze(CAN)
    assert wait_until(lambda: mapper._fixations, TIMEOUT, spin=executor)
    peers.publish_detection('can', 0.8, None, pass_index=0)      # at the principal point
    assert wait_until(lambda: mapper.recognitions_received == 1, TIMEOUT, spin=executor)
    named = [o for o in mapper.map.objects() if o.evidence]
    assert len(named) == 1 and np.linalg.norm(named[0].position - CAN) < 0.01
    # in a saccade: no fixation point, the pixel's ray hits nothing known: not placed
    peers.publish_gaze(CAN, moving=True)
    assert wait_until(lambda: mapper._fixations[-1][2], TIMEOUT, spin=executor)
    peers.publish_detection('box', 0.8, None, pass_index=0)
    assert wait_until(lambda: mapper.recognitions_received == 2, TIMEOUT, spin=executor)
    assert mapper.recognitions_placed == 1 and 'box' not in named[0].evidence


def test_a_detection_before_the_camera_info_is_refused_and_the_node_goes_on(graph) -> None:
    peers, mapper, executor = graph
    peers.publish_detection('can', 0.9, CAN)
    topic = mapper._topics[map_node.DETECTIONS_TOPIC]
    assert wait_until(lambda: mapper.input_health.refused().get((topic, map_node.NO_CAMERA_INFO)),
                      TIMEOUT, spin=executor)
    # clusters in a frame tf does not know: refused, named
    msg = Detection3DArray()
    msg.header.frame_id = 'nowhere'
    peers.cluster_pub.publish(msg)
    clusters = mapper._topics[map_node.CLUSTERS_TOPIC]
    assert wait_until(lambda: mapper.input_health.refused().get((clusters, map_node.NO_POSE)),
                      TIMEOUT, spin=executor)
    n = mapper.publications
    assert wait_until(lambda: mapper.publications > n + 2, TIMEOUT, spin=executor)


def test_node_parameters(context) -> None:
    mapper = map_node.ObjectMapNode(context=context)
    try:
        check_node_parameters(mapper, map_node.PARAMETERS, 'min_label_share', 1.5)
        assert all(r.successful for r in mapper.set_parameters(
            [Parameter('min_recognitions', value=5)]))
        assert mapper.map.config.min_recognitions == 5
    finally:
        mapper.destroy_node()


def test_the_stereo_cloud_is_subscribed_only_while_stereo_depth_is_on(graph) -> None:
    """Off (the graph's setting), the map does not subscribe to /stereo/points: each 1.5 MB cloud
    would cost its transfer only to be dropped (issue 27). On, its clouds are read again."""
    peers, mapper, executor = graph
    stereo = peers.create_publisher(PointCloud2, mapper._topics[map_node.STEREO_TOPIC], 2)
    peers.publish_poses()
    assert wait_until(lambda: mapper.poses.pose_at(CAMERA, 0.0) is not None, TIMEOUT,
                      spin=executor)
    assert all(r.successful for r in mapper.set_parameters(
        [Parameter('use_stereo_depth', value=True)]))
    assert wait_until(lambda: stereo.get_subscription_count() > 0, TIMEOUT, spin=executor)
    cloud = np.zeros(3, dtype=[('x', '<f4'), ('y', '<f4'), ('z', '<f4')])
    cloud['z'] = 1.0
    msg = array_to_pointcloud2(cloud)
    msg.header.frame_id, msg.header.stamp = CAMERA, peers.stamp()
    stereo.publish(msg)
    assert wait_until(lambda: mapper._stereo is not None, TIMEOUT, spin=executor)
    assert all(r.successful for r in mapper.set_parameters(
        [Parameter('use_stereo_depth', value=False)]))
    assert wait_until(lambda: stereo.get_subscription_count() == 0, TIMEOUT, spin=executor)
    assert mapper._stereo is None


def test_markers_are_built_only_while_something_subscribes(context, monkeypatch) -> None:
    """A MarkerArray is for viewers: without a subscriber the map does not build it (issue 27);
    the other two outputs go out at every publication."""
    built: list[int] = []
    real = map_node.marker_array
    monkeypatch.setattr(map_node, 'marker_array',
                        lambda *args: built.append(1) or real(*args))
    mapper = map_node.ObjectMapNode(context=context)
    viewer = Node('marker_viewer', context=context, start_parameter_services=False)
    got: list[Any] = []
    with spinning(context, [mapper, viewer], lambda: True, TIMEOUT) as executor:
        mapper.publish_map()
        mapper.publish_map()
        assert mapper.publications == 2 and built == []
        viewer.create_subscription(MarkerArray, mapper._markers_pub.topic_name, got.append,
                                   qos_profile_latched)
        assert wait_until(lambda: mapper._markers_pub.get_subscription_count() > 0, TIMEOUT,
                          spin=executor)
        assert wait_until(lambda: built and got, TIMEOUT, spin=executor)   # the timer's turn
