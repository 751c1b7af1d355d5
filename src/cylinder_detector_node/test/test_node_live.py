"""The cylinder detector live on the bundled runtime: organized clouds in, cylinders and markers
out.

A test node publishes synthetic organized clouds (core.scene: a ray-cast tabletop seen from a
camera optical frame) and listens to /cylinders and /cylinders/markers, all in one process and one
executor (the detector's pipeline runs on its own worker thread). Nothing asserts on wall-clock
time: the tests wait for conditions.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from cylinder_detector_node import node as cyl_node
from cylinder_detector_node.core.overlay import CYLINDER_COLOUR
from cylinder_detector_node.core.scene import make_tabletop
from vizzy_runtime.convert import array_to_pointcloud2, image_to_numpy, numpy_to_image
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
    no_renderer,
    publish_until,
    reported_status,
    scaled,
    spinning,
    wait_until,
)

pytestmark = pytest.mark.live  # also run on the real rclpy (scripts/test_ros.sh)

CylinderArray = message('active_vision_msgs/msg/CylinderArray')
MarkerArray = message('visualization_msgs/msg/MarkerArray')
Marker = message('visualization_msgs/msg/Marker')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')
Image = message('sensor_msgs/msg/Image')
DiagnosticArray = message('diagnostic_msgs/msg/DiagnosticArray')

TIMEOUT = scaled(60.0)
FRAME = 'rgbd_camera_optical_frame'
XYZ = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4')])


class Camera(Node):
    """Publishes clouds and images (as a driver: the default reliable QoS); keeps what the
    detector publishes. On the detector's resolved topic names."""

    def __init__(self, context: Context, detector: Any) -> None:
        super().__init__('fake_rgbd', context=context, start_parameter_services=False)
        self.arrays: list[Any] = []
        self.markers: list[Any] = []
        self.cloud_pub = self.create_publisher(PointCloud2, detector._cloud_sub.topic_name,
                                               qos_profile_system_default)
        self.image_pub = self.create_publisher(Image, detector._image_sub.topic_name,
                                               qos_profile_system_default)
        self.create_subscription(CylinderArray, detector._pub.topic_name, self.arrays.append, 10)
        self.create_subscription(MarkerArray, detector._marker_pub.topic_name,
                                 self.markers.append, 10)
        self.overlays: list[Any] = []
        self.create_subscription(Image, detector._overlay_pub.topic_name, self.overlays.append,
                                 qos_profile_sensor_data)


@pytest.fixture
def graph(context):
    detector = cyl_node.CylinderDetectorNode(
        context=context, parameter_overrides=[Parameter('heartbeat_period_s', value=3600.0)])
    camera = Camera(context, detector)
    with spinning(context, [camera, detector],
                  lambda: camera.cloud_pub.get_subscription_count() > 0
                  and detector._pub.get_subscription_count() > 0
                  and detector._marker_pub.get_subscription_count() > 0, TIMEOUT) as executor:
        yield camera, detector, executor


def _cloud_message(xyz: np.ndarray, stamp_sec: int) -> Any:
    grid = np.empty(xyz.shape[:2], dtype=XYZ)
    grid['x'], grid['y'], grid['z'] = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    msg = array_to_pointcloud2(grid)
    msg.header.frame_id = FRAME
    msg.header.stamp.sec = stamp_sec
    return msg


def _image_msg(rgb: np.ndarray, stamp_sec: int) -> Any:
    msg = numpy_to_image(np.ascontiguousarray(rgb), 'rgb8')
    msg.header.frame_id = FRAME
    msg.header.stamp.sec = stamp_sec
    return msg


def _send_until(camera: Camera, executor: Any, msg: Any, done: Any, image: Any = None) -> bool:
    """Publish (image and) msg again every second until done()."""
    def publish() -> None:
        if image is not None:
            camera.image_pub.publish(image)
            wait_until(lambda: False, 0.05, spin=executor)   # let the image arrive first
        camera.cloud_pub.publish(msg)

    return publish_until(publish, done, executor, TIMEOUT, period=1.0)


