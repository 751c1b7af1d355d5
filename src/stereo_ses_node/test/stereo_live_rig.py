"""The stereo_ses node's live test rig (imported by test_node_live*.py): a test node that
publishes a textured fronto-parallel plane rendered exactly into both cameras, camera_info,
the camera poses and gaze states, and keeps what the node publishes; the `graph` fixture."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest

from stereo_ses_node import node as ses_node
from stereo_ses_node.core.geometry import vergence_poses
from stereo_ses_node.core.synthetic import plane_texture, render_plane
from vizzy_runtime.convert import (
    numpy_to_image,
    pointcloud2_to_array,
)
from vizzy_runtime.ros import (
    Context,
    Node,
    Parameter,
    message,
    qos_profile_latched,
    qos_profile_system_default,
)
from vizzy_runtime.testing import scaled, spinning, wait_until
from vizzy_runtime.tf import TF_STATIC_TOPIC

Image = message('sensor_msgs/msg/Image')
CameraInfo = message('sensor_msgs/msg/CameraInfo')
PointCloud2 = message('sensor_msgs/msg/PointCloud2')
GazeCommand = message('active_vision_msgs/msg/GazeCommand')
GazeState = message('active_vision_msgs/msg/GazeState')
TFMessage = message('tf2_msgs/msg/TFMessage')
TransformStamped = message('geometry_msgs/msg/TransformStamped')
DiagnosticArray = message('diagnostic_msgs/msg/DiagnosticArray')

TIMEOUT = scaled(30.0)
W, H = 320, 240
F = 160.0 / np.tan(np.radians(85.4 / 2))
K = np.array([[F, 0, 159.5], [0, F, 119.5], [0, 0, 1.0]])
DEPTH = 1.0
BASELINE = 0.204
FRAMES = {'left': 'left_camera_optical_frame', 'right': 'right_camera_optical_frame'}
# the cyclopean optical frame (z forward, x right, y down) 0.1 m in front of ego (x fwd, z up)
EGO_CYC = np.eye(4)
EGO_CYC[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
EGO_CYC[:3, 3] = [0.1, 0.0, 0.0]
POSES = dict(zip(('left', 'right'), vergence_poses(BASELINE, 2 * np.arctan(0.102 / DEPTH)),
                 strict=True))


def _stamped(parent: str, child: str, pose: np.ndarray) -> Any:
    from scipy.spatial.transform import Rotation
    msg = TransformStamped(child_frame_id=child)
    msg.header.frame_id = parent
    t = msg.transform
    t.translation.x, t.translation.y, t.translation.z = (float(v) for v in pose[:3, 3])
    t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w = (
        float(v) for v in Rotation.from_matrix(pose[:3, :3]).as_quat())
    return msg


class Rig(Node):
    """Publishes the stereo pair, camera_info (as a driver: the default reliable QoS, which the
    node's reliable inputs need), tf and gaze states; keeps the node's outputs. On the node's
    resolved topic names."""

    def __init__(self, context: Context, ses: Any) -> None:
        super().__init__('fake_rig', context=context, start_parameter_services=False)
        self.points: list[Any] = []
        self.cells: list[Any] = []
        self.gaze: list[Any] = []
        self.last_pair: tuple[Any, Any] | None = None      # the last pair _feed sent
        self.image_pubs = {e: self.create_publisher(Image, ses._image_subs[e].topic_name,
                                                    qos_profile_system_default) for e in FRAMES}
        self.info_pubs = {e: self.create_publisher(CameraInfo, ses._info_subs[e].topic_name,
                                                   qos_profile_system_default) for e in FRAMES}
        self.tf_pub = self.create_publisher(TFMessage, ses.resolve_topic_name(TF_STATIC_TOPIC),
                                            qos_profile_latched)
        self.state_pub = self.create_publisher(GazeState, ses._gaze_state_sub.topic_name, 10)
        self.create_subscription(PointCloud2, ses._points_pub.topic_name, self.points.append, 10)
        self.create_subscription(PointCloud2, ses._cells_pub.topic_name, self.cells.append, 10)
        self.create_subscription(GazeCommand, ses._gaze_pub.topic_name, self.gaze.append, 10)
        tex = plane_texture(512)
        self.images = {e: render_plane(K, POSES[e], W, H, DEPTH, tex, 0.004) for e in FRAMES}

    def publish_info(self) -> None:
        for eye, pub in self.info_pubs.items():
            info = CameraInfo(width=W, height=H)
            info.header.frame_id = FRAMES[eye]
            info.k = K.reshape(9).tolist()
            pub.publish(info)

    def publish_tf(self) -> None:
        self.tf_pub.publish(TFMessage(transforms=[
            _stamped('ego', FRAMES[e], EGO_CYC @ POSES[e]) for e in FRAMES]))

    def image(self, eye: str, stamp: int, array: np.ndarray | None = None,
              encoding: str = 'rgb8') -> Any:
        msg = numpy_to_image(self.images[eye] if array is None else array, encoding)
        msg.header.frame_id = FRAMES[eye]
        msg.header.stamp.sec, msg.header.stamp.nanosec = 100 + stamp, 0
        return msg


@pytest.fixture
def graph(context):
    ses = ses_node.StereoSesNode(context=context, parameter_overrides=[
        Parameter('sensor', value='cartesian'), Parameter('n_rf', value=100),
        Parameter('n_cells', value=3000), Parameter('max_rate_hz', value=30.0),
        Parameter('decision_period_s', value=0.1), Parameter('frames_per_fixation', value=1),
        Parameter('cells_rate_hz', value=20.0)])
    rig = Rig(context, ses)
    with spinning(context, [rig, ses],
                  lambda: all(p.get_subscription_count() > 0 for p in rig.image_pubs.values())
                  and rig.state_pub.get_subscription_count() > 0
                  and ses._points_pub.get_subscription_count() > 0
                  and ses._cells_pub.get_subscription_count() > 0
                  and ses._gaze_pub.get_subscription_count() > 0, TIMEOUT) as executor:
        yield rig, ses, executor


# Image stamps (100 s + these): always increasing, as a camera's; the node refuses a pair that is
# not newer than the last one it fused.
_stamps = itertools.count()
# A pair is published again only when none formed this long after it was sent (lost images):
# a copy of a pair the worker was merely slow to take would be handled twice (issue 28 item 8).
RESEND_S = 10.0


def _take(n: int) -> int:
    """The first of n consecutive fresh stamps."""
    first = next(_stamps)
    for _ in range(n - 1):
        next(_stamps)
    return first


def _feed(rig: Rig, ses: Any, executor: Any, left: Any = None, right: Any = None) -> bool:
    """Publish a pair (a fresh stamp unless given) and wait until the node handled it."""
    stamp = next(_stamps)
    left = left or rig.image('left', stamp)
    right = right or rig.image('right', stamp)
    rig.last_pair = (left, right)
    received, done = ses.pairs_received, ses.pairs_processed + 1
    for _ in range(int(TIMEOUT / RESEND_S)):
        rig.image_pubs['left'].publish(left)
        rig.image_pubs['right'].publish(right)
        if wait_until(lambda: ses.pairs_received > received, RESEND_S, spin=executor):
            return (wait_until(lambda: ses.pairs_processed >= done, TIMEOUT, spin=executor)
                    and _settled(ses, executor))
    return False


def _settled(ses: Any, executor: Any) -> bool:
    """Wait until every pair formed so far was handled (processed or replaced), twice 0.1 s
    apart: a copy _feed re-sent while a slow worker was busy (a loaded machine) must not be
    fused later, during the next step of a test."""
    def idle() -> bool:
        return ses.pairs_processed + ses.pairs_dropped >= ses.pairs_received

    for _ in range(int(TIMEOUT / 0.1)):
        if not wait_until(idle, TIMEOUT, spin=executor):
            return False
        before = ses.pairs_received
        wait_until(lambda before=before: ses.pairs_received > before, 0.1, spin=executor)
        if ses.pairs_received == before and idle():
            return True
    return False


def _cells(msg: Any) -> np.ndarray:
    return pointcloud2_to_array(msg).reshape(-1)