def test_two_upright_cylinders_on_a_table(graph) -> None:
    camera, detector, executor = graph
    scene = make_tabletop(np.random.default_rng(3), n_cylinders=2, n_distractors=0)
    msg = _cloud_message(scene.cloud, 42)
    assert msg.height == 480 and msg.width == 640
    stamped = lambda a: a.header.stamp.sec == 42   # noqa: E731
    marked = lambda m: m.markers and m.markers[0].header.stamp.sec == 42   # noqa: E731
    assert _send_until(camera, executor, msg,
                       lambda: (any(map(stamped, camera.arrays))
                                and any(map(marked, camera.markers))))
    out = next(a for a in camera.arrays if stamped(a))
    assert out.header.frame_id == FRAME
    assert len(out.cylinders) == 2, [(c.center, c.radius) for c in out.cylinders]
    assert sorted(c.id for c in out.cylinders) == [0, 1]
    # "up" of the table in the optical frame: the table normal, from the ground truth's camera
    for base, radius, height in scene.cylinders:
        centre_true = base + 0.5 * height * _up(scene)
        c = min(out.cylinders, key=lambda c: np.linalg.norm(_xyz(c.center) - centre_true))
        axis = _xyz(c.axis)
        assert abs(np.linalg.norm(axis) - 1.0) < 1e-6
        assert np.degrees(np.arccos(min(1.0, axis @ _up(scene)))) < 10.0
        # distance from the true centre to the fitted axis, and the height along it
        d = centre_true - _xyz(c.center)
        assert np.linalg.norm(d - (d @ axis) * axis) < 0.02
        assert abs(c.radius - radius) < 0.2 * radius
        assert abs(c.height - height) < 0.3 * height
        assert c.label == 'cylinder' and 0.5 <= c.confidence <= 1.0
        assert c.fit_quality == c.confidence

    markers = next(m for m in camera.markers if marked(m)).markers
    assert markers[0].action == Marker.DELETEALL
    bodies = [m for m in markers if m.type == Marker.CYLINDER]
    assert len(bodies) == 2 and all(m.header.frame_id == FRAME for m in bodies)
    for m, c in zip(sorted(bodies, key=lambda m: m.id), sorted(out.cylinders, key=lambda c: c.id),
                    strict=True):
        q = m.pose.orientation
        z_axis = _rotate_z(q.x, q.y, q.z, q.w)
        assert np.allclose(z_axis, _xyz(c.axis), atol=1e-6)
        assert m.scale.x == pytest.approx(2 * c.radius) and m.scale.z == pytest.approx(c.height)
    assert sum(m.type == Marker.TEXT_VIEW_FACING for m in markers) == 2
    assert detector.frames_processed >= 1


def test_the_overlay_draws_the_cylinders_on_the_colour_image(graph) -> None:
    camera, detector, executor = graph
    detector.set_parameters([Parameter('use_classifier', value=False)])
    scene = make_tabletop(np.random.default_rng(3), n_cylinders=2, n_distractors=0)
    grey = _image_msg(np.full((480, 640, 3), 128, np.uint8), 43)
    stamped = lambda m: m.header.stamp.sec == 43   # noqa: E731
    assert _send_until(camera, executor, _cloud_message(scene.cloud, 43),
                       lambda: any(map(stamped, camera.overlays)), image=grey)
    overlay = next(m for m in camera.overlays if stamped(m))
    assert (overlay.encoding, overlay.height, overlay.width) == ('rgb8', 480, 640)
    assert overlay.header.frame_id == FRAME
    drawn = (image_to_numpy(overlay) == np.array(CYLINDER_COLOUR, np.uint8)).all(axis=-1)
    assert drawn.sum() > 100   # two outlines, not a stray pixel


def test_all_nan_cloud_gives_an_empty_array_and_a_log_line(graph, capfd) -> None:
    camera, detector, executor = graph
    msg = _cloud_message(np.full((48, 64, 3), np.nan), 7)
    assert _send_until(camera, executor, msg,
                       lambda: any(a.header.stamp.sec == 7 for a in camera.arrays))
    assert all(not a.cylinders for a in camera.arrays if a.header.stamp.sec == 7)
    assert wait_until(lambda: '0 finite points' in capfd.readouterr().err, TIMEOUT, spin=executor)
    # the markers travel on their own topic: they may arrive after the array
    assert wait_until(lambda: any(m.markers[0].header.stamp.sec == 7
                                  and [k.action for k in m.markers] == [Marker.DELETEALL]
                                  for m in camera.markers), TIMEOUT, spin=executor)

    # a bare table (no objects): empty array, the node keeps working; parameters change live
    bare = make_tabletop(np.random.default_rng(0), n_cylinders=0, n_distractors=0)
    assert _send_until(camera, executor, _cloud_message(bare.cloud, 8),
                       lambda: any(a.header.stamp.sec == 8 for a in camera.arrays))
    assert all(not a.cylinders for a in camera.arrays if a.header.stamp.sec == 8)
    assert detector.set_parameters([Parameter('method', value='rabbani'),
                                    Parameter('classifier_model',
                                              value='/nonexistent/model.pt')])[0].successful
    assert detector._params[1].method == 'rabbani'
    assert detector.classifier is None
    assert 'classifier unavailable' in capfd.readouterr().err
    assert not detector.set_parameters([Parameter('classifier_threshold', value=1.5)])[0].successful
    assert not detector.set_parameters([Parameter('radius_min_m', value=0.5)])[0].successful
    assert not detector.set_parameters([Parameter('bias', value='sideways')])[0].successful


def _up(scene: Any) -> np.ndarray:
    """The table normal (table-frame +z) in the camera frame, from two cylinders' bases would be
    ambiguous; the scene's camera rotation is fixed: recompute it as make_tabletop does."""
    eye = np.array([0.0, -0.55, 0.6])
    fwd = -eye / np.linalg.norm(eye)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    return np.stack([right, down, fwd]) @ np.array([0.0, 0.0, 1.0])


def _xyz(v: Any) -> np.ndarray:
    return np.array([v.x, v.y, v.z], dtype=float)


def _rotate_z(x: float, y: float, z: float, w: float) -> np.ndarray:
    """The image of +z under the unit quaternion (x, y, z, w)."""
    return np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])


@pytest.fixture(scope='module')
def rendered():
    """The simulator's tabletop (seed 0) as its RGB-D camera sees it: image, cloud, ground truth."""
    from cylinder_detector_node.training.sim_frames import SimRenderer
    try:
        r = SimRenderer()
        frame = r.frame(0)
        r.close()
    except Exception as exc:   # no offscreen OpenGL
        no_renderer(str(exc))
    return frame


def test_classifier_rejects_non_cylinders_and_checks_image_size(graph, rendered, capfd) -> None:
    camera, detector, executor = graph
    assert detector.classifier is not None
    cloud, image = _cloud_message(rendered.cloud, 50), _image_msg(rendered.image, 50)
    stamped = lambda a: a.header.stamp.sec == 50   # noqa: E731
    assert _send_until(camera, executor, cloud, lambda: any(map(stamped, camera.arrays)), image)
    out = next(a for a in camera.arrays if stamped(a))
    det = detector.last_detection
    assert detector.last_classified and det.rejected_by_classifier >= 1
    assert len(out.cylinders) == len(det.cylinders) >= 3
    for c in out.cylinders:   # every reported cylinder is a real one; confidence = P(cylinder)
        centre = np.array([[c.center.x, c.center.y, c.center.z]])
        nearest = rendered.objects[int(np.argmin(rendered.surface_distances(centre)[0]))]
        assert nearest.is_cylinder, nearest.name
        assert 0.5 <= c.confidence <= 1.0 and 0.0 < c.fit_quality <= 1.0
    # without the classifier the same frame gives non-cylinders too (Eq. 4.4 alone lets them
    # through)
    assert detector.set_parameters([Parameter('use_classifier', value=False)])[0].successful
    assert _send_until(camera, executor, _cloud_message(rendered.cloud, 51),
                       lambda: any(a.header.stamp.sec == 51 for a in camera.arrays), image)
    out_no = next(a for a in camera.arrays if a.header.stamp.sec == 51)
    assert len(out_no.cylinders) > len(out.cylinders)
    assert not detector.last_classified

    # an image of another size: a clear message, detection goes on without the classifier
    assert detector.set_parameters([Parameter('use_classifier', value=True)])[0].successful
    capfd.readouterr()
    small = _image_msg(rendered.image[::2, ::2], 52)
    assert _send_until(camera, executor, _cloud_message(rendered.cloud, 52),
                       lambda: any(a.header.stamp.sec == 52 for a in camera.arrays), small)
    assert not detector.last_classified
    assert 'image 320x240 does not match the 640x480 cloud' in detector.classifier_skipped
    assert any(a.header.stamp.sec == 52 and a.cylinders for a in camera.arrays)


def test_refused_inputs_are_counted_per_topic_and_reason(graph, capfd, monkeypatch) -> None:
    """Bad clouds (refused on the worker thread) and bad images (on arrival) are counted per
    (topic, reason) in input_health, logged and reported on /diagnostics; each refused cloud is
    answered with an empty array; the valid cloud right after is processed; nothing raises, and
    an exception in a callback or the worker is counted too."""
    camera, detector, executor = graph
    health = detector.input_health
    cloud_topic, image_topic = detector._cloud_sub.topic_name, detector._image_sub.topic_name
    reports: list[Any] = []
    camera.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, reports.append, 10)
    expected: dict[tuple[str, str], int] = {}

    def send_cloud(msg: Any, reason: str) -> None:
        """Publish msg until the detector received it once (sensor-data QoS may lose it), then
        wait for its refusal."""
        received = detector.clouds_received
        assert publish_until(lambda: camera.cloud_pub.publish(msg),
                             lambda: detector.clouds_received > received, executor, TIMEOUT,
                             period=5.0)
        expected[(cloud_topic, reason)] = 1
        assert wait_until(lambda: health.refused() == expected, TIMEOUT, spin=executor), \
            health.refused()
        stamp = msg.header.stamp.sec           # answered with an empty array
        assert wait_until(lambda: any(a.header.stamp.sec == stamp and not a.cylinders
                                      for a in camera.arrays), TIMEOUT, spin=executor)

    def send_image(msg: Any, reason: str) -> None:
        """Images are checked in the callback: refused once it arrived (sent again if lost)."""
        expected[(image_topic, reason)] = 1
        assert publish_until(lambda: camera.image_pub.publish(msg),
                             lambda: health.refused() == expected, executor, TIMEOUT,
                             period=5.0), health.refused()

    x, y = np.meshgrid(np.linspace(-0.3, 0.3, 64), np.linspace(-0.2, 0.2, 48))
    plane = np.stack([x, y, np.ones_like(x)], axis=-1)     # a flat 64x48 cloud 1 m away
    no_fields = _cloud_message(plane, 60)
    no_fields.fields = []
    send_cloud(no_fields, cyl_node.NO_XYZ)
    truncated = _cloud_message(plane, 61)
    truncated.height = 2 * truncated.height                 # more points than the data holds
    send_cloud(truncated, cyl_node.SHORT_DATA)
    send_cloud(_cloud_message(np.full((48, 64, 3), np.nan), 62), cyl_node.TOO_FEW_POINTS)
    empty = array_to_pointcloud2(np.zeros(0, dtype=XYZ))
    empty.header.stamp.sec = 63
    send_cloud(empty, cyl_node.EMPTY_CLOUD)
    send_image(_mono_image(48, 64, 64), cyl_node.UNSUPPORTED_ENCODING)
    tall = _image_msg(np.zeros((48, 64, 3), np.uint8), 64)
    tall.height = 96                                        # more rows than the data holds
    send_image(tall, cyl_node.SHORT_DATA)
    assert health.accepted() == {}

    # a valid cloud right after: processed (an array with its stamp, the accept count)
    assert _send_until(camera, executor, _cloud_message(plane, 65),
                       lambda: health.accepted().get(cloud_topic) == 1
                       and any(a.header.stamp.sec == 65 for a in camera.arrays))
    assert health.refused() == expected and detector.frames_dropped == 0
    # and a valid image is accepted
    grey = np.full((48, 64, 3), 90, np.uint8)
    assert publish_until(lambda: camera.image_pub.publish(_image_msg(grey, 65)),
                         lambda: health.accepted().get(image_topic) == 1, executor, TIMEOUT,
                         period=5.0)

    # /diagnostics: the node's status carries the counts
    name = detector.get_fully_qualified_name()

    def reported() -> dict[str, str]:
        return reported_status(reports, name)

    want = {**{f'{topic}: {reason}': '1' for topic, reason in expected},
            f'{cloud_topic}: accepted': '1', f'{image_topic}: accepted': '1'}
    assert wait_until(lambda: reported() == want, TIMEOUT, spin=executor), reported()
    # each first refusal logged once, naming topic and reason; nothing raised
    err = capfd.readouterr().err
    for topic, reason in expected:
        assert err.count(f'{topic}: refused: {reason}') == 1, err
    assert f'{cloud_topic}: refused: {cyl_node.NO_XYZ}: no cylinders: no field(s) x, y, z' in err
    assert 'Traceback' not in err
    assert not any(reason.startswith('failed on') for _, reason in health.refused())

    # an exception in the image callback or in the worker (both guarded): counted on its topic
    def boom(*_: Any, **__: Any) -> None:
        raise RuntimeError('on fire')

    monkeypatch.setattr(cyl_node, 'colour_image_refusal', boom)
    send_image(_image_msg(grey, 66), 'failed on an image: RuntimeError')
    monkeypatch.setattr(cyl_node, 'detect_cylinders', boom)
    received = detector.clouds_received
    assert publish_until(lambda: camera.cloud_pub.publish(_cloud_message(plane, 66)),
                         lambda: detector.clouds_received > received, executor, TIMEOUT,
                         period=5.0)
    expected[(cloud_topic, 'failed on a cloud: RuntimeError')] = 1
    assert wait_until(lambda: health.refused() == expected, TIMEOUT, spin=executor), \
        health.refused()
    monkeypatch.undo()                       # and the node goes on
    assert _send_until(camera, executor, _cloud_message(plane, 67),
                       lambda: health.accepted().get(cloud_topic) == 2
                       and any(a.header.stamp.sec == 67 for a in camera.arrays))
    assert 'refused: failed on a cloud: RuntimeError: on fire' in capfd.readouterr().err


def _mono_image(height: int, width: int, stamp_sec: int) -> Any:
    msg = numpy_to_image(np.zeros((height, width), np.uint8), 'mono8')
    msg.header.frame_id = FRAME
    msg.header.stamp.sec = stamp_sec
    return msg
